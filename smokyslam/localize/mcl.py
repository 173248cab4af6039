"""Monte Carlo localization in a saved map: predict with odometry, weigh by the likelihood
field, resample (low-variance), adapt the particle count (KLD), recover from kidnapping by
injecting random particles when the likelihood collapses (augmented MCL).

Everything is numpy over particles (and particles x points in the likelihood field); the only
loops are over filter steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.geometry import se2_compose, wrap_angle
from smokyslam.localize.likelihood import LikelihoodField


@dataclass(frozen=True)
class MclSettings:
    """min/max_particles: KLD bounds. kld_epsilon, kld_z: KLD error and its normal quantile.
    bin_m, bin_rad: the histogram KLD counts occupied bins on. alpha_slow, alpha_fast: the
    averages of the likelihood that decide random injection. motion_scale: variance
    multiplier on the odometry covariance. points_weight: the exponent on each point's
    likelihood (a scan's points are not independent: < 1 keeps one scan from collapsing the
    filter onto one particle)."""

    min_particles: int = 200
    max_particles: int = 2000
    kld_epsilon: float = 0.05
    kld_z: float = 2.33
    bin_m: float = 0.25
    bin_rad: float = np.radians(10.0)
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    motion_scale: float = 4.0
    points_weight: float = 0.3


class MonteCarloLocalizer:
    """Verbs: :meth:`start_tracking` or :meth:`start_global`, then per radar frame
    :meth:`predict` and :meth:`update`; :meth:`estimate` at any time."""

    def __init__(self, field: LikelihoodField, settings: MclSettings, seed: int = 0) -> None:
        self.field = field
        self.settings = settings
        self._rng = np.random.default_rng(seed)
        self.particles = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self._w_slow = self._w_fast = 0.0

    # ------------------------------------------------------------------ start

    def start_tracking(self, pose: np.ndarray, sigmas: np.ndarray) -> None:
        """Particles around (3,) ``pose`` with (3,) ``sigmas`` (m, m, rad)."""
        n = self.settings.max_particles
        noise = self._rng.normal(0.0, 1.0, (n, 3)) * np.asarray(sigmas, dtype=float)
        self._set(np.asarray(pose, dtype=float) + noise)

    def start_global(self) -> None:
        """Particles spread over the map's free cells, any heading."""
        self._set(self._random_particles(self.settings.max_particles))

    def _random_particles(self, n: int) -> np.ndarray:
        free = self.field.free_xy
        picks = free[self._rng.integers(0, len(free), n)]
        jitter = self._rng.uniform(-0.5, 0.5, (n, 2)) * self.field.spec.resolution_m
        yaw = self._rng.uniform(-np.pi, np.pi, n)
        return np.column_stack([picks + jitter, yaw])

    def _set(self, particles: np.ndarray) -> None:
        self.particles = particles
        self.particles[:, 2] = wrap_angle(self.particles[:, 2])
        self.weights = np.full(len(particles), 1.0 / len(particles))

    # ------------------------------------------------------------------ per frame

    def predict(self, delta: np.ndarray, covariance: np.ndarray) -> None:
        """Move every particle by the odometry step (3,) with its (3, 3) covariance."""
        cov = np.asarray(covariance, dtype=float) * self.settings.motion_scale
        noise = self._rng.multivariate_normal(np.zeros(3), cov, len(self.particles))
        self.particles = se2_compose(self.particles, np.asarray(delta, float) + noise)
        self.particles[:, 2] = wrap_angle(self.particles[:, 2])

    def update(self, points_xy: np.ndarray) -> None:
        """Weigh by the (N, 2) base-frame radar points, then resample."""
        if len(points_xy) == 0:
            return
        log_l = self.field.log_likelihood(self.particles, points_xy)
        log_l *= self.settings.points_weight
        peak = log_l.max()
        likelihood = np.exp(log_l - peak)
        weights = self.weights * likelihood
        total = weights.sum()
        if not np.isfinite(total) or total <= 0:
            weights, total = np.ones(len(weights)), float(len(weights))
        self.weights = weights / total
        # Augmented MCL: short and long averages of the mean likelihood per point.
        # Per point, so that the averages do not depend on how many points a scan has.
        mean_l = float(np.exp((peak + np.log(np.mean(likelihood))) / len(points_xy)))
        s = self.settings
        self._w_slow += s.alpha_slow * (mean_l - self._w_slow) if self._w_slow else mean_l
        self._w_fast += s.alpha_fast * (mean_l - self._w_fast) if self._w_fast else mean_l
        self._resample(max(0.0, 1.0 - self._w_fast / self._w_slow) if self._w_slow else 0.0)

    def _resample(self, inject: float) -> None:
        """Low-variance resampling to the KLD count, with random particles injected with
        probability max(0, 1 - w_fast / w_slow)."""
        # While the likelihood has collapsed, search with every particle there may be.
        n = self.settings.max_particles if inject > 0.1 else self._kld_count()
        steps = (self._rng.uniform(0.0, 1.0 / n) + np.arange(n) / n).clip(max=1.0 - 1e-12)
        index = np.searchsorted(np.cumsum(self.weights), steps)
        particles = self.particles[np.minimum(index, len(self.particles) - 1)]
        fresh = self._rng.uniform(size=n) < inject
        if fresh.any():
            particles[fresh] = self._random_particles(int(fresh.sum()))
        self._set(particles.copy())

    def _kld_count(self) -> int:
        """Particles for a KLD bound on the error of the binned posterior (Fox 2003)."""
        s = self.settings
        bins = np.column_stack(
            [
                np.floor(self.particles[:, :2] / s.bin_m),
                np.floor(self.particles[:, 2] / s.bin_rad),
            ]
        ).astype(np.int64)
        k = len(np.unique(bins[self.weights > 1e-9 / len(self.weights)], axis=0))
        if k <= 1:
            return s.min_particles
        a = 2.0 / (9.0 * (k - 1))
        n = (k - 1) / (2 * s.kld_epsilon) * (1.0 - a + np.sqrt(a) * s.kld_z) ** 3
        return int(np.clip(np.ceil(n), s.min_particles, s.max_particles))

    # ------------------------------------------------------------------ result

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """((3,) weighted mean pose (circular mean of the yaw), (3, 3) covariance)."""
        w = self.weights
        xy = w @ self.particles[:, :2]
        yaw = np.arctan2(w @ np.sin(self.particles[:, 2]), w @ np.cos(self.particles[:, 2]))
        mean = np.array([xy[0], xy[1], yaw])
        d = self.particles - mean
        d[:, 2] = wrap_angle(d[:, 2])
        return mean, (d * w[:, None]).T @ d

    @property
    def count(self) -> int:
        return len(self.particles)
