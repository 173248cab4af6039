"""The motion prior of a radar rig: Doppler ego-velocity for translation, gyro for yaw.

Between two radar frames the sensor is assumed to hold a constant body twist, so the step is
the SE(2) exponential of ``[v * dt, yaw_delta]`` with ``v`` the newer frame's Doppler velocity.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from smokyslam.config import RadarOdometryConfig
from smokyslam.frontends.radar.doppler import EgoVelocity, estimate_ego_velocity
from smokyslam.frontends.radar.map_age_bias import MapAge, MapAgeBias, ScanYaw, scan_yaw
from smokyslam.geometry import se2_exp, wrap_angle
from smokyslam.types import ImuSample, RadarScan

NO_GYRO_YAW_SIGMA_RAD = np.pi
"""Yaw sigma of a step without gyro samples: the prior says nothing about yaw."""

GAP_SIGMA_M = 2.0
"""Translation sigma of a step across a gap in the log (longer than ``max_step_s``): the
prior says next to nothing, and scan matching finds the rig in the map it has."""


@dataclass
class MotionPrior:
    """Predicted step between consecutive frames.

    delta: (3,) [x_m, y_m, yaw_rad] in the earlier frame's sensor frame.
    covariance: (3, 3) of this step alone, in the same order (what dead reckoning reports).
    doppler: the ego-velocity estimate it came from. dt_s: the frame interval it covers.
    match_covariance: (3, 3) prior covariance for scan matching: the yaw variance is the
    heading filter's, which also carries the previous frame's yaw uncertainty.
    stamp_s: the frame's stamp. gyro_yaw_rad: the raw gyro integral up to it, from the
    starting yaw, no bias taken off (NaN once a frame had no gyro samples).
    """

    delta: np.ndarray
    covariance: np.ndarray
    doppler: EgoVelocity
    match_covariance: np.ndarray | None = None
    dt_s: float = 0.0
    stamp_s: float = np.nan
    gyro_yaw_rad: float = np.nan

    def __post_init__(self) -> None:
        if self.match_covariance is None:
            self.match_covariance = self.covariance

    @cached_property
    def information(self) -> np.ndarray:
        """(3, 3) inverse of ``match_covariance``: what scan matching weighs the prior by."""
        return np.linalg.inv(self.match_covariance)


class GyroIntegrator:
    """Sums gyro z into yaw increments between radar frames.

    A sample's rate is held over the interval since the previous sample (for the first one,
    since the previous radar frame), so one sample per frame carrying ``yaw_delta / dt`` (the
    CARMEN emulation) integrates back to ``yaw_delta``, and 100 Hz samples integrate as usual.
    """

    def __init__(self) -> None:
        self._last_stamp_s: float | None = None

    def integrate(self, samples: Iterable[ImuSample], start_s: float) -> float | None:
        """Yaw increment (rad) from ``samples`` (time-ordered); None when there are none."""
        yaw_rad, count = 0.0, 0
        last = start_s if self._last_stamp_s is None else max(self._last_stamp_s, start_s)
        for sample in samples:
            yaw_rad += float(sample.gyro_radps[2]) * max(sample.stamp_s - last, 0.0)
            last = sample.stamp_s
            count += 1
        self._last_stamp_s = last
        return yaw_rad if count else None


def exp_jacobian(twist: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """(3, 3) numerical Jacobian of :func:`se2_exp` at ``twist``."""
    perturb = np.eye(3) * step
    return ((se2_exp(twist + perturb) - se2_exp(twist - perturb)) / (2.0 * step)).T


class HeadingFilter:
    """Kalman filter on ``[yaw, gyro bias]``, with scan matching as a yaw measurement.

    Scan matching against the local map measures the yaw relative to that map in every
    frame; the gyro predicts it. Tracking how the two disagree over many frames estimates the
    gyro bias, which a frame-to-frame comparison cannot see under the per-frame noise. The
    yaw variance it predicts (the previous frame's yaw uncertainty plus the gyro step) is the
    yaw prior the matcher should use.

    Registrations are not independent yaw measurements: frames close in time match a map
    made mostly of the same points and share its errors. Registrations within
    ``decorrelation_s`` count as one measurement, so each frame's scan variance is inflated
    by ``decorrelation_s / dt`` (none at 1 s CARMEN steps, 10x at 10 Hz radar). Without it
    the bias estimate at 10 Hz locked onto map errors within seconds (office seed 7:
    -0.15 deg/s estimated against a true +0.095 deg/s).
    """

    def __init__(
        self,
        gyro_sigma_radps: float,
        bias_sigma_radps: float,
        bias_walk: float,
        decorrelation_s: float = 0.0,
    ):
        self.bias_radps = 0.0
        self.covariance = np.diag([0.0, bias_sigma_radps**2])  # [yaw rad, bias rad/s]
        self._gyro_var = gyro_sigma_radps**2
        self._walk_var = bias_walk**2
        self._decorrelation_s = decorrelation_s
        self._dt_s = 1.0

    def predict(self, dt_s: float) -> float:
        """Propagate over one frame interval; return the predicted yaw variance (rad^2)."""
        F = np.array([[1.0, -dt_s], [0.0, 1.0]])
        Q = np.diag([self._gyro_var * dt_s**2, self._walk_var * dt_s])
        self._dt_s = dt_s
        self.covariance = F @ self.covariance @ F.T + Q
        return float(self.covariance[0, 0])

    def correct(self, scan: ScanYaw | None) -> None:
        """Fold in one frame's registration as its scan-only yaw measurement (``scan_yaw``:
        recovered from how far the registration moved the yaw and how much it shrank its
        variance; None when the scan added nothing). Its variance is inflated for the frames
        that share its map (``decorrelation_s``).
        """
        if scan is None:
            return
        scan_var = scan.decorrelated_variance(self._decorrelation_s, self._dt_s)
        innovation = scan.innovation_rad
        P = self.covariance
        gain = P[:, 0] / (P[0, 0] + scan_var)
        self.bias_radps += float(gain[1] * innovation)
        self.covariance = P - np.outer(gain, P[0, :])


class MotionPriorEstimator:
    """Turns each radar frame (and the gyro samples since the previous one) into a prior.

    With ``anchored`` (scan matching feeds every frame back through :meth:`correct_heading`)
    the gyro bias is estimated and the matcher's yaw prior comes from the heading filter;
    otherwise the prior is the plain Doppler/gyro step. Where the filter estimates a bias, the
    map-age fit (``map_age_bias.py``) runs beside it, and once it is sure enough
    (``map_age_bias_below_degps``) its bias replaces the filter's after every frame.
    ``initial_yaw_rad``: where the raw gyro integral starts.
    """

    def __init__(
        self, config: RadarOdometryConfig, anchored: bool = False, initial_yaw_rad: float = 0.0
    ) -> None:
        self._config = config
        self._anchored = anchored
        self._gyro = GyroIntegrator()
        self._gyro_yaw_rad = float(initial_yaw_rad)
        self.estimates_bias = anchored and config.gyro_bias_sigma_degps > 0
        """Whether the heading filter (and the map-age fit beside it) estimates a gyro bias."""
        self.map_age = (
            MapAgeBias(config.heading_decorrelation_s, np.radians(config.map_age_bias_below_degps))
            if self.estimates_bias and config.map_age_bias_below_degps is not None
            else None
        )
        self._last_stamp_s: float | None = None
        self._last_velocity = np.zeros(2)
        self._registered_velocity = False  # _last_velocity came from scan matching
        self.heading = HeadingFilter(
            np.radians(config.yaw_rate_sigma_degps),
            np.radians(config.gyro_bias_sigma_degps),
            np.radians(config.gyro_bias_walk_degps),
            config.heading_decorrelation_s,
        )

    @property
    def bias_sigma_radps(self) -> float:
        """Sigma of the bias in use: the map-age fit's once it has replaced the filter's,
        else the heading filter's."""
        if self.map_age is not None and self.map_age.bias_radps is not None:
            return float(self.map_age.sigma_radps)
        return float(np.sqrt(self.heading.covariance[1, 1]))

    def predict(self, scan: RadarScan, imu: Iterable[ImuSample] = ()) -> MotionPrior:
        """The step from the previous frame to ``scan`` (zero for the first frame)."""
        config = self._config
        points = scan.points_xy_m
        doppler = estimate_ego_velocity(
            np.arctan2(points[:, 1], points[:, 0]),
            scan.doppler_mps,
            inlier_threshold_mps=config.doppler_inlier_mps,
            min_inliers=config.doppler_min_inliers,
        )
        previous = self._last_stamp_s
        self._last_stamp_s = scan.stamp_s
        yaw_delta = self._gyro.integrate(imu, scan.stamp_s if previous is None else previous)
        stamps = {"stamp_s": scan.stamp_s}
        if previous is None:
            stamps["gyro_yaw_rad"] = self._gyro_yaw_rad
            return MotionPrior(np.zeros(3), np.diag([1e-6, 1e-6, 1e-6]), doppler, **stamps)
        self._gyro_yaw_rad += np.nan if yaw_delta is None else yaw_delta
        stamps["gyro_yaw_rad"] = self._gyro_yaw_rad
        dt_s = max(scan.stamp_s - previous, 1e-6)
        if dt_s > config.max_step_s:  # a gap in the log: nothing is known of the motion
            gap_cov = np.diag([GAP_SIGMA_M**2, GAP_SIGMA_M**2, NO_GYRO_YAW_SIGMA_RAD**2])
            return MotionPrior(np.zeros(3), gap_cov, doppler, gap_cov, dt_s, **stamps)
        velocity_cov = doppler.covariance
        if doppler.valid:
            self._last_velocity = doppler.velocity_mps
            self._registered_velocity = False
        elif self._registered_velocity:  # no Doppler: coast on what scan matching found
            velocity_cov = np.eye(2) * config.coast_sigma_mps**2
        else:
            # Coast on the last velocity, with the uncertainty of not knowing it at all.
            velocity_cov = np.eye(2) * max(1.0, float(self._last_velocity @ self._last_velocity))
        twist = np.array([*(self._last_velocity * dt_s), 0.0])
        sigma_step = config.velocity_sigma_rel * np.hypot(*twist[:2])
        sigma_step += config.velocity_sigma_mps * dt_s
        twist_cov = np.zeros((3, 3))
        twist_cov[:2, :2] = velocity_cov * dt_s**2 + np.eye(2) * sigma_step**2
        if yaw_delta is None:
            twist_cov[2, 2] = NO_GYRO_YAW_SIGMA_RAD**2
            anchored_yaw_var = twist_cov[2, 2]
        else:
            twist[2] = yaw_delta - self.heading.bias_radps * dt_s
            twist_cov[2, 2] = (np.radians(config.yaw_rate_sigma_degps) * dt_s) ** 2
            anchored_yaw_var = self.heading.predict(dt_s) if self._anchored else 0.0
        J = exp_jacobian(twist)
        anchored_cov = twist_cov.copy()
        anchored_cov[2, 2] = max(anchored_yaw_var, twist_cov[2, 2])
        return MotionPrior(
            se2_exp(twist),
            J @ twist_cov @ J.T,
            doppler,
            J @ anchored_cov @ J.T,
            dt_s,
            **stamps,
        )

    def registered(self, prior: MotionPrior, registered_delta: np.ndarray) -> None:
        """A frame's step as scan matching registered it: without Doppler, its velocity is
        what the next frames coast on."""
        if prior.doppler.valid or prior.dt_s <= 0.0:
            return
        self._last_velocity = np.asarray(registered_delta[:2], dtype=float) / prior.dt_s
        self._registered_velocity = True

    def correct_heading(
        self,
        prior: MotionPrior,
        registered_delta: np.ndarray,
        covariance: np.ndarray,
        registered_yaw_rad: float = np.nan,
        map_age: MapAge | None = None,
    ) -> None:
        """Feed one frame's registered step (solved with ``prior.match_covariance``) back
        into the heading filter, and with its registered yaw and what it matched
        (``map_age``) into the map-age fit, whose bias then replaces the filter's once sure."""
        prior_var, posterior_var = prior.match_covariance[2, 2], float(covariance[2, 2])
        innovation = float(wrap_angle(registered_delta[2] - prior.delta[2]))
        scan = scan_yaw(prior_var, posterior_var, innovation)
        if self.map_age is not None and map_age is not None and scan is not None:
            scan_yaw_rad = registered_yaw_rad - innovation + scan.innovation_rad
            offset = scan_yaw_rad - prior.gyro_yaw_rad
            self.map_age.add(prior.stamp_s, offset, scan, prior.dt_s, map_age)
        self.heading.correct(scan)
        bias = None if self.map_age is None else self.map_age.bias_radps
        if bias is not None:
            self.heading.bias_radps = bias

    @staticmethod
    def first(prior: MotionPrior) -> MotionPrior:
        """The prior of the first frame, which defines the origin: no step."""
        return replace(prior, delta=np.zeros(3), match_covariance=prior.covariance)
