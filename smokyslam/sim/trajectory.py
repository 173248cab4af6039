"""A simulated walk: densely sampled ground-truth poses of ``base_link`` in the world."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.geometry import interpolate_se2, wrap_angle


@dataclass
class Trajectory:
    """Planar poses sampled densely enough to interpolate (>= 100 Hz).

    stamps_s: (N,) seconds from the start of the log, strictly increasing.
    poses_world_base: (N, 3) [x_m, y_m, yaw_rad] of base_link in the world.
    """

    stamps_s: np.ndarray
    poses_world_base: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.stamps_s[-1] - self.stamps_s[0])

    def pose_at(self, stamp_s: np.ndarray | float) -> np.ndarray:
        """(3,) or (M, 3) interpolated poses."""
        return interpolate_se2(self.stamps_s, self.poses_world_base, stamp_s)

    def velocity_world_at(self, stamp_s: np.ndarray | float) -> np.ndarray:
        """(2,) or (M, 2) world-frame velocity of base_link, m/s (central differences)."""
        vx = np.gradient(self.poses_world_base[:, 0], self.stamps_s)
        vy = np.gradient(self.poses_world_base[:, 1], self.stamps_s)
        q = np.atleast_1d(stamp_s)
        v = np.stack([np.interp(q, self.stamps_s, vx), np.interp(q, self.stamps_s, vy)], axis=-1)
        return v if np.ndim(stamp_s) else v[0]

    def yaw_rate_at(self, stamp_s: np.ndarray | float) -> np.ndarray | float:
        """Yaw rate of base_link, rad/s."""
        yaw = np.unwrap(self.poses_world_base[:, 2])
        rate = np.gradient(yaw, self.stamps_s)
        return np.interp(stamp_s, self.stamps_s, rate)

    @property
    def path_length_m(self) -> float:
        steps = np.diff(self.poses_world_base[:, :2], axis=0)
        return float(np.linalg.norm(steps, axis=1).sum())

    def heading_change_rad(self) -> float:
        """Total absolute turning, radians."""
        return float(np.abs(wrap_angle(np.diff(self.poses_world_base[:, 2]))).sum())
