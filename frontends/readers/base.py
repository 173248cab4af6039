"""The contract every log reader keeps, and the summary it reports.

Readers turn a file into time-ordered typed frames (``smokyslam.types``). They are picked by
an explicit registry (``frontends.readers.registry``), never by probing attributes.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    Frame,
    GroundTruthMap,
    GroundTruthTrajectory,
)


@dataclass
class StreamSummary:
    """One topic (or stream) of a log."""

    topic: str
    msgtype: str
    count: int
    rate_hz: float


@dataclass
class LogSummary:
    """What ``smokyslam info`` prints."""

    path: Path
    format: str
    duration_s: float
    start_s: float
    streams: list[StreamSummary] = field(default_factory=list)
    damage: str | None = None
    """Where a damaged log breaks off (the counts are of what could be read)."""


SENSOR_STREAMS = ("radar", "imu", "camera_image", "camera_depth")
"""What ``frames()`` can yield: radar scans, IMU samples, camera images (with their
intrinsics) and the depth images paired with them."""


class LogReader(Protocol):
    """A sensor log opened for replay."""

    path: Path

    def summary(self) -> LogSummary:
        """Per-topic type, count and rate, and the log's duration."""
        ...

    def frames(self, streams: Collection[str] | None = None) -> Iterator[Frame]:
        """Every radar, camera and IMU frame, in time order, each decoded once. Never ground
        truth: estimators read this and nothing else. ``streams``: only these of
        :data:`SENSOR_STREAMS` (None: all), so a run decodes nothing it does not use."""
        ...

    def log_time_s(self, stamps_s: np.ndarray) -> np.ndarray:
        """(N,) stamps from the log start (``stamp_s``, as frames carry them) on the log's own
        clock, seconds since the epoch: what trajectory files and recordings are stamped
        with, so that they match the log's messages."""
        ...

    def ground_truth_trajectory(self) -> GroundTruthTrajectory | None:
        """The ground-truth base_link poses (sorted by stamp), when the log has them."""
        ...

    def ground_truth_map(self) -> GroundTruthMap | None:
        """The ground-truth occupancy grid, when the log has one."""
        ...

    def observed_ground_truth_map(self) -> GroundTruthMap | None:
        """The part of the ground truth a lidar observed along the walk, when the log has it."""
        ...

    def extrinsics(self) -> Extrinsics:
        """Sensor mounting (``T_base_radar``, ``T_base_camera``); identity when unknown."""
        ...

    def camera_intrinsics(self) -> CameraIntrinsics | None:
        """Camera intrinsics, when the log has a camera."""
        ...

    def problems(self) -> dict[str, object]:
        """What reading has dropped, skipped or found damaged so far (counts by kind, and
        ``damage``), for ``metrics.json``; empty for a clean log."""
        ...
