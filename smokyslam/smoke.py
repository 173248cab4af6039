"""Smoke emulated at replay time, so one clean log serves every smoke level.

- Radar: exactly ``round(radar_loss * N)`` of a scan's N returns are dropped, chosen at random.
- Camera: haze first, ``I' = I exp(-B d) + A (1 - exp(-B d))`` with density ``B = haze``
  (1/m), airlight ``A`` (grey level) and per-pixel depth ``d`` (``frame.depth_m``, or
  ``default_depth_m`` where the frame has no depth or a pixel's depth is NaN/inf or <= 0);
  then salt and pepper: exactly ``round(camera_noise * H * W)`` distinct pixels are set to 0 or
  255 with equal probability. The depth image itself is left clean.
- Every other frame passes through unchanged (the same object).

Rounding is to the nearest integer with halves up (``floor(x + 0.5)``). Randomness is drawn
from a generator seeded by ``(seed, stream, stamp in ns)``, so a frame's smoke does not depend
on which other frames were processed before it, and runs are repeatable.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator

import numpy as np

from smokyslam.config import SmokeConfig
from smokyslam.frontends.readers.base import LogReader, LogSummary
from smokyslam.types import (
    CameraFrame,
    CameraIntrinsics,
    Extrinsics,
    Frame,
    GroundTruthMap,
    RadarScan,
)

_RADAR_STREAM, _CAMERA_STREAM = 1, 2


def _count(fraction: float, total: int) -> int:
    """``fraction * total`` rounded to the nearest integer, halves up, within [0, total]."""
    return min(max(math.floor(fraction * total + 0.5), 0), total)


class SmokeEmulator:
    """Degrades radar scans and camera frames as configured in ``SmokeConfig``."""

    def __init__(self, config: SmokeConfig) -> None:
        self.config = config

    @property
    def needs_depth(self) -> bool:
        """Whether camera frames need their depth image (haze does)."""
        return self.config.haze > 0.0

    def apply(self, frame: Frame) -> Frame:
        """A smoky copy of a RadarScan or CameraFrame; other frames are returned as they are."""
        if isinstance(frame, RadarScan):
            return self._radar(frame)
        if isinstance(frame, CameraFrame):
            return self._camera(frame)
        return frame

    def _rng(self, stream: int, stamp_s: float) -> np.random.Generator:
        stamp_ns = round(stamp_s * 1e9) % 2**64
        return np.random.default_rng([self.config.seed % 2**64, stream, stamp_ns])

    def _radar(self, scan: RadarScan) -> RadarScan:
        n = len(scan)
        n_drop = _count(self.config.radar_loss, n)
        keep = np.ones(n, dtype=bool)
        if n_drop:
            # A fixed per-frame order makes levels nested: what 0.1 drops, 0.2 drops too.
            keep[self._rng(_RADAR_STREAM, scan.stamp_s).permutation(n)[:n_drop]] = False
        return dataclasses.replace(
            scan,
            points_xyz_m=scan.points_xyz_m[keep],
            intensity=scan.intensity[keep],
            doppler_mps=scan.doppler_mps[keep],
        )

    def transmission(self, frame: CameraFrame) -> np.ndarray:
        """(H, W) float32 haze transmission ``exp(-B d)`` of a camera frame, in [0, 1]."""
        default_m = np.float32(self.config.default_depth_m)
        if frame.depth_m is None:
            depth_m = np.full(frame.image.shape, default_m, dtype=np.float32)
        else:
            depth_m = np.asarray(frame.depth_m, dtype=np.float32)
            depth_m = np.where(np.isfinite(depth_m) & (depth_m > 0.0), depth_m, default_m)
        return np.exp(np.float32(-self.config.haze) * depth_m)

    def _camera(self, frame: CameraFrame) -> CameraFrame:
        image = frame.image
        if self.config.haze > 0.0:
            t = self.transmission(frame)
            hazy = image * t + np.float32(self.config.airlight) * (1.0 - t)
            image = np.clip(np.rint(hazy), 0, 255).astype(np.uint8)
        n_noisy = _count(self.config.camera_noise, image.size)
        if n_noisy:
            rng = self._rng(_CAMERA_STREAM, frame.stamp_s)
            # Pixel order and salt/pepper values are drawn for the whole frame, independent of
            # the level, so a noisier level corrupts a superset of the same pixels.
            order = rng.permutation(image.size)
            salt = rng.random(image.size) < 0.5
            pixels = order[:n_noisy]
            image = image.copy()
            image.reshape(-1)[pixels] = np.where(salt[pixels], 255, 0).astype(np.uint8)
        return dataclasses.replace(frame, image=image)


class SmokedLog:
    """A log reader whose frames come out through a :class:`SmokeEmulator` (LogReader Protocol).

    Everything but ``frames()`` passes through to the wrapped reader unchanged.
    """

    def __init__(self, reader: LogReader, config: SmokeConfig) -> None:
        self.reader = reader
        self.path = reader.path
        self.emulator = SmokeEmulator(config)

    def frames(self) -> Iterator[Frame]:
        return (self.emulator.apply(frame) for frame in self.reader.frames())

    def summary(self) -> LogSummary:
        return self.reader.summary()

    def ground_truth_map(self) -> GroundTruthMap | None:
        return self.reader.ground_truth_map()

    def extrinsics(self) -> Extrinsics:
        return self.reader.extrinsics()

    def camera_intrinsics(self) -> CameraIntrinsics | None:
        return self.reader.camera_intrinsics()


def split_smoke(reader: LogReader) -> tuple[LogReader, SmokeEmulator | None]:
    """The clean reader behind a :class:`SmokedLog` and its emulator (None for any other
    reader), for a pipeline that smokes frames where it uses them: only the camera frames it
    tracks, in the process that tracks them. Smoke is seeded per frame, so the frames come out
    exactly as the SmokedLog would have given them."""
    if isinstance(reader, SmokedLog):
        return reader.reader, reader.emulator
    return reader, None
