"""Radar odometry: one ``register`` per radar frame, returning the frames it finalized.

Both classes estimate the pose of the radar (sensor frame), starting at ``initial_pose``
(identity by default) in their own world frame; :func:`poses_world_base` moves those poses to
base_link with the rig's ``T_base_radar``.

Input: a :class:`RadarScan` with per-point Doppler, and the IMU samples received since the
previous scan (gyro z is integrated by :class:`GyroIntegrator`'s convention: a sample's rate
holds since the previous sample). Works alike for 10 Hz radar with 100 Hz IMU and for CARMEN
laser logs emulated as radar; the latter are keyframe-subsampled (0.1-0.9 m and up to 78°
between scans), much harder for scan matching than 10 Hz radar.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from smokyslam.config import RadarOdometryConfig
from smokyslam.frontends.radar.motion_prior import MotionPrior, MotionPriorEstimator
from smokyslam.frontends.radar.scan_matcher import JointIcpMatcher, MatchResult
from smokyslam.geometry import se2_compose, se2_from_matrix, se2_inverse
from smokyslam.types import ImuSample, Odometry, OdometryHealth, RadarScan


def poses_world_base(poses_world_radar: np.ndarray, T_base_radar: np.ndarray) -> np.ndarray:
    """(N, 3) base_link poses from (N, 3) radar poses and the (4, 4) or (3, 3) mounting."""
    mount = se2_from_matrix(T_base_radar)
    return se2_compose(np.asarray(poses_world_radar, dtype=float), se2_inverse(mount))


def _doppler_extra(prior: MotionPrior) -> dict[str, float]:
    return {
        "doppler_inliers": float(prior.doppler.inliers),
        "doppler_valid": float(prior.doppler.valid),
    }


class DeadReckoning:
    """Integrates the Doppler ego-velocity and the gyro alone: the baseline for scan matching.

    A frame is ``lost`` when its Doppler velocity could not be estimated (it then coasts on
    the last velocity).
    """

    def __init__(self, config: RadarOdometryConfig, initial_pose: np.ndarray | None = None):
        self._prior = MotionPriorEstimator(config)
        self.pose = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, float)

    def register(self, scan: RadarScan, imu: Iterable[ImuSample] = ()) -> list[Odometry]:
        """Advance by the motion prior of ``scan``: always exactly one finalized frame."""
        prior = self._prior.predict(scan, imu)
        self.pose = se2_compose(self.pose, prior.delta)
        health = OdometryHealth(
            inliers=prior.doppler.inliers,
            fitness=float(np.sqrt(np.trace(prior.doppler.covariance))),
            lost=not prior.doppler.valid,
            extra=_doppler_extra(prior),
        )
        return [Odometry(scan.stamp_s, self.pose.copy(), prior.delta, prior.covariance, health)]

    def flush(self) -> list[Odometry]:
        """Nothing is ever pending."""
        return []

    @property
    def gyro_bias_radps(self) -> None:
        """Dead reckoning estimates no gyro bias."""
        return None


@dataclass
class _Pending:
    points_xy: np.ndarray
    prior: MotionPrior  # carries the frame's stamp_s


class RadarOdometry:
    """Doppler/gyro prior combined with scan matching (``config.matcher``).

    Frames are registered in batches (``joint_batch_frames`` or ``kiss_batch_frames``):
    ``register`` returns an empty list until a batch is complete, then the batch's frames in
    order; ``flush`` registers the last, partial batch at the end of a log. Every returned
    frame is a keyframe whose ``delta`` is the step from the frame before it.
    ``joint-icp`` solves the batch's poses jointly with the prior; ``kiss-icp`` registers the
    prior-stitched batch as one cloud; ``none`` keeps the prior alone. A frame is ``lost``
    when scan matching found too few correspondences for it.
    """

    def __init__(self, config: RadarOdometryConfig, initial_pose: np.ndarray | None = None):
        self._matcher = _make_matcher(config)
        self.pose = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, float)
        self._pending: list[_Pending] = []
        self._batch_frames = (
            config.kiss_batch_frames if config.matcher == "kiss-icp" else config.joint_batch_frames
        )
        self._started = False
        # The heading filter needs one registration per prediction, jointly with the prior.
        self._heading_feedback = config.matcher == "joint-icp" and self._batch_frames == 1
        self._prior = MotionPriorEstimator(
            config, anchored=self._heading_feedback, initial_yaw_rad=float(self.pose[2])
        )

    @property
    def gyro_bias_radps(self) -> float | None:
        """The gyro-bias estimate in use, rad/s (the heading filter's, replaced by the map-age
        fit once it is sure); None when none is estimated (a batch matcher, or
        ``gyro_bias_sigma_degps`` 0)."""
        return self._prior.heading.bias_radps if self._prior.estimates_bias else None

    def register(self, scan: RadarScan, imu: Iterable[ImuSample] = ()) -> list[Odometry]:
        """Queue ``scan`` with its prior; register the batch when it is full."""
        prior = self._prior.predict(scan, imu)
        if not self._started:  # the first frame defines the origin
            prior = MotionPriorEstimator.first(prior)
            self._started = True
        self._pending.append(_Pending(scan.points_xy_m, prior))
        if len(self._pending) < self._batch_frames:
            return []
        return self.flush()

    def flush(self) -> list[Odometry]:
        """Register whatever frames are queued and return them."""
        if not self._pending:
            return []
        batch, self._pending = self._pending, []
        results = self._matcher.register_batch(
            [p.points_xy for p in batch], self.pose, [p.prior for p in batch]
        )
        self.pose = results[-1].pose_world_sensor.copy()
        for pending, result in zip(batch, results, strict=True):
            if result.matched and result.inliers > 0:
                self._prior.registered(pending.prior, result.delta)
                if self._heading_feedback:
                    self._prior.correct_heading(
                        pending.prior,
                        result.delta,
                        result.covariance,
                        float(result.pose_world_sensor[2]),
                        result.map_age,
                    )
        extra = {}
        if self._prior.estimates_bias:  # where the bias estimate stands after this batch
            extra = {
                "gyro_bias_radps": float(self.gyro_bias_radps),
                "gyro_bias_sigma_radps": self._prior.bias_sigma_radps,
            }
        return [_odometry(p, r, extra) for p, r in zip(batch, results, strict=True)]


def _odometry(pending: _Pending, result: MatchResult, extra: dict[str, float]) -> Odometry:
    """``extra``: added to the health's (the gyro bias estimate, when there is one)."""
    health = OdometryHealth(
        inliers=result.inliers,
        fitness=result.fitness,
        lost=not result.matched,
        extra={**_doppler_extra(pending.prior), **extra},
    )
    return Odometry(
        pending.prior.stamp_s,
        result.pose_world_sensor.copy(),
        result.delta,
        result.covariance,
        health,
    )


class ScanMatcher(Protocol):
    """What :class:`RadarOdometry` needs from a scan matcher."""

    def register_batch(
        self, frames_xy: list[np.ndarray], anchor_pose: np.ndarray, priors: list[MotionPrior]
    ) -> list[MatchResult]:
        """Register B frames of (N_b, 2) sensor-frame points that follow the world pose
        ``anchor_pose`` (3,), with B priors (frame b-1 -> b); one result per frame."""
        ...


class _PriorOnlyMatcher:
    """The prior alone, behind the matcher interface (``matcher: none``)."""

    def register_batch(
        self, frames_xy: list[np.ndarray], anchor_pose: np.ndarray, priors: list[MotionPrior]
    ) -> list[MatchResult]:
        results, pose = [], anchor_pose
        for prior in priors:
            pose = se2_compose(pose, prior.delta)
            results.append(MatchResult(pose, prior.delta, prior.covariance, 0, np.nan, True))
        return results


def _make_matcher(config: RadarOdometryConfig) -> ScanMatcher:
    if config.matcher == "joint-icp":
        return JointIcpMatcher(config)
    if config.matcher == "kiss-icp":
        from smokyslam.frontends.radar.kiss_matcher import KissBatchMatcher

        return KissBatchMatcher(config)
    return _PriorOnlyMatcher()
