"""A closed tour walked in time: a periodic spline, curvature- and acceleration-limited speeds,
and poses sampled at a fixed rate (the last step of :mod:`smokyslam.sim.planner`)."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator
from scipy.ndimage import maximum_filter1d

from smokyslam.config import TrajectoryConfig
from smokyslam.sim.trajectory import Trajectory

SAMPLE_RATE_HZ = 200.0  # trajectory samples per second
ACCEL_MPS2 = 0.4  # walking speed changes at most this fast
TURN_MARGIN = 0.95  # planned yaw rates stay 5 % under the limit
SPEED_MARGIN = 0.01  # planned speeds stay 1 % inside [min_speed, max_speed]


def arc_lengths(path: np.ndarray) -> np.ndarray:
    """(N,) distance along an (N, 2) polyline from its first point."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])


class WalkLoop:
    """A closed tour as a periodic spline with its curvature-limited speeds along arc length."""

    def __init__(self, points: np.ndarray, config: TrajectoryConfig, clear: bool = True) -> None:
        closed = np.vstack([points, points[:1]])
        cum = arc_lengths(closed)
        self.spline = CubicSpline(cum, closed, bc_type="periodic")
        self.length_m = float(cum[-1])
        # Nodes split each knot interval in three: curvature peaks sit at the knots.
        self.s = (cum[:-1, None] + np.diff(cum)[:, None] * np.arange(3) / 3.0).ravel()
        d1, d2 = self.spline(self.s, 1), self.spline(self.s, 2)
        self.metric = np.linalg.norm(d1, axis=1)  # metres walked per unit of s (about 1)
        self.kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / self.metric**3
        # Curvature peaks can fall between nodes: cap speeds by the largest of five neighbours.
        kappa_peak = maximum_filter1d(np.abs(self.kappa), size=5, mode="wrap")
        turn_limited = TURN_MARGIN * config.max_turn_rate_radps / np.maximum(kappa_peak, 1e-9)
        # Plan 1 % inside the speed limits: sampling and interpolation wobble by a few 0.1 %.
        self.v_min = config.min_speed_mps * (1.0 + SPEED_MARGIN)
        self.v_max = config.max_speed_mps * (1.0 - SPEED_MARGIN)
        self.v_cap = np.clip(turn_limited, self.v_min, self.v_max)
        # Walkable within every limit: clear of walls, and no curve too tight for min_speed.
        self.feasible = clear and bool(turn_limited.min() >= self.v_min)

    def speeds(self, cruise_mps: float) -> np.ndarray:
        """(n,) speed at ``self.s``: capped by cruise and curvature, then acceleration-limited."""
        n, two_a = len(self.s), 2.0 * ACCEL_MPS2
        s3 = np.concatenate([self.s - self.length_m, self.s, self.s + self.length_m])
        u = np.tile(np.minimum(self.v_cap, cruise_mps) ** 2, 3)  # three laps: periodic limits
        forward = two_a * s3 + np.minimum.accumulate(u - two_a * s3)
        backward = -two_a * s3 + np.minimum.accumulate((u + two_a * s3)[::-1])[::-1]
        return np.sqrt(np.minimum(u, np.minimum(forward, backward))[n : 2 * n])

    def node_times(self, cruise_mps: float) -> np.ndarray:
        """(n + 1,) seconds at ``self.s`` and back at the start."""
        v = self.speeds(cruise_mps)
        ds = np.diff(np.append(self.s, self.length_m)) * self.metric
        dt = 2.0 * ds / (v + np.roll(v, -1))
        return np.concatenate([[0.0], np.cumsum(dt)])

    def duration_s(self, cruise_mps: float) -> float:
        return float(self.node_times(cruise_mps)[-1])

    def cruise_for(self, duration_s: float) -> float:
        """Cruise speed making one lap last ``duration_s`` (clamped to the speed limits)."""
        lo, hi = self.v_min, self.v_max
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.duration_s(mid) > duration_s else (lo, mid)
        return 0.5 * (lo + hi)

    def sample(self, duration_s: float, cruise_mps: float, laps: int = 1) -> Trajectory:
        """Poses at SAMPLE_RATE_HZ over ``[0, duration_s]`` walking ``laps`` laps at cruise speed.

        Laps lasting within 0.1 % of ``duration_s`` are stretched to end exactly on time; longer
        ones are cut off at ``duration_s``.
        """
        t_lap = self.node_times(cruise_mps)
        t_nodes = np.append((t_lap[:-1] + t_lap[-1] * np.arange(laps)[:, None]).ravel(), 0.0)
        t_nodes[-1] = laps * t_lap[-1]
        s_nodes = np.append((self.s + self.length_m * np.arange(laps)[:, None]).ravel(), 0.0)
        s_nodes[-1] = laps * self.length_m
        if abs(t_nodes[-1] - duration_s) < 1e-3 * duration_s:
            t_nodes = t_nodes * (duration_s / t_nodes[-1])
        stamps = np.linspace(0.0, duration_s, int(np.ceil(duration_s * SAMPLE_RATE_HZ)) + 1)
        s = PchipInterpolator(t_nodes, s_nodes)(np.minimum(stamps, t_nodes[-1])) % self.length_m
        xy, d1 = self.spline(s), self.spline(s, 1)
        yaw = np.arctan2(d1[:, 1], d1[:, 0])
        return Trajectory(stamps, np.column_stack([xy, yaw]))
