"""Resampling that keeps the filter's hypotheses while it tracks from a given start.

Low-variance resampling draws particles in proportion to their weights. A place the first
scans disfavour (by a factor of e^10 to e^30 over a few seconds, when a stretch of wall in
front of the true start is missing from the map) then loses every particle, and no later
scan can bring it back: the filter has forgotten it. The true place often wins later, once
the walk sees what tells the two apart.

So while tracking, the particles are split into hypotheses (the heaviest particle and every
particle within :data:`RADIUS_M` and :data:`RADIUS_RAD` of it, then the heaviest of the rest,
..., at most :data:`MAX_HYPOTHESES`; the particles left then form one last group), and each
is resampled on its own: to its share of the particles, but to at least
:data:`KEEP_PARTICLES` each weighted down so that the hypothesis keeps its total weight. The
cloud's posterior is unchanged (an importance sample of the same mass per hypothesis); a
hypothesis is dropped only once its weight falls below :data:`KEEP_SHARE` of the whole.

The radius is half the estimate's main-mode radius: places 1 m apart must stay apart for a
0.15 m target. With 1 m, warehouse 20025's true place and one 1 m further along a rack aisle
were one hypothesis, resampled by weight, and the true place lost its particles while the
first scans favoured the other; the filter then tracked 1 m off for 16 s although the true
place fitted better from 6 s on. With 0.3 m the eight hypotheses covered too little of a
start's 1 m cloud.
"""

from __future__ import annotations

import numpy as np

from smokyslam.localize.particles import near
from smokyslam.localize.sampling import low_variance

MAX_HYPOTHESES = 8
RADIUS_M = 0.5
RADIUS_RAD = float(np.radians(30.0))
KEEP_PARTICLES = 20
KEEP_SHARE = float(np.exp(-40.0))


def split(
    poses: np.ndarray,
    weights: np.ndarray,
    radius_m: float = RADIUS_M,
    radius_rad: float = RADIUS_RAD,
) -> list[np.ndarray]:
    """Index arrays of the groups of (P, 3) ``poses``: at most :data:`MAX_HYPOTHESES`
    hypotheses, heaviest seed first, then the particles left, if any."""
    remaining = np.ones(len(poses), dtype=bool)
    groups: list[np.ndarray] = []
    while remaining.any() and len(groups) < MAX_HYPOTHESES:
        index = np.flatnonzero(remaining)
        seed = poses[index[np.argmax(weights[index])]]
        group = index[near(poses[index], seed, radius_m, radius_rad)]
        groups.append(group)
        remaining[group] = False
    if remaining.any():
        groups.append(np.flatnonzero(remaining))
    return groups


def resample_keeping(
    poses: np.ndarray, weights: np.ndarray, n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """((M, 3) poses, (M,) weights): about ``n`` particles drawn by low-variance resampling
    within each group of :func:`split`, each keeping its total weight and at least
    :data:`KEEP_PARTICLES` particles (so M may exceed ``n`` by that many per group beyond
    the first)."""
    groups = split(poses, weights)
    mass = np.array([weights[g].sum() for g in groups])
    total = float(mass.sum())
    drawn, drawn_weights = [], []
    for group, group_mass in zip(groups, mass, strict=True):
        if group_mass < KEEP_SHARE * total:
            continue
        m = max(KEEP_PARTICLES, int(np.rint(n * group_mass / total)))
        picks = group[low_variance(weights[group] / group_mass, m, rng)]
        drawn.append(poses[picks])
        drawn_weights.append(np.full(m, group_mass / m))
    return np.vstack(drawn), np.concatenate(drawn_weights)
