"""Checks at the reader boundary: what cannot be used is dropped and counted, never passed on.

- IMU samples with a NaN/inf rate or acceleration are dropped.
- Radar points with a NaN/inf coordinate are dropped (a scan of only such points is an empty
  scan, still a frame); a NaN/inf velocity or intensity is unknown (NaN Doppler, zero
  intensity) for that point only. A point cloud without a velocity field has no Doppler at
  all: radar odometry then runs on scan matching and the gyro.
- Camera images of zero size, or of another size than the camera's (its intrinsics, else the
  first image), are dropped.
- Time: a stream whose log time jumps forward by more than ``max_gap_s``, or whose header
  stamps run backwards while its log time runs forwards, is reported with the time and the
  size of the jump.

- A message that does not decode (malformed, damaged) is skipped; a topic none of whose
  messages can be used is an error at the end.

Every stream with something dropped or odd gets one warning when the log has been read
(``report``), with the counts; ``counts`` keeps them for ``metrics.json``.
"""

from __future__ import annotations

import logging
from collections import Counter
from pathlib import Path

import numpy as np

from smokyslam.types import CameraFrame, ImuSample, RadarScan

logger = logging.getLogger(__name__)

HEADER_BACKWARDS_S = 0.5
"""Header stamps running backwards by more than this (log time forwards) are reported."""


class StreamChecks:
    """One reader pass's checks; one verb per kind of frame, then :meth:`report`."""

    def __init__(self, path: Path, max_gap_s: float | None) -> None:
        self.path = path
        self.max_gap_s = max_gap_s
        self.counts: Counter[str] = Counter()
        """What was dropped or odd, by kind (``imu_nonfinite``, ``radar_points_nonfinite``...)."""
        self.notes: list[str] = []
        """Time anomalies, one line each (the first few of each stream)."""
        self._last: dict[str, tuple[float, float]] = {}
        self._image_shape: tuple[int, int] | None = None
        self._good: Counter[str] = Counter()
        self._bad: Counter[str] = Counter()
        self._first_bad: dict[str, str] = {}

    def good_message(self, topic: str) -> None:
        self._good[topic] += 1

    def bad_message(self, topic: str, problem: str) -> None:
        """A message that could not be decoded or used: skipped, counted, the first kept."""
        self._bad[topic] += 1
        self._first_bad.setdefault(topic, problem)

    def unusable_topic(self) -> str | None:
        """A topic none of whose messages could be used (the first problem), if any."""
        for topic, count in self._bad.items():
            if count and not self._good[topic]:
                return f"{topic} ({count} messages; the first: {self._first_bad[topic]})"
        return None

    def radar(self, scan: RadarScan, dropped_points: int, has_velocity: bool) -> RadarScan:
        """The decoded scan (its bad points already dropped by the decoder), counted."""
        self.counts["radar_points_nonfinite"] += dropped_points
        if not has_velocity:
            self.counts["radar_scans_without_velocity"] += 1
        else:
            self.counts["radar_points_unknown_velocity"] += int(
                np.count_nonzero(~np.isfinite(scan.doppler_mps))
            )
        return scan

    def imu(self, sample: ImuSample) -> ImuSample | None:
        if np.isfinite(sample.gyro_radps).all() and np.isfinite(sample.accel_mps2).all():
            return sample
        self.counts["imu_nonfinite"] += 1
        return None

    def image(self, frame: CameraFrame) -> CameraFrame | None:
        """The frame, or None for an empty image or one of another size than the camera's
        (its intrinsics, else the first image)."""
        shape = frame.image.shape[:2]
        if min(shape) == 0:
            self.counts["images_empty"] += 1
            return None
        if self._image_shape is None:
            intrinsics = frame.intrinsics
            self._image_shape = (
                shape if intrinsics is None else (intrinsics.height, intrinsics.width)
            )
        if shape != self._image_shape:
            self.counts["images_resized"] += 1
            return None
        return frame

    def time(self, topic: str, stamp_s: float, header_s: float) -> None:
        """Note a message's log stamp (s from the log start) and header stamp (s, 0: none)."""
        last = self._last.get(topic)
        self._last[topic] = (stamp_s, header_s if header_s else np.nan)
        if last is None:
            return
        if self.max_gap_s is not None and stamp_s - last[0] > self.max_gap_s:
            self._note(
                topic, f"{topic}: log time jumps {stamp_s - last[0]:.1f} s at {last[0]:.2f} s"
            )
        if header_s and last[1] - header_s > HEADER_BACKWARDS_S:
            self._note(
                topic,
                f"{topic}: header stamps run {last[1] - header_s:.1f} s backwards at log time "
                f"{stamp_s:.2f} s",
            )

    def _note(self, topic: str, line: str) -> None:
        self.counts[f"time_anomalies {topic}"] += 1
        if self.counts[f"time_anomalies {topic}"] <= 3:
            self.notes.append(line)

    def report(self) -> None:
        """One warning per kind of problem, with its count."""
        words = {
            "imu_nonfinite": "IMU samples with NaN/inf values dropped",
            "radar_points_nonfinite": "radar points with NaN/inf coordinates dropped",
            "radar_points_unknown_velocity": "radar points with NaN/inf velocity (Doppler unknown)",
            "radar_scans_without_velocity": "radar scans without a velocity field: radar odometry "
            "runs without Doppler (scan matching and the gyro)",
            "images_empty": "camera images of zero size dropped",
            "images_resized": "camera images of another size than the camera's dropped",
        }
        for key, text in words.items():
            if self.counts[key]:
                logger.warning("%s: %d %s", self.path, self.counts[key], text)
        for line in self.notes:
            logger.warning("%s: %s", self.path, line)
        for topic, count in self._bad.items():
            logger.warning(
                "%s: %d malformed %s messages skipped (the first: %s)",
                self.path,
                count,
                topic,
                self._first_bad[topic],
            )
