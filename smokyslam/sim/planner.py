"""Walking paths: a smooth, timed closed tour of a World, walked forwards like a person.

Steps 1-4 (walkable cells, stops, tours, legs) are in :mod:`smokyslam.sim.walk_graph` and
step 7's timing in :mod:`smokyslam.sim.walk_loop`; here:

5. Where the walker turns back (> 100 deg at a stop) it walks a teardrop loop around the stop.
6. Smoothing until the curvature allows ``min_speed`` within the turn-rate limit, pushing the
   path back out wherever it comes closer than ``clearance_m`` + 1 cell to a wall.
7. Speeds: capped by curvature and cruise speed, acceleration-limited; the longest tour that
   fits at full speed is chosen and its cruise speed bisected so the walk lasts ``duration_s``.

The walk ends where it began and never stops: speed stays within [min_speed, max_speed] and the
heading is the direction of motion.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from smokyslam.config import TrajectoryConfig
from smokyslam.errors import ConfigError
from smokyslam.geometry import wrap_angle
from smokyslam.sim.trajectory import Trajectory
from smokyslam.sim.walk_graph import WalkGrid, WalkLegs, growing_tours, tour_stops, walk_clearance_m
from smokyslam.sim.walk_loop import TURN_MARGIN, WalkLoop, arc_lengths
from smokyslam.sim.world import World

logger = logging.getLogger(__name__)

_PREFERRED_SPEED = 0.75  # of max_speed: repeated tours are walked near this pace
_LOOP_TURN_RAD = np.radians(100.0)  # sharper turns at a waypoint become teardrop loops
_TANGENT_BACK_M = 1.5  # a teardrop leaves the leg this far before its waypoint
_DS_M = 0.05  # polyline spacing while smoothing


def turn_radius_m(config: TrajectoryConfig) -> float:
    """Tightest curve radius walkable at ``min_speed_mps`` within the turn-rate limit."""
    return config.min_speed_mps / (TURN_MARGIN * config.max_turn_rate_radps)


def loop_radius_m(config: TrajectoryConfig) -> float:
    """Radius of the teardrop loops in which the walker turns back."""
    return 1.3 * turn_radius_m(config)


def start_clearance_m(config: TrajectoryConfig, resolution_m: float) -> float:
    """Clearance a start or waypoint needs for a loop around it."""
    return loop_radius_m(config) + walk_clearance_m(config, resolution_m)


def _point_at(path: np.ndarray, cum: np.ndarray, s_m: float) -> np.ndarray:
    return np.array([np.interp(s_m, cum, path[:, 0]), np.interp(s_m, cum, path[:, 1])])


def _teardrop(
    a: np.ndarray, w: np.ndarray, b: np.ndarray, radius_m: float, sign: float
) -> tuple[np.ndarray, int]:
    """Points A, a circle arc around W (entered and left tangentially), B; and the arc middle.

    ``sign`` +1 circles counter-clockwise (a left turn overall), -1 clockwise.
    """
    da, db = np.linalg.norm(a - w), np.linalg.norm(b - w)
    r = min(radius_m, 0.9 * da, 0.9 * db)
    theta_t = np.arctan2(*(a - w)[::-1]) + sign * np.arccos(r / da)
    theta_u = np.arctan2(*(b - w)[::-1]) - sign * np.arccos(r / db)
    sweep = (sign * (theta_u - theta_t)) % (2.0 * np.pi)
    n = max(8, int(np.ceil(r * sweep / _DS_M)))
    angles = theta_t + sign * np.linspace(0.0, sweep, n)
    arc = w + r * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    return np.vstack([a, arc, b]), 1 + n // 2


def _resample_closed(points: np.ndarray, start_s: float = 0.0) -> np.ndarray:
    """(N, 2) points every ~_DS_M along the closed polyline, the first at arc length start_s."""
    closed = np.vstack([points, points[:1]])
    step = np.linalg.norm(np.diff(closed, axis=0), axis=1)
    closed = closed[np.concatenate([[True], step > 1e-9])]
    cum = arc_lengths(closed)
    n = max(16, round(cum[-1] / _DS_M))
    s = (start_s + np.arange(n) * cum[-1] / n) % cum[-1]
    return np.stack([np.interp(s, cum, closed[:, 0]), np.interp(s, cum, closed[:, 1])], axis=-1)


def _respace_smooth(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points every ~_DS_M along a periodic spline through a closed, already smooth path.

    Unlike linear resampling this adds no millimetre kinks, which a spline would turn into
    curvature noise. Also returns (N,) the spline's peak |curvature|, 1/m, around each point
    (checked at the point and a third of a step to either side), as the final walk sees it.
    """
    closed = np.vstack([points, points[:1]])
    cum = arc_lengths(closed)
    n = max(16, round(cum[-1] / _DS_M))
    spline = CubicSpline(cum, closed, bc_type="periodic")
    s = (np.arange(n)[:, None] + np.array([-1.0, 0.0, 1.0]) / 3.0) * cum[-1] / n
    d1, d2 = spline(s % cum[-1], 1), spline(s % cum[-1], 2)
    cross = d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]
    kappa = np.abs(cross) / np.linalg.norm(d1, axis=-1) ** 3
    return spline(s[:, 1]), kappa.max(axis=1)


class _TourBuilder:
    """Turns a waypoint sequence into a smooth closed path (with loops where it turns back)."""

    def __init__(self, grid: WalkGrid, legs: WalkLegs, cells: np.ndarray, config: TrajectoryConfig):
        self.grid, self.legs, self.config = grid, legs, config
        self.points = grid.spec.centres_of(cells[:, ::-1])
        self.gradient = np.stack(np.gradient(grid.clearance)[::-1], axis=-1)  # [d/dx, d/dy]
        self.target_m = config.clearance_m + grid.spec.resolution_m
        self.kappa_max = 1.0 / turn_radius_m(config)

    def polyline(self, seq: list[int]) -> np.ndarray:
        """Closed raw path through ``seq`` (teardrops included), starting at the first stop."""
        radius = loop_radius_m(self.config)
        if len(seq) == 1:
            angles = np.linspace(0.0, 2.0 * np.pi, max(16, int(2 * np.pi * radius / _DS_M)))[:-1]
            return self.points[seq[0]] + radius * np.stack([np.sin(angles), -np.cos(angles)], -1)
        n = len(seq)
        paths = [self.legs.path(seq[i], seq[(i + 1) % n]) for i in range(n)]
        cums = [arc_lengths(p) for p in paths]
        cut_start, cut_end, loops = [0.0] * n, [0.0] * n, [None] * n
        for i in range(n):
            w = self.points[seq[i]]
            back_in = min(_TANGENT_BACK_M, 0.45 * cums[i - 1][-1])
            a = _point_at(paths[i - 1], cums[i - 1], cums[i - 1][-1] - back_in)
            b = _point_at(paths[i], cums[i], min(_TANGENT_BACK_M, 0.45 * cums[i][-1]))
            turn = wrap_angle(np.arctan2(*(b - w)[::-1]) - np.arctan2(*(w - a)[::-1]))
            if abs(turn) <= _LOOP_TURN_RAD:
                continue
            sign = 1.0 if turn >= 0 else -1.0
            # Entering is leaving backwards in time, around the circle the other way.
            reverse_in = paths[i - 1][::-1]
            cut_end[i - 1] = self._tangent_back(reverse_in, arc_lengths(reverse_in), radius, -sign)
            cut_start[i] = self._tangent_back(paths[i], cums[i], radius, sign)
            a = _point_at(paths[i - 1], cums[i - 1], cums[i - 1][-1] - cut_end[i - 1])
            b = _point_at(paths[i], cums[i], cut_start[i])
            loops[i] = (a, w, b, radius, sign)
        pieces, anchor = [], 0
        for i in range(n):
            if loops[i] is None:
                pieces.append(self.points[seq[i]][None])
            else:
                piece, mid = _teardrop(*loops[i])
                anchor = mid if i == 0 else anchor
                pieces.append(piece)
            inside = (cums[i] > cut_start[i]) & (cums[i] < cums[i][-1] - cut_end[i])
            pieces.append(paths[i][inside])
        poly = np.vstack(pieces)
        return _resample_closed(poly, arc_lengths(poly)[anchor])

    def _tangent_back(self, path: np.ndarray, cum: np.ndarray, radius: float, sign: float):
        """Arc length along ``path`` (leaving a loop's centre) where the loop should rejoin it.

        The straight tangent from the loop circle to that point must stay well clear of walls:
        the nearest to _TANGENT_BACK_M of the points whose tangent keeps 0.6 m, else the best.
        """
        backs = np.arange(0.5, 2.51, 0.1)
        backs = backs[backs <= 0.45 * cum[-1]]
        if len(backs) == 0:
            return 0.45 * cum[-1]
        w = path[0]
        pts = np.stack([np.interp(backs, cum, path[:, 0]), np.interp(backs, cum, path[:, 1])], -1)
        offset = pts - w
        dist = np.maximum(np.linalg.norm(offset, axis=1), 1.2 * radius)
        theta = np.arctan2(offset[:, 1], offset[:, 0]) - sign * np.arccos(radius / dist)
        tangent = w + radius * np.stack([np.cos(theta), np.sin(theta)], -1)
        frac = np.linspace(0.0, 1.0, 12)[None, :, None]
        segment = tangent[:, None, :] + frac * (pts - tangent)[:, None, :]
        worst = self.clearance_at(segment.reshape(-1, 2))[0].reshape(len(backs), -1).min(axis=1)
        worst[np.linalg.norm(offset, axis=1) < 1.2 * radius] = 0.0
        ok = worst >= 0.6
        if not ok.any():
            return float(backs[np.argmax(worst)])
        return float(backs[ok][np.argmin(np.abs(backs[ok] - _TANGENT_BACK_M))])

    def clearance_at(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N,) clearance, metres, and (N, 2) unit direction away from walls, at points' cells."""
        cells = self.grid.spec.cells_of(points)
        ix = np.clip(cells[:, 0], 0, self.grid.clearance.shape[1] - 1)
        iy = np.clip(cells[:, 1], 0, self.grid.clearance.shape[0] - 1)
        g = self.gradient[iy, ix]
        return self.grid.clearance[iy, ix], g / np.maximum(np.linalg.norm(g, axis=1), 1e-9)[:, None]

    def smooth(self, p: np.ndarray) -> tuple[np.ndarray, bool]:
        """Smooth until curvature <= 0.9 kappa_max, pushing points back out to target clearance.

        Returns the path and whether it got there.
        """
        p = gaussian_filter1d(p, 0.15 / _DS_M, axis=0, mode="wrap")
        for _ in range(150):
            p, kappa = _respace_smooth(p)
            bad = kappa > 0.9 * self.kappa_max
            clear, away = self.clearance_at(p)
            low = clear < self.target_m
            if not bad.any() and not low.any():
                return p, True
            if bad.any():
                w = np.clip(4.0 * gaussian_filter1d(bad.astype(float), 3.0, mode="wrap"), 0, 1)
                p = p + w[:, None] * (gaussian_filter1d(p, 2.0, axis=0, mode="wrap") - p)
            if low.any():
                push = np.zeros_like(p)
                push[low] = away[low] * (self.target_m + 0.03 - clear[low])[:, None]
                p = p + gaussian_filter1d(push, 1.5, axis=0, mode="wrap") * 2.0
        clear = bool((self.clearance_at(p)[0] >= self.config.clearance_m).all())
        logger.debug("smoothing stopped with curvature or clearance still off")
        return p, clear

    def walk(self, seq: list[int]) -> WalkLoop:
        path, clear = self.smooth(self.polyline(seq))
        return WalkLoop(path, self.config, clear)


def plan_walk(world: World, duration_s: float, seed: int, config: TrajectoryConfig) -> Trajectory:
    """A walk of ``duration_s`` seconds through ``world``, starting and ending at its start pose.

    Returns poses of base_link sampled at SAMPLE_RATE_HZ from stamp 0.0. Speeds stay within
    ``[min_speed_mps, max_speed_mps]``, yaw rates within ``max_turn_rate_radps``, and the path
    keeps ``clearance_m`` from occupied cells. The walk visits as many open spots (rooms) as fit
    at full speed, and repeats its tour when one lap is too short. Deterministic for a seed.
    """
    if not duration_s > 0:
        raise ConfigError(f"walk duration must be positive, got {duration_s}")
    rng = np.random.default_rng(seed)
    grid = WalkGrid(world, config)
    cells = grid.waypoints(start_clearance_m(config, world.spec.resolution_m))
    legs = grid.legs(cells)
    tours = growing_tours(legs.cost, rng)
    builder = _TourBuilder(grid, legs, cells, config)
    walks: dict[int, WalkLoop] = {}

    def walk(c: int) -> WalkLoop:
        if c not in walks:
            walks[c] = builder.walk(tour_stops(tours, c))
        return walks[c]

    def fits(c: int) -> bool:
        return walk(c).feasible and walk(c).duration_s(walk(c).v_max) <= duration_s

    # The most stops that can be walked at full speed within the duration (bisection).
    lo, hi = -1, len(tours)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    # Fill the duration by walking slower, or by walking the tour several times.
    for c in range(lo, -1, -1):
        lap = walk(c)
        fewest = int(np.ceil(duration_s / lap.duration_s(lap.v_min)))
        most = int(np.floor(duration_s / lap.duration_s(lap.v_max)))
        if lap.feasible and fewest <= most:  # take the number of laps nearest a natural pace
            natural = float(np.clip(_PREFERRED_SPEED * config.max_speed_mps, lap.v_min, lap.v_max))
            laps = int(np.clip(round(duration_s / lap.duration_s(natural)), fewest, most))
            logger.debug("walk: stops %s, %d x %.1f m", tour_stops(tours, c), laps, lap.length_m)
            return lap.sample(duration_s, lap.cruise_for(duration_s / laps), laps)
    logger.warning("a %.1f s walk is too short to return to the start", duration_s)
    return walk(0).sample(duration_s, walk(0).v_max)
