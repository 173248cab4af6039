"""Metric scale of monocular camera odometry, estimated against radar/Doppler translations.

Camera relative poses come up to an unknown scale that stays roughly constant while tracking
and is lost when the camera is. Over a sliding window of keyframe pairs the metric (radar)
translation length is compared with the camera's: the median ratio rejects outliers, then the
scale is the inliers' summed metric length over their summed camera length.

Why a ratio of sums, not a least-squares fit of the metric lengths on the camera's: a fit
takes its regressor as exact, and here the regressor is the noisy one (per keyframe step the
camera's length is 12-17 % off, the radar's 2 %, measured by ``metrics.json`` ``step_errors``).
Noise in the regressor shrinks the fitted slope by about 1 / (1 + relative variance): the
camera's metric steps came out 2-3 % short, 3 mm a step, and the fused path shrank with them.
A ratio of sums is unbiased to first order whichever side is noisy.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from smokyslam.config import ScaleConfig


@dataclass(frozen=True)
class ScaleEstimate:
    """scale: metres per camera unit. relative_sigma: 1-sigma spread of the fit, as a fraction
    of ``scale``. pairs: keyframe pairs used."""

    scale: float
    relative_sigma: float
    pairs: int


class ScaleEstimator:
    """Windowed scale from pairs of (camera, metric) translation lengths of the same motion."""

    def __init__(
        self,
        window: int,
        min_pairs: int,
        min_translation_m: float,
        inlier_ratio_tolerance: float,
    ) -> None:
        """window: keyframe pairs kept. min_pairs: inliers needed before a scale is reported.
        min_translation_m: shorter metric motions carry no scale and are skipped.
        inlier_ratio_tolerance: ratios further than this fraction from the median are outliers."""
        self._pairs: deque[tuple[float, float]] = deque(maxlen=window)
        self._min_pairs = min_pairs
        self._min_translation_m = min_translation_m
        self._tolerance = inlier_ratio_tolerance

    def reset(self) -> None:
        """Forget every pair: the camera re-entered after being lost and has a fresh scale."""
        self._pairs.clear()

    def update(
        self, camera_translation: np.ndarray, metric_translation_m: np.ndarray
    ) -> ScaleEstimate | None:
        """Add one keyframe pair and return the current estimate (None until enough pairs).

        camera_translation: (2,) camera odometry translation, camera units (any frame).
        metric_translation_m: (2,) radar/Doppler translation of the same motion, metres.
        Only lengths are compared, so the two need not share a frame.
        """
        camera_norm = float(np.linalg.norm(camera_translation))
        metric_norm = float(np.linalg.norm(metric_translation_m))
        if metric_norm >= self._min_translation_m and camera_norm > 1e-9:
            self._pairs.append((camera_norm, metric_norm))
        return self.estimate()

    def estimate(self) -> ScaleEstimate | None:
        """The scale from the pairs in the window, or None with fewer than ``min_pairs``."""
        if len(self._pairs) < self._min_pairs:
            return None
        camera, metric = np.array(self._pairs).T
        ratios = metric / camera
        median = np.median(ratios)
        inliers = np.abs(ratios - median) <= self._tolerance * median
        if inliers.sum() < self._min_pairs:
            return None
        c, m = camera[inliers], metric[inliers]
        n = len(c)
        scale = float(m.sum() / c.sum())
        residual = m - scale * c
        sigma = np.sqrt(residual @ residual * n / max(n - 1, 1)) / c.sum()
        return ScaleEstimate(scale, float(sigma / scale), n)


class SharedScale:
    """Another estimator's scale, read and never fed (same verbs as :class:`ScaleEstimator`).

    For steps too short to carry a scale themselves: the localizer's camera steps span one
    radar frame (3-5 cm at a walk, under ``min_translation_m``), so they take the scale that
    SLAM's keyframe pairs (0.2 m and more) keep. The source resets itself when its camera
    comes back from a loss."""

    def __init__(self, source: ScaleEstimator) -> None:
        self._source = source

    def reset(self) -> None:
        """Nothing to forget: the source keeps the pairs."""

    def update(
        self, camera_translation: np.ndarray, metric_translation_m: np.ndarray
    ) -> ScaleEstimate | None:
        """The source's current estimate; the pair is not added."""
        return self._source.estimate()

    def estimate(self) -> ScaleEstimate | None:
        return self._source.estimate()


def metric_relative_pose(
    delta: np.ndarray, covariance: np.ndarray, estimate: ScaleEstimate
) -> tuple[np.ndarray, np.ndarray]:
    """Scale a camera relative pose to metres.

    delta: (3,) ``[x, y, yaw_rad]`` of frame j in frame i, x and y in camera units;
    covariance: (3, 3) in the Pose2 tangent, x/y in camera units. Returns the metric delta and
    its covariance, with the scale's own uncertainty added along the direction of travel.
    """
    scale_matrix = np.diag([estimate.scale, estimate.scale, 1.0])
    metric = scale_matrix @ np.asarray(delta, dtype=float)
    metric_cov = scale_matrix @ np.asarray(covariance, dtype=float) @ scale_matrix
    # The scale error moves the end along the translation, expressed in the tangent (frame j).
    c, s = np.cos(metric[2]), np.sin(metric[2])
    along_xy = np.array([[c, s], [-s, c]]) @ metric[:2] * estimate.relative_sigma
    along = np.array([along_xy[0], along_xy[1], 0.0])
    return metric, metric_cov + np.outer(along, along)


def get_scale_estimator(config: ScaleConfig) -> ScaleEstimator:
    """A ScaleEstimator with the window and outlier settings of ``config``."""
    return ScaleEstimator(
        window=config.window,
        min_pairs=config.min_pairs,
        min_translation_m=config.min_translation_m,
        inlier_ratio_tolerance=config.inlier_tolerance,
    )
