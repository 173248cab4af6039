"""Camera odometry turned into base_link between factors for radar keyframe pairs.

The camera runs at its own rate, so its poses are kept for a while and interpolated at the
two keyframe stamps (in the same camera map: never across a reinitialization or a lost frame).
Each factor is weighted by the camera gate (tracking decides whether the camera takes part,
image quality how much: ``camera_gate.py``; a yaw factor by tracking alone, below) and checked
against the radar step of the same pair: one that disagrees beyond ``consistency_chi2`` is not
added. (That keeps a failing camera out; it does not make fused better than radar alone in
every run: docs/accuracy.md.)

What a factor holds (``slam.camera_factor``):

- ``yaw`` (the default): the camera's turn between the keyframes, with its reported variance
  scaled (``slam.camera_yaw_variance_scale``) so that its sigma stands to the radar's as their
  measured errors do (both then claim about twice their error). Its translation is the
  radar's step, left free (:data:`FREE_TRANSLATION_VARIANCE_M2`), and the check compares the
  turns alone (1 dof). Measured against the truth on simulated walks, the camera's metric
  step is 27-69 mm off along the path (its scale) against the radar's 4-5 mm, while its turn is
  0.24-0.54 deg off against the radar's 0.17-0.25 deg: its yaw is the part worth adding, and
  needs no metric scale. Its reported yaw sigma (about 0.1 deg) is too small by about 4x.
  Image noise leaves that turn as good as in clean air (0.38 deg RMS per pair at camera noise
  0, 0.2 and 0.4, docs/accuracy.md), so a yaw factor is weighed by the gate's tracking part
  alone: image quality does not inflate it.
- ``pose``: the whole step, made metric by the windowed scale estimated against the radar
  step, moved from the camera body to base_link through the mount, checked on 3 dof with its
  own covariance. The camera's reported covariances are about 10x too small (NEES ~30), so this
  gate is strict and passes about 30 % of pairs.

The metric step is kept in both modes where the scale is known (``steps``, for evaluation).

Long turns (``slam.camera_long_turn_s``, yaw factors only): the per-pair turns are weak, and
as independent factors they cannot say that the camera's errors do not add up, since it tracks
against its own map. Every ``camera_long_turn_s`` seconds of unbroken tracking in one camera
map, one more yaw factor holds the camera's whole turn since the last one, with
``camera_long_turn_sigma_deg``. That is what a gyro bias held a little off needs: in warehouse
10081 the radar's bias estimate turned the fused heading 5 deg over the walk while the camera's
stayed within about 1 deg (docs/accuracy.md).
"""

from __future__ import annotations

import logging
from collections import Counter, deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, get_args

import numpy as np

from smokyslam.backends.camera_gate import (
    CameraGate,
    CameraHealth,
    get_camera_gate,
    inflate_covariance,
)
from smokyslam.backends.scale import (
    ScaleEstimator,
    SharedScale,
    get_scale_estimator,
    metric_relative_pose,
)
from smokyslam.config import CameraFactorKind
from smokyslam.errors import ConfigError
from smokyslam.frontends.camera.odometry import CameraOdometryResult
from smokyslam.frontends.camera.pose import planar_from_camera
from smokyslam.geometry import (
    interpolate_se2,
    se2_between,
    se2_compose,
    se2_conjugate,
    se2_inverse,
    wrap_angle,
)
from smokyslam.types import StepPairs

if TYPE_CHECKING:
    from smokyslam.config import BackendConfig, SlamConfig

logger = logging.getLogger(__name__)

KEEP_S = 10.0
"""Seconds of camera poses kept for the keyframe pairs still waiting for the camera."""

FREE_TRANSLATION_VARIANCE_M2 = 1e4
"""Variance (m^2) of a yaw factor's translation: 100 m sigma, i.e. no constraint."""

FACTOR_KINDS = get_args(CameraFactorKind)
"""What a camera factor may hold (``slam.camera_factor``): the turn alone, or the whole step."""


@dataclass(frozen=True)
class CameraFactor:
    """delta: (3,) base_link pose of keyframe j in keyframe i, metres and radians.
    covariance: (3, 3) tangent covariance, inflated by 1 / weight^2. weight: the gate weight
    (pose factors) or its tracking part (yaw factors)."""

    delta: np.ndarray
    covariance: np.ndarray
    weight: float


@dataclass(frozen=True)
class LongTurn:
    """The camera's turn (rad) from keyframe ``old_index`` to the keyframe it was asked for,
    and the (3, 3) tangent covariance of a factor holding it: translation free, the turn's
    variance inflated by the tracking weight."""

    old_index: int
    yaw_rad: float
    covariance: np.ndarray


@dataclass(frozen=True)
class _Anchor:
    index: int
    stamp_s: float
    yaw_rad: float
    map_id: int


@dataclass(frozen=True)
class _Sample:
    stamp_s: float
    pose: np.ndarray  # (3,) camera body in the camera odometry world, camera units
    covariance: np.ndarray  # (3, 3) reported for this frame
    map_id: int
    tracked: bool
    weight: float  # gate weight, 0 when dropped
    tracking: float  # its tracking part, 0 when dropped


def camera_health(result: CameraOdometryResult) -> CameraHealth:
    """What the gate reads from one frame: a lost frame has no inliers."""
    return CameraHealth(
        noise_fraction=result.quality.impulse_fraction,
        contrast=result.quality.rms_contrast,
        tracked=0 if result.lost else result.health.tracked,
        inlier_ratio=0.0 if result.lost else result.health.inlier_ratio,
    )


class CameraFactorMaker:
    """Keeps recent camera poses; ``factor`` makes one keyframe pair's camera factor.

    T_base_camera: (4, 4) mount (optical axes). kind: ``yaw`` or ``pose``, what a factor holds
    (module docstring). covariance_scale: variance multiplier on the camera's reported
    covariances (pose factors, and the metric steps kept); yaw_variance_scale: on its reported
    yaw (yaw factors). consistency_chi2: largest Mahalanobis distance between camera and radar
    steps (3 dof for pose factors, 1 for yaw factors); larger is an outlier.
    """

    def __init__(
        self,
        T_base_camera: np.ndarray,
        gate: CameraGate,
        scale: ScaleEstimator | SharedScale,
        covariance_scale: float,
        consistency_chi2: float,
        kind: CameraFactorKind,
        yaw_variance_scale: float,
        long_turn_s: float = 0.0,
        long_turn_sigma_rad: float = np.radians(2.0),
    ) -> None:
        if kind not in FACTOR_KINDS:
            raise ConfigError(
                f"unknown camera factor kind '{kind}' (choose {', '.join(FACTOR_KINDS)})"
            )
        self._mount = planar_from_camera(np.asarray(T_base_camera, dtype=float))
        self._gate = gate
        self._scale = scale
        self._covariance_scale = covariance_scale
        self._consistency_chi2 = consistency_chi2
        self._kind = kind
        self._yaw_variance_scale = yaw_variance_scale
        self._long_turn_s = long_turn_s if kind == "yaw" else 0.0  # a pose factor holds it
        self._long_turn_variance = long_turn_sigma_rad**2
        self._anchor: _Anchor | None = None
        self._samples: deque[_Sample] = deque()
        self.weight = 0.0
        """Gate weight of the latest frame."""
        self.outcomes: Counter[str] = Counter()
        """Keyframe pairs by outcome: used, untracked, gated, no_scale, inconsistent."""
        self._steps: list[tuple[float, float, np.ndarray, np.ndarray]] = []

    @property
    def latest_stamp_s(self) -> float:
        """Stamp of the newest camera frame (-inf before the first)."""
        return self._samples[-1].stamp_s if self._samples else -np.inf

    @property
    def scale(self) -> ScaleEstimator | SharedScale:
        """The windowed metric scale its factors use."""
        return self._scale

    @property
    def scale_m(self) -> float | None:
        """Metres per camera unit of the current camera map, None until established."""
        estimate = self._scale.estimate()
        return None if estimate is None else estimate.scale

    @property
    def steps(self) -> StepPairs:
        """Every pair that got a metric camera step, with the radar's step of it."""
        if not self._steps:
            return StepPairs(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 3)))
        a, b, radar, camera = zip(*self._steps, strict=True)
        return StepPairs(np.column_stack([a, b]), np.array(radar), np.array(camera))

    def add(self, result: CameraOdometryResult) -> float:
        """Take one camera odometry frame; returns its gate weight."""
        decision = self._gate.update(camera_health(result))
        if decision.reentered or result.reinitialized:
            self._scale.reset()  # a camera back from a loss brings a new scale
        if result.lost or result.reinitialized:
            self._anchor = None  # a long turn spans unbroken tracking only
        self.weight = decision.weight if not result.lost else 0.0
        tracking = decision.tracking if not result.lost else 0.0
        self._samples.append(
            _Sample(
                result.stamp_s,
                np.asarray(result.pose_world_camera, dtype=float),
                np.asarray(result.covariance, dtype=float),
                result.reinitializations,
                not result.lost,
                self.weight,
                tracking,
            )
        )
        while self._samples and self._samples[0].stamp_s < result.stamp_s - KEEP_S:
            self._samples.popleft()
        return self.weight

    def factor(
        self,
        stamp_a_s: float,
        stamp_b_s: float,
        radar_delta: np.ndarray,
        radar_covariance: np.ndarray,
    ) -> CameraFactor | None:
        """The camera factor between the keyframes at ``stamp_a_s`` and ``stamp_b_s``, or None.

        radar_delta / radar_covariance: (3,), (3, 3) the radar between factor of the same pair
        (base_link, tangent): the metric reference for the scale and the consistency check.
        Call once the camera has passed ``stamp_b_s`` (``latest_stamp_s``).
        """
        span = self._span(stamp_a_s, stamp_b_s)
        if span is None:
            self.outcomes["untracked"] += 1
            return None
        weight = min(s.weight for s in span)
        if weight <= 0.0:
            self.outcomes["gated"] += 1
            return None
        stamps = np.array([s.stamp_s for s in span])
        poses = np.array([s.pose for s in span])
        pose_a, pose_b = interpolate_se2(stamps, poses, np.array([stamp_a_s, stamp_b_s]))
        step = se2_between(pose_a, pose_b)
        radar_in_camera = se2_compose(
            se2_compose(se2_inverse(self._mount), radar_delta), self._mount
        )
        estimate = self._scale.update(step[:2], radar_in_camera[:2])
        if estimate is not None:
            covariance = self._covariance_scale * (span[0].covariance + span[-1].covariance)
            metric, metric_cov = metric_relative_pose(step, covariance, estimate)
            delta, delta_cov = se2_conjugate(metric, metric_cov, self._mount)
            self._steps.append((stamp_a_s, stamp_b_s, np.asarray(radar_delta, dtype=float), delta))
        if self._kind == "yaw":
            tracking = min(s.tracking for s in span)
            return self._yaw_factor(step[2], span, radar_delta, radar_covariance, tracking)
        if estimate is None:
            self.outcomes["no_scale"] += 1
            return None
        innovation = se2_between(radar_delta, delta)
        # Checked with the camera's own covariance: a degraded camera is weighed less in the
        # graph, but not let in with larger disagreements.
        chi2 = float(innovation @ np.linalg.solve(radar_covariance + delta_cov, innovation))
        if chi2 > self._consistency_chi2:
            self.outcomes["inconsistent"] += 1
            logger.debug("camera step at %.2f s disagrees with radar (chi2 %.1f)", stamp_b_s, chi2)
            return None
        self.outcomes["used"] += 1
        return CameraFactor(delta, inflate_covariance(delta_cov, weight), weight)

    def long_turn(self, index: int, stamp_s: float) -> LongTurn | None:
        """The camera's turn since the last long-turn keyframe, once ``long_turn_s`` has
        passed in one camera map with every frame tracked; keyframe ``index`` at ``stamp_s``
        then starts the next one. Call for keyframes whose pair got a camera factor."""
        if self._long_turn_s <= 0.0:
            return None
        span = self._span(stamp_s, stamp_s)
        if span is None:
            self._anchor = None
            return None
        stamps = np.array([s.stamp_s for s in span])
        poses = np.array([s.pose for s in span])
        yaw = float(interpolate_se2(stamps, poses, np.array([stamp_s]))[0, 2])
        anchor, map_id = self._anchor, span[0].map_id
        same_map = anchor is not None and anchor.map_id == map_id
        if same_map and stamp_s - anchor.stamp_s < self._long_turn_s:
            return None
        self._anchor = _Anchor(index, stamp_s, yaw, map_id)
        tracking = min(s.tracking for s in span)
        if not same_map or tracking <= 0.0:
            return None
        free = FREE_TRANSLATION_VARIANCE_M2
        covariance = inflate_covariance(np.diag([free, free, self._long_turn_variance]), tracking)
        return LongTurn(anchor.index, float(wrap_angle(yaw - anchor.yaw_rad)), covariance)

    def _yaw_factor(
        self,
        yaw_rad: float,
        span: list[_Sample],
        radar_delta: np.ndarray,
        radar_covariance: np.ndarray,
        weight: float,
    ) -> CameraFactor | None:
        """The camera's turn ``yaw_rad`` over ``span`` as a factor whose translation is the
        radar's, left free; None when the turns disagree beyond the check."""
        variance = self._yaw_variance_scale * (span[0].covariance[2, 2] + span[-1].covariance[2, 2])
        innovation = float(wrap_angle(yaw_rad - radar_delta[2]))
        if innovation**2 / (radar_covariance[2, 2] + variance) > self._consistency_chi2:
            self.outcomes["inconsistent"] += 1
            logger.debug("camera turn disagrees with radar by %.2f deg", np.degrees(innovation))
            return None
        self.outcomes["used"] += 1
        delta = np.array([radar_delta[0], radar_delta[1], yaw_rad])
        covariance = np.diag([FREE_TRANSLATION_VARIANCE_M2, FREE_TRANSLATION_VARIANCE_M2, variance])
        return CameraFactor(delta, inflate_covariance(covariance, weight), weight)

    def _span(self, stamp_a_s: float, stamp_b_s: float) -> list[_Sample] | None:
        """The frames from the last one at or before ``stamp_a_s`` to the first one at or after
        ``stamp_b_s``, if they exist, were all tracked and belong to one camera map."""
        samples = list(self._samples)
        stamps = np.array([s.stamp_s for s in samples])
        first = int(np.searchsorted(stamps, stamp_a_s, side="right")) - 1
        last = int(np.searchsorted(stamps, stamp_b_s, side="left"))
        if first < 0 or last >= len(samples):
            return None
        span = samples[first : last + 1]
        if any(s.map_id != span[0].map_id or not s.tracked for s in span):
            return None
        return span


def get_camera_factor_maker(
    backend: BackendConfig,
    slam: SlamConfig,
    T_base_camera: np.ndarray,
    scale: ScaleEstimator | SharedScale | None = None,
    kind: CameraFactorKind | None = None,
) -> CameraFactorMaker:
    """The camera factor maker of the backend and slam config sections; ``scale``: one to
    use instead of its own (``backend.scale``); ``kind``: what its factors hold, instead of
    ``slam.camera_factor``."""
    return CameraFactorMaker(
        T_base_camera,
        get_camera_gate(backend.camera_gate),
        scale if scale is not None else get_scale_estimator(backend.scale),
        slam.camera_covariance_scale,
        slam.camera_consistency_chi2,
        kind if kind is not None else slam.camera_factor,
        slam.camera_yaw_variance_scale,
        slam.camera_long_turn_s,
        np.radians(slam.camera_long_turn_sigma_deg),
    )
