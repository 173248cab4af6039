"""Smoke emulated at replay time, so one clean log serves every smoke level.

One notation names a level everywhere (``--smoke R:C[:H]``: radar loss, camera noise, haze),
parsed by :func:`parse_smoke` into a :class:`SmokeLevel`; the run loop applies it once per
frame through one :class:`SmokeEmulator`.

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
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.config import SmokeConfig
from smokyslam.errors import ConfigError
from smokyslam.types import CameraFrame, Frame, RadarScan

if TYPE_CHECKING:
    from smokyslam.config import SmokySlamConfig

_RADAR_STREAM, _CAMERA_STREAM = 1, 2
_PLAIN_NUMBER = re.compile(r"\d+(\.\d*)?|\.\d+")


@dataclass(frozen=True)
class SmokeLevel:
    """One smoke level, each number kept as typed (``haze_text`` is "" when haze-free), so
    folder names read as the user wrote them."""

    radar_loss_text: str
    camera_noise_text: str
    haze_text: str = ""

    @classmethod
    def from_values(cls, radar_loss: float, camera_noise: float, haze: float) -> SmokeLevel:
        """A level from numbers (written with ``:g``; a haze of 0 is haze-free)."""
        return cls(f"{radar_loss:g}", f"{camera_noise:g}", f"{haze:g}" if haze else "")

    @property
    def radar_loss(self) -> float:
        return float(self.radar_loss_text)

    @property
    def camera_noise(self) -> float:
        return float(self.camera_noise_text)

    @property
    def haze(self) -> float:
        return float(self.haze_text) if self.haze_text else 0.0

    @property
    def smoke_label(self) -> str:
        """``r<loss>-c<noise>``, as typed."""
        return f"r{self.radar_loss_text}-c{self.camera_noise_text}"

    @property
    def label(self) -> str:
        """``r<loss>-c<noise>``, plus ``-h<haze>`` when hazy."""
        return self.smoke_label + (f"-h{self.haze_text}" if self.haze_text else "")

    @property
    def notation(self) -> str:
        """``R:C`` or ``R:C:H``, as ``--smoke`` takes it."""
        haze = f":{self.haze_text}" if self.haze_text else ""
        return f"{self.radar_loss_text}:{self.camera_noise_text}{haze}"

    def apply(self, config: SmokySlamConfig) -> SmokySlamConfig:
        """``config`` with this level's radar loss, camera noise and haze (the other smoke
        settings, airlight and seed, kept)."""
        smoke = config.smoke.model_copy(
            update={
                "radar_loss": self.radar_loss,
                "camera_noise": self.camera_noise,
                "haze": self.haze,
            }
        )
        return config.model_copy(update={"smoke": smoke})


def check_number(text: str, name: str, item: str, upper: float | None) -> str:
    """``text`` checked as a plain decimal in [0, upper] (0 or more without ``upper``) and
    returned unchanged; ConfigError naming ``name`` and the ``item`` it came from."""
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{name} in '{item}' is not a number: '{text}'") from None
    bound = f"between 0 and {upper:g}" if upper is not None else "0 or more"
    if not math.isfinite(value) or value < 0 or (upper is not None and value > upper):
        raise ConfigError(f"{name} in '{item}' must be {bound}, got '{text}'")
    if not _PLAIN_NUMBER.fullmatch(text):
        raise ConfigError(f"{name} in '{item}': write a plain decimal such as 0.1, got '{text}'")
    return text


def parse_smoke(text: str) -> SmokeLevel:
    """``R:C`` or ``R:C:H`` (radar loss and camera noise in [0, 1], haze 1/m, 0 or more) as a
    level; a haze of 0 is the haze-free level. ConfigError for anything else."""
    parts = [part.strip() for part in text.strip().split(":")]
    if len(parts) not in (2, 3):
        raise ConfigError(
            f"smoke '{text}' must be radar_loss:camera_noise[:haze], e.g. 0.1:0.2 or 0.1:0.2:0.5"
        )
    item = text.strip()
    loss = check_number(parts[0], "radar_loss", item, 1.0)
    noise = check_number(parts[1], "camera_noise", item, 1.0)
    haze = check_number(parts[2], "haze", item, None) if len(parts) == 3 else ""
    return SmokeLevel(loss, noise, haze if haze and float(haze) else "")


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
