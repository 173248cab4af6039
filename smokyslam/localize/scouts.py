"""Scouts: a small second particle set that searches around the localizer's estimate.

Augmented MCL notices a lost filter by comparing how well its particles explain the scans
now with how well they did before. A cloud that settled in the wrong place within its first
scans (a start a metre off, beside a stretch of corridor that fits as well for a moment) was
never better, so nothing is noticed, and no particle is left where the true pose is.

Scouts are drawn where the current scan fits within ``SEARCH_RADIUS_M`` and
``SEARCH_RADIUS_RAD`` of the estimate, move with the same odometry and are weighed by the
same likelihood, but never count for the estimate. When they explain the points
``BETTER_BY`` times better than the particles do (short averages of the per-point
likelihood) for ``PERSIST_FRAMES`` frames in a row, the localizer takes them as its
particles. In the right place the best fit near the estimate is the estimate itself, so
scouts do no better than the particles.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import LocalizeConfig
from smokyslam.localize.likelihood import LikelihoodField
from smokyslam.localize.particles import ParticleSet, smoothed
from smokyslam.localize.sampling import where_the_scan_fits

COUNT = 200
"""Scouts (a converged tracking cloud's size: KLD's usual lower bound)."""
SEARCH_RADIUS_M = 4.0
SEARCH_RADIUS_RAD = np.radians(30.0)
CANDIDATES_PER_SCOUT = 20
REFRESH = 0.3
"""Share of the scouts drawn anew, where the scan fits, each time they are resampled."""
BETTER_BY = 1.5
PERSIST_FRAMES = 10


class Scouts:
    """Verbs: :meth:`predict` with each odometry step, :meth:`update` with each scan."""

    def __init__(
        self,
        field: LikelihoodField,
        settings: LocalizeConfig,
        rng: np.random.Generator,
    ) -> None:
        """``settings``: the localizer's per-point exponent, short-average rate and
        resampling threshold, which the scouts share."""
        self.field = field
        self.settings = settings
        self._rng = rng
        self.set = ParticleSet()
        self._w_fast = 0.0
        self._better_frames = 0

    def predict(self, delta: np.ndarray, covariance: np.ndarray) -> None:
        """Move by the odometry step ``delta`` with its (3, 3) ``covariance`` (as scaled for
        the particles)."""
        self.set.move(delta, covariance, self._rng)

    def update(
        self, points_xy: np.ndarray, estimate: np.ndarray, w_particles: float, p_unknown: float
    ) -> bool:
        """Weigh by ``points_xy`` (unknown space scored as the filter now scores it,
        ``p_unknown``); True when the scouts have explained the points better than the
        particles (``w_particles``, their short average) for long enough."""
        s = self.settings
        if not len(self.set):
            self.set.reset(self._draw(COUNT, points_xy, estimate, p_unknown))
        _, mean_l = self.set.weigh(self.field, points_xy, s.points_weight, p_unknown)
        self._w_fast = smoothed(self._w_fast, mean_l, s.alpha_fast)
        if self.set.degenerate(s.resample_ess):
            self._resample(points_xy, estimate, p_unknown)
        better = w_particles > 0 and self._w_fast > BETTER_BY * w_particles
        self._better_frames = self._better_frames + 1 if better else 0
        return self._better_frames >= PERSIST_FRAMES

    def take(self, n: int) -> np.ndarray:
        """(n, 3) particles drawn from the scouts by weight; the scouts start over."""
        taken = self.set.draw(n, self._rng).copy()
        self.set = ParticleSet()
        self._w_fast, self._better_frames = 0.0, 0
        return taken

    def _resample(self, points_xy: np.ndarray, estimate: np.ndarray, p_unknown: float) -> None:
        n = len(self.set)
        kept = self.set.draw(n, self._rng)
        fresh = self._rng.uniform(size=n) < REFRESH
        if fresh.any():
            kept[fresh] = self._draw(int(fresh.sum()), points_xy, estimate, p_unknown)
        self.set.reset(kept)

    def _draw(
        self, n: int, points_xy: np.ndarray, estimate: np.ndarray, p_unknown: float
    ) -> np.ndarray:
        """(n, 3) poses near ``estimate`` drawn where the scan fits."""
        m = n * CANDIDATES_PER_SCOUT
        radius = SEARCH_RADIUS_M * np.sqrt(self._rng.uniform(size=m))
        bearing = self._rng.uniform(-np.pi, np.pi, m)
        candidates = np.column_stack(
            [
                estimate[0] + radius * np.cos(bearing),
                estimate[1] + radius * np.sin(bearing),
                estimate[2] + self._rng.uniform(-SEARCH_RADIUS_RAD, SEARCH_RADIUS_RAD, m),
            ]
        )
        return where_the_scan_fits(
            candidates,
            self.field,
            points_xy,
            self.settings.points_weight,
            n,
            self._rng,
            p_unknown,
        )
