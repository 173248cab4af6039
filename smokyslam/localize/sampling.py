"""The ways the localizer draws poses: around a given start (a truncated Gaussian),
low-variance resampling of weights, and dual sampling (mixture MCL): candidate poses kept in
proportion to how well they explain a scan."""

from __future__ import annotations

import numpy as np

from smokyslam.localize.likelihood import LikelihoodField

MAX_REDRAWS = 100
"""Rounds of redrawing the poses beyond the cut (each round keeps 1 - P(beyond) of them)."""


def around(
    pose: np.ndarray, sigmas: np.ndarray, cut: float, n: int, rng: np.random.Generator
) -> np.ndarray:
    """(n, 3) poses drawn from a Gaussian around (3,) ``pose`` with (3,) independent
    ``sigmas``, truncated at ``cut`` sigmas: the position radially (the normalised offset's
    length), the heading on its own. Draws beyond the cut are drawn again."""
    z = rng.normal(0.0, 1.0, (n, 3))
    for _ in range(MAX_REDRAWS):
        beyond = (np.hypot(z[:, 0], z[:, 1]) > cut) | (np.abs(z[:, 2]) > cut)
        if not beyond.any():
            break
        z[beyond] = rng.normal(0.0, 1.0, (int(beyond.sum()), 3))
    else:
        z = np.clip(z, -cut, cut)  # a cut so tight that redrawing cannot meet it
        z[:, :2] *= np.minimum(1.0, cut / np.maximum(np.hypot(z[:, 0], z[:, 1]), 1e-12))[:, None]
    return np.asarray(pose, dtype=float) + z * np.asarray(sigmas, dtype=float)


def low_variance(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n,) indices drawn by low-variance (systematic) resampling of normalised ``weights``."""
    steps = (rng.uniform(0.0, 1.0 / n) + np.arange(n) / n).clip(max=1.0 - 1e-12)
    return np.minimum(np.searchsorted(np.cumsum(weights), steps), len(weights) - 1)


def where_the_scan_fits(
    candidates: np.ndarray,
    field: LikelihoodField,
    points_xy: np.ndarray,
    points_weight: float,
    n: int,
    rng: np.random.Generator,
    p_unknown: float | None = None,
) -> np.ndarray:
    """(n, 3) of the (M, 3) ``candidates``, drawn in proportion to the (tempered) likelihood
    of ``points_xy``: a wrong place has little chance of being drawn, while the right one,
    which uniform sampling hits only once in many thousand draws, is drawn often."""
    log_l = field.log_likelihood(candidates, points_xy, p_unknown) * points_weight
    weights = np.exp(log_l - log_l.max())
    return candidates[low_variance(weights / weights.sum(), n, rng)]
