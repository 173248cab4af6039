"""Doppler velocity and gyro yaw rate integrated between keyframes into one relative pose.

The result feeds one ``BetweenFactorPose2`` per keyframe pair, with the covariance propagated
through the integration (first order) and expressed in gtsam's Pose2 tangent.
"""

from __future__ import annotations

import numpy as np

from smokyslam.backends.noise import tangent_covariance
from smokyslam.geometry import wrap_angle


def integrate_velocity(
    dt_s: np.ndarray,
    velocity_mps: np.ndarray,
    velocity_covariance: np.ndarray,
    yaw_rate_radps: np.ndarray,
    yaw_rate_variance: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate K constant-rate segments into a relative pose and its covariance.

    dt_s: (K,) segment lengths, s. velocity_mps: (K, 2) body-frame planar velocity (base_link,
    already corrected for the radar lever arm), m/s. velocity_covariance: (K, 2, 2), m^2/s^2.
    yaw_rate_radps: (K,) rad/s. yaw_rate_variance: (K,) rad^2/s^2 of each segment's mean rate
    (white noise only; inflate it to cover gyro bias).

    Each segment moves along its mid-segment heading. Returns ``delta`` (3,) ``[x_m, y_m,
    yaw_rad]`` of the end in the start frame and its (3, 3) covariance in gtsam's Pose2 tangent
    ``[x, y, theta]``.
    """
    dt = np.atleast_1d(np.asarray(dt_s, dtype=float))
    velocity = np.asarray(velocity_mps, dtype=float).reshape(-1, 2)
    velocity_cov = np.asarray(velocity_covariance, dtype=float).reshape(-1, 2, 2)
    rate = np.atleast_1d(np.asarray(yaw_rate_radps, dtype=float))
    rate_var = np.atleast_1d(np.asarray(yaw_rate_variance, dtype=float))
    pose = np.zeros(3)
    covariance = np.zeros((3, 3))
    # A keyframe gap holds a handful of segments: the recursion is short and sequential.
    for k in range(dt.size):
        heading = pose[2] + 0.5 * rate[k] * dt[k]
        c, s = np.cos(heading), np.sin(heading)
        R = np.array([[c, -s], [s, c]])
        dR_v = np.array(
            [-s * velocity[k, 0] - c * velocity[k, 1], c * velocity[k, 0] - s * velocity[k, 1]]
        )
        F = np.eye(3)
        F[:2, 2] = dR_v * dt[k]
        G_v = np.zeros((3, 2))
        G_v[:2] = R * dt[k]
        G_w = np.array([*(dR_v * dt[k] * 0.5 * dt[k]), dt[k]])
        covariance = (
            F @ covariance @ F.T + G_v @ velocity_cov[k] @ G_v.T + np.outer(G_w, G_w) * rate_var[k]
        )
        pose[:2] += R @ velocity[k] * dt[k]
        pose[2] += rate[k] * dt[k]
    delta = np.array([pose[0], pose[1], wrap_angle(pose[2])])
    return delta, tangent_covariance(delta, covariance)


class VelocityIntegrator:
    """Collects velocity/yaw-rate segments online until the next keyframe takes them."""

    def __init__(self) -> None:
        self._segments: list[tuple[float, np.ndarray, np.ndarray, float, float]] = []

    def add(
        self,
        dt_s: float,
        velocity_mps: np.ndarray,
        velocity_covariance: np.ndarray,
        yaw_rate_radps: float,
        yaw_rate_variance: float,
    ) -> None:
        """Append one segment (units and frames as in :func:`integrate_velocity`)."""
        self._segments.append(
            (
                dt_s,
                np.asarray(velocity_mps),
                np.asarray(velocity_covariance),
                yaw_rate_radps,
                yaw_rate_variance,
            )
        )

    def take(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The integrated ``(delta (3,), covariance (3, 3))`` since the last take, or None."""
        if not self._segments:
            return None
        dt, v, cov, rate, rate_var = zip(*self._segments, strict=True)
        self._segments.clear()
        return integrate_velocity(
            np.array(dt), np.array(v), np.array(cov), np.array(rate), np.array(rate_var)
        )
