"""The two ways the localizer draws poses: low-variance resampling of weights, and dual
sampling (mixture MCL): candidate poses kept in proportion to how well they explain a scan."""

from __future__ import annotations

import numpy as np

from smokyslam.localize.likelihood import LikelihoodField


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
