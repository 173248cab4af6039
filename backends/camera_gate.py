"""The camera-linchpin fix: how much the graph may trust camera factors right now.

The paper's system lost everything when smoke blinded its camera. Here the camera's health
maps to a weight in [0, 1]; a factor's covariance is inflated by ``1 / weight^2`` (1: as
reported, 0: not added). Two kinds of health enter, differently:

- tracking (features followed into the frame, PnP inlier ratio) decides whether the camera
  takes part at all. It drops out when tracking fails (weight under ``drop_below``) and comes
  back only after several frames tracking well again, flagged ``reentered`` so the caller
  resets the camera's metric scale;
- image quality (salt-and-pepper fraction, contrast) only weighs it. A smoky camera that still
  tracks keeps contributing, with less weight: it never vanishes at the first noise.

The weight is the product of the two.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.errors import EstimationError

if TYPE_CHECKING:
    from smokyslam.config import CameraGateConfig


@dataclass(frozen=True)
class CameraHealth:
    """Per-frame camera health.

    noise_fraction: estimated salt-and-pepper pixel fraction, 0..1.
    contrast: RMS contrast of the image (grey-level std / 255), 0..1; haze lowers it.
    tracked: features tracked into this frame. inlier_ratio: geometric inliers / tracked, 0..1.
    """

    noise_fraction: float
    contrast: float
    tracked: int
    inlier_ratio: float


@dataclass(frozen=True)
class HealthRamp:
    """Weight 1 at ``good``, 0 at ``bad``, linear in between (either may be the larger)."""

    good: float
    bad: float

    def weight(self, value: float) -> float:
        return float(np.clip((value - self.bad) / (self.good - self.bad), 0.0, 1.0))


@dataclass(frozen=True)
class GateDecision:
    """weight: 0 (drop camera factors) to 1 (trust as reported): tracking times quality.
    tracking: its tracking part alone (0 when dropped).
    reentered: True on the first frame the camera is used again after being dropped."""

    weight: float
    tracking: float
    reentered: bool = False


class CameraGate:
    """Camera factor weight from health, with hysteresis on tracking. One verb: ``update``."""

    def __init__(
        self,
        noise_fraction: HealthRamp,
        contrast: HealthRamp,
        tracked: HealthRamp,
        inlier_ratio: HealthRamp,
        drop_below: float,
        reenter_above: float,
        reenter_frames: int,
    ) -> None:
        """Ramps per health signal. The tracking weight (the smaller of ``tracked`` and
        ``inlier_ratio``) drops the camera when it falls below ``drop_below``; it re-enters
        after ``reenter_frames`` consecutive frames at or above ``reenter_above``. The quality
        weight (the smaller of ``noise_fraction`` and ``contrast``) scales the weight."""
        self._quality = (noise_fraction, contrast)
        self._tracking = (tracked, inlier_ratio)
        self._drop_below = drop_below
        self._reenter_above = reenter_above
        self._reenter_frames = reenter_frames
        self._dropped = False
        self._healthy_streak = 0

    @property
    def dropped(self) -> bool:
        """Whether camera factors are currently dropped."""
        return self._dropped

    def tracking_weight(self, health: CameraHealth) -> float:
        """How well the frame was tracked: the worse of its two tracking ramps."""
        return min(
            self._tracking[0].weight(health.tracked), self._tracking[1].weight(health.inlier_ratio)
        )

    def quality_weight(self, health: CameraHealth) -> float:
        """How clean the image is: the worse of its impulse-noise and contrast ramps."""
        noise, contrast = self._quality
        return min(noise.weight(health.noise_fraction), contrast.weight(health.contrast))

    def raw_weight(self, health: CameraHealth) -> float:
        """The weight before hysteresis: tracking times quality."""
        return self.tracking_weight(health) * self.quality_weight(health)

    def update(self, health: CameraHealth) -> GateDecision:
        """Decide the weight of this frame's camera factor."""
        tracking = self.tracking_weight(health)
        weight = tracking * self.quality_weight(health)
        if not self._dropped:
            if tracking < self._drop_below:
                self._dropped = True
                self._healthy_streak = 0
                return GateDecision(0.0, 0.0)
            return GateDecision(weight, tracking)
        self._healthy_streak = self._healthy_streak + 1 if tracking >= self._reenter_above else 0
        if self._healthy_streak < self._reenter_frames:
            return GateDecision(0.0, 0.0)
        self._dropped = False
        return GateDecision(weight, tracking, reentered=True)


def inflate_covariance(covariance: np.ndarray, weight: float) -> np.ndarray:
    """Covariance scaled by ``1 / weight^2`` (weight in (0, 1]); a down-weighted factor."""
    if weight <= 0.0:
        raise EstimationError("a dropped factor (weight 0) has no covariance; do not add it")
    return np.asarray(covariance, dtype=float) / weight**2


def get_camera_gate(config: CameraGateConfig) -> CameraGate:
    """A CameraGate with the health ramps and hysteresis of ``config``."""
    return CameraGate(
        noise_fraction=HealthRamp(*config.noise_fraction),
        contrast=HealthRamp(*config.contrast),
        tracked=HealthRamp(*config.tracked),
        inlier_ratio=HealthRamp(*config.inlier_ratio),
        drop_below=config.drop_below,
        reenter_above=config.reenter_above,
        reenter_frames=config.reenter_frames,
    )
