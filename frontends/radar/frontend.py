"""The radar frontend stage: levels each scan once, then radar odometry or dead reckoning.

Scans are levelled (rotated through ``T_base_radar`` into the radar's position and heading
with z up), so a tilted or upside-down radar turns the same way as the gyro; everything
downstream (keyframe submaps, maps, the recording) uses the levelled scan it hands out.

A scan of more than ``max_points`` points (a dense frame of a real sensor) is thinned first,
so every stage's work per scan stays bounded: one point per 5 cm cell, then an even random
subset seeded by the scan's stamp (the same frame always thins the same way).
"""

from __future__ import annotations

import dataclasses
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from smokyslam.frontends.radar.odometry import DeadReckoning, RadarOdometry
from smokyslam.geometry import se2_from_matrix, transform_points_2d
from smokyslam.rig import level_scan
from smokyslam.types import ImuSample, Odometry, RadarScan

if TYPE_CHECKING:
    from smokyslam.config import RadarOdometryConfig

RadarKind = Literal["scan-matching", "dead-reckoning"]


@dataclass(frozen=True)
class RadarFrame:
    """One radar frame out of the frontend: its odometry and its levelled scan."""

    odometry: Odometry
    scan: RadarScan


class RadarFrontend:
    """One verb per frame: :meth:`add_imu` per IMU sample, :meth:`register` per radar scan
    (the frames odometry finished, in order); :meth:`flush` at the end of the log."""

    def __init__(
        self, odometry: RadarOdometry | DeadReckoning, T_base_radar: np.ndarray, max_points: int
    ):
        self._odometry = odometry
        self._max_points = max_points
        self.thinned = 0
        """Scans thinned to ``max_points``."""
        self._T_base_radar = np.asarray(T_base_radar, dtype=float)
        self._imu: list[ImuSample] = []
        self._waiting: deque[RadarScan] = deque()
        self.pose_base_radar = se2_from_matrix(self._T_base_radar)
        """(3,) planar pose of the levelled radar frame on base_link."""

    def add_imu(self, sample: ImuSample) -> None:
        self._imu.append(sample)

    def register(self, scan: RadarScan) -> list[RadarFrame]:
        """Level ``scan`` and register it with the IMU samples since the previous scan."""
        if len(scan) > self._max_points:
            scan = thin_scan(scan, self._max_points)
            self.thinned += 1
        levelled, _ = level_scan(scan, self._T_base_radar)
        self._waiting.append(levelled)
        finished = self._odometry.register(levelled, self._imu)
        self._imu = []
        return self._pair(finished)

    def flush(self) -> list[RadarFrame]:
        """The frames still queued in the odometry's last, partial batch."""
        return self._pair(self._odometry.flush())

    @property
    def gyro_bias_radps(self) -> float | None:
        """The odometry's gyro-bias estimate, rad/s (None when it estimates none)."""
        return self._odometry.gyro_bias_radps

    def points_base_xy(self, frame: RadarFrame) -> np.ndarray:
        """(N, 2) the frame's points in base_link, metres."""
        return transform_points_2d(self.pose_base_radar, frame.scan.points_xyz_m[:, :2])

    def _pair(self, finished: list[Odometry]) -> list[RadarFrame]:
        # Odometry finishes frames in their order, so the oldest waiting scan is each one's.
        return [RadarFrame(odometry, self._waiting.popleft()) for odometry in finished]


THIN_CELL_M = 0.05
"""Cell side of the first thinning step of a dense scan: one point per cell."""


def thin_scan(scan: RadarScan, max_points: int) -> RadarScan:
    """``scan`` with at most ``max_points`` points: the first point of each 5 cm cell (in
    3D), then an even random subset seeded by the stamp."""
    cells = np.floor(scan.points_xyz_m / THIN_CELL_M).astype(np.int64)
    _, keep = np.unique(cells, axis=0, return_index=True)
    if len(keep) > max_points:
        rng = np.random.default_rng(round(scan.stamp_s * 1e9) % 2**63)
        keep = rng.choice(keep, size=max_points, replace=False)
    keep = np.sort(keep)
    return dataclasses.replace(
        scan,
        points_xyz_m=scan.points_xyz_m[keep],
        intensity=scan.intensity[keep],
        doppler_mps=scan.doppler_mps[keep],
    )


def get_radar_frontend(
    kind: RadarKind, config: RadarOdometryConfig, T_base_radar: np.ndarray
) -> RadarFrontend:
    """Scan-matching radar odometry or Doppler/gyro dead reckoning, as configured."""
    odometry = DeadReckoning(config) if kind == "dead-reckoning" else RadarOdometry(config)
    return RadarFrontend(odometry, T_base_radar, config.max_points)
