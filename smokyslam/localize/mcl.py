"""Monte Carlo localization in a saved map: predict with odometry, weigh by the likelihood
field, resample (low-variance), adapt the particle count (KLD), recover from kidnapping by
injecting particles when the likelihood collapses (augmented MCL; after a global start its
long average starts over once the cloud has settled; a search set off while tracking from a
given start ends once the cloud has settled again). A tracking start's particles are drawn
within ``init_sigma_cut`` sigmas of it. Particles placed for a global start, and injected
ones, are drawn where the current scan fits (mixture MCL's dual sampling, ``sampling.py``),
not uniformly. Scouts (``scouts.py``) search around the estimate
and take over when they explain the scans clearly better, for a cloud that went wrong so early
that augmented MCL, comparing it with its own past, cannot tell.

Everything is numpy over particles (and particles x points in the likelihood field); the only
loops are over filter steps.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import LocalizeConfig
from smokyslam.geometry import wrap_angle
from smokyslam.localize.hypotheses import resample_keeping
from smokyslam.localize.likelihood import LikelihoodField
from smokyslam.localize.particles import ParticleSet, near, smoothed, weighted_mean
from smokyslam.localize.sampling import around, where_the_scan_fits
from smokyslam.localize.scouts import Scouts

KLD_Z = 2.33
"""The upper normal quantile of KLD's bound (1 - delta = 0.99)."""
INJECT_FLOOR = 0.2
"""Injection rates below this are the averages' noise, not a collapsed likelihood (a scan's
fit swings by tens of percent from frame to frame; at 0.05 a walk into a poorly mapped room
drew particles to a wrong place that fitted better for a few scans)."""
INJECT_FLOOR_TRACKING = 0.35
"""The same while tracking from a given start, where a moderate fall of the fit is more
likely a stretch the map knows poorly than a lost filter. On the real Intel lab log (a map
of its first half, tracking its second) such a stretch lowers the fit by 25-30 % for about 30
scans, and at 0.2 the search it set off settled in wrong places for good
(``tests/test_localize_intel.py``). After a kidnapping the rate keeps rising (the L-corridor
test: past 0.2 after 11 scans, 0.35 after 21, 0.55 after 40), so injection starts later:
recovered for good after 23-30 scans over 8 seeds (13-33 at 0.2). A search (a global start)
keeps ``INJECT_FLOOR``: there a fall of the fit is how a wrong settlement shows."""
SETTLED_SHARE = 0.9
"""A cloud has settled once its main mode holds this share of the weight (a global start's,
and a search's set off while tracking)."""
RESUME_FRAMES = 5
"""Frames a search started from tracking must stay settled before tracking resumes."""
MODE_RADIUS_M, MODE_RADIUS_RAD = 1.0, np.radians(30.0)
"""How far from its seed (a KLD bin's mean) a particle still belongs to the main mode."""
MODE_CANDIDATES = 5
"""The heaviest KLD bins whose neighbourhoods compete to be the main mode. The heaviest bin
alone is where the particles are densest, not where most weight lies: in warehouse 20030 a
clump of injected particles 8 m away held it with 25 % of the weight while 33 % lay within
0.5 m of the truth, over more bins. On the real Intel lab log the estimate then jumped 5-6 m
for a scan or two (filter seeds 4-6 of 0-7)."""


class MonteCarloLocalizer:
    """Verbs: :meth:`start_tracking` or :meth:`start_global`, then per radar frame
    :meth:`predict` and :meth:`update`; :meth:`estimate` at any time."""

    def __init__(self, field: LikelihoodField, settings: LocalizeConfig) -> None:
        """``settings``: the particle bounds, KLD, augmented-MCL averages, the motion
        noise's scale and the per-point exponent (``LocalizeConfig``); seeded by its
        ``seed``."""
        self.field = field
        self.settings = settings
        self._rng = np.random.default_rng(settings.seed)
        self.set = ParticleSet()
        self._w_slow = self._w_fast = self._w_mode = 0.0
        self._place_on_first_scan = False
        self._tracking = False
        self._from_start = False  # started from a given pose: tracking resumes after a search
        self._settled_frames = 0
        self._settling = False
        self._mode_cache: tuple[int, tuple[np.ndarray, np.ndarray]] | None = None
        scout_rng = np.random.default_rng([settings.seed, 1])  # the filter's own draws unchanged
        self.scouts = Scouts(field, settings, scout_rng)

    @property
    def particles(self) -> np.ndarray:
        """(P, 3) the particles' poses in the map (x m, y m, yaw rad)."""
        return self.set.poses

    @property
    def weights(self) -> np.ndarray:
        """(P,) their normalised weights."""
        return self.set.weights

    # ------------------------------------------------------------------ start

    def start_tracking(self, pose: np.ndarray, sigmas: np.ndarray) -> None:
        """Particles around (3,) ``pose`` with (3,) ``sigmas`` (m, m, rad), within
        ``init_sigma_cut`` sigmas of it."""
        s = self.settings
        self.set.reset(around(pose, sigmas, s.init_sigma_cut, s.max_particles, self._rng))
        self._tracking = self._from_start = True

    def start_global(self) -> None:
        """Particles spread over the map's free cells, any heading; the first
        :meth:`update` draws them again where its scan fits (see :meth:`_likely_particles`)."""
        self.set.reset(self._random_particles(self.settings.max_particles))
        self._place_on_first_scan = True
        self._tracking = False
        self._settling = True

    def _random_particles(self, n: int) -> np.ndarray:
        free = self.field.free_xy
        picks = free[self._rng.integers(0, len(free), n)]
        jitter = self._rng.uniform(-0.5, 0.5, (n, 2)) * self.field.spec.resolution_m
        yaw = self._rng.uniform(-np.pi, np.pi, n)
        return np.column_stack([picks + jitter, yaw])

    def _likely_particles(self, n: int, points_xy: np.ndarray) -> np.ndarray:
        """(n, 3) poses drawn where the scan fits, from ``global_candidates`` x n uniform
        poses (mixture MCL's dual sampling)."""
        candidates = self._random_particles(n * self.settings.global_candidates)
        return where_the_scan_fits(
            candidates, self.field, points_xy, self.settings.points_weight, n, self._rng
        )

    # ------------------------------------------------------------------ per frame

    def predict(self, delta: np.ndarray, covariance: np.ndarray) -> None:
        """Move every particle by the odometry step (3,) with its (3, 3) covariance."""
        cov = np.asarray(covariance, dtype=float) * self.settings.motion_scale
        self.set.move(delta, cov, self._rng)
        self.scouts.predict(np.asarray(delta, float), cov)

    def update(self, points_xy: np.ndarray) -> None:
        """Weigh by the (N, 2) base-frame radar points, then resample."""
        if len(points_xy) == 0:
            return
        if self._place_on_first_scan:
            self._place_on_first_scan = False
            self.set.reset(self._likely_particles(len(self.set), points_xy))
        # Augmented MCL: short and long averages of how well the particles explain a point.
        p_unknown = self.p_unknown
        raw, mean_l = self.set.weigh(self.field, points_xy, self.settings.points_weight, p_unknown)
        s = self.settings
        self._w_slow = smoothed(self._w_slow, mean_l, s.alpha_slow)
        self._w_fast = smoothed(self._w_fast, mean_l, s.alpha_fast)
        inject = max(0.0, 1.0 - self._w_fast / self._w_slow) if self._w_slow else 0.0
        floor = INJECT_FLOOR_TRACKING if self._tracking else INJECT_FLOOR
        inject = inject if inject >= floor else 0.0
        # Scouts search near the main mode, and are weighed against it (not the whole cloud,
        # which may rightly hold other modes).
        mode, near = self._main_mode()
        per_point = np.exp(raw[near] / len(points_xy))
        mode_l = float(self.weights[near] @ per_point / self.weights[near].sum())
        self._w_mode = smoothed(self._w_mode, mode_l, s.alpha_fast)
        if self._settling and self.weights[near].sum() >= SETTLED_SHARE:
            self._restart_long_average()
        if self.scouts.update(points_xy, mode, self._w_mode, p_unknown):
            self.set.reset(self.scouts.take(len(self.set)))  # they found a better place
            self._w_mode = 0.0
            return
        self._resume_tracking(inject == 0.0 and self.weights[near].sum() >= SETTLED_SHARE)
        # Resample only when the weights have degenerated (or particles are to be injected):
        # resampling every frame lets chance alone pick between equally good hypotheses.
        if inject > 0.0:
            self._tracking = False  # the likelihood collapsed: search until settled again
        if inject > 0.0 or self.set.degenerate(s.resample_ess):
            self._resample(inject, points_xy)

    def _restart_long_average(self) -> None:
        """A global start's cloud has settled: augmented MCL's long average starts over
        from the short one. Until now it averaged a cloud spread over the whole map, which
        explains the points far worse than any settled cloud (0.34 against 0.65 per point on
        office 20001); anchored there, it would never notice the settled cloud fitting worse
        and worse in a wrong place (0.40 there, while the true pose fitted 0.80), and no
        particle would be injected."""
        self._settling = False
        self._w_slow = self._w_fast

    def _resume_tracking(self, settled: bool) -> None:
        """A search set off by a collapse of the fit, while tracking from a given start, ends
        once the cloud has settled again (its main mode holding ``SETTLED_SHARE`` of the
        weight, nothing injected) for ``RESUME_FRAMES`` frames in a row: the filter tracks
        again, with tracking's injection floor and unknown-space score. Kept searching, the
        next stretch the map knows poorly (a fit 20-25 % down for a second) injected particles
        that out-fitted the true place there: warehouse 20030's estimate jumped 8.6 m for
        three frames, 1.7 s after its search had settled."""
        if not self._from_start or self._tracking:
            return
        self._settled_frames = self._settled_frames + 1 if settled else 0
        if self._settled_frames >= RESUME_FRAMES:
            self._tracking, self._settled_frames = True, 0

    @property
    def p_unknown(self) -> float:
        """The least likelihood of a point in unknown space, now: ``p_unknown_tracking``
        while tracking from a given start, ``p_unknown`` while searching (a global start, or
        once the likelihood has collapsed). Near a trusted pose, a point in unknown space
        most likely hit something the map never saw (radar sees through walls into rooms the
        mapping walk did not enter), and scoring it low drags the cloud to wherever the map
        happens to be complete; a search must instead tell places apart, and a wrong place
        puts its points in unknown space outside the building."""
        s = self.settings
        return s.p_unknown_tracking if self._tracking else s.p_unknown

    def _resample(self, inject: float, points_xy: np.ndarray) -> None:
        """Low-variance resampling to the KLD count, with particles injected with
        probability max(0, 1 - w_fast / w_slow), drawn where the current scan fits.

        Injected particles start at ``inject_weight`` of a resampled one's weight. Drawn as
        the best fits of many random poses to one scan, they beat the cloud at once wherever
        the scan alone is ambiguous. Measured with equal weights: a global start that had
        found the pose turned on the spot, its fit fell 20 %, and the estimate jumped 8-12 m
        to such a place for 1-3 s. That happened in 4 of 10 office walks."""
        # While the likelihood has collapsed (any injection, INJECT_FLOOR and up), search with
        # every particle there may be.
        n = self.settings.max_particles if inject > 0.0 else self._kld_count()
        if self._tracking:  # (an injection ends it) keep places the first scans disfavour
            self.set.reset(*resample_keeping(self.particles, self.weights, n, self._rng))
            return
        particles = self.set.draw(n, self._rng)
        fresh = self._rng.uniform(size=n) < inject
        if fresh.any():
            particles[fresh] = self._likely_particles(int(fresh.sum()), points_xy)
        self.set.reset(particles, np.where(fresh, self.settings.inject_weight, 1.0))

    def _bins(self) -> np.ndarray:
        """(P, 3) int KLD histogram bins of the particles."""
        s = self.settings
        return np.column_stack(
            [
                np.floor(self.particles[:, :2] / s.kld_bin_m),
                np.floor(self.particles[:, 2] / np.radians(s.kld_bin_deg)),
            ]
        ).astype(np.int64)

    def _kld_count(self) -> int:
        """Particles for a KLD bound on the error of the binned posterior (Fox 2003)."""
        s = self.settings
        bins = self._bins()
        k = len(np.unique(bins[self.weights > 1e-9 / len(self.weights)], axis=0))
        if k <= 1:
            return s.min_particles
        a = 2.0 / (9.0 * (k - 1))
        n = (k - 1) / (2 * s.kld_epsilon) * (1.0 - a + np.sqrt(a) * KLD_Z) ** 3
        return int(np.clip(np.ceil(n), s.min_particles, s.max_particles))

    # ------------------------------------------------------------------ result

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """((3,) weighted mean pose of the main mode, (3, 3) covariance of the whole cloud).

        The main mode: the particles within ``MODE_RADIUS_M`` and ``MODE_RADIUS_RAD`` of a
        KLD bin's mean, of the ``MODE_CANDIDATES`` heaviest bins the one holding the most
        weight; the mean of a cloud split between places lies in neither.
        """
        mean = self.set.mean()
        mode, _ = self._main_mode()
        d = self.particles - mean
        d[:, 2] = wrap_angle(d[:, 2])
        return mode, (d * self.weights[:, None]).T @ d

    def _main_mode(self) -> tuple[np.ndarray, np.ndarray]:
        """((3,) weighted mean of the main mode, (P,) bool: the particles in it); found once
        per state of the particles (``update`` and ``estimate`` both ask)."""
        if self._mode_cache is None or self._mode_cache[0] != self.set.version:
            self._mode_cache = (self.set.version, self._find_main_mode())
        return self._mode_cache[1]

    def _find_main_mode(self) -> tuple[np.ndarray, np.ndarray]:
        """Of the ``MODE_CANDIDATES`` heaviest KLD bins, the one whose neighbourhood holds the
        most weight."""
        bins = self._bins()
        _, label = np.unique(bins, axis=0, return_inverse=True)
        label = label.reshape(-1)
        mass = np.bincount(label, weights=self.weights)
        bins_kept = (label == b for b in np.argsort(mass)[::-1][:MODE_CANDIDATES])
        seeds = [weighted_mean(self.particles[keep], self.weights[keep]) for keep in bins_kept]
        held = [self.weights[self._near(seed)].sum() for seed in seeds]
        seed = seeds[int(np.argmax(held))]
        mode = self._near(seed)
        if not mode.any():
            return seed, np.ones(len(self.particles), dtype=bool)
        return self.set.mean(mode), mode

    def _near(self, seed: np.ndarray) -> np.ndarray:
        return near(self.particles, seed, MODE_RADIUS_M, MODE_RADIUS_RAD)

    @property
    def count(self) -> int:
        return len(self.set)
