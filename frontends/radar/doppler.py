"""Doppler ego-velocity: the radar's own planar velocity from one frame's radial speeds.

A static point at bearing ``u = (cos a, sin a)`` seen from a sensor moving with velocity ``v``
(radar frame, m/s) has the radial speed ``doppler = -u . v`` (positive moving away). Moving
objects and ghosts break that relation; RANSAC over point pairs finds the static majority, then
least squares on the inliers gives the velocity and its covariance.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import numpy as np

logger = logging.getLogger(__name__)


@dataclass
class EgoVelocity:
    """Planar radar velocity from one frame.

    velocity_mps: (2,) [vx, vy], m/s, radar frame.
    covariance: (2, 2) m^2/s^2, from the inlier residuals (floored by ``min_sigma_mps``).
    inliers: number of points consistent with a static world.
    inlier_mask: (N,) bool over the input points.
    valid: False when too few points or no consistent pair was found (velocity is then zero
    and the covariance large).
    """

    velocity_mps: np.ndarray
    covariance: np.ndarray
    inliers: int
    inlier_mask: np.ndarray
    valid: bool = True


ENUMERATED_PAIRS = 20_000
"""Up to this many point pairs, every pair is listed and the hypotheses drawn among them;
beyond it pairs are drawn directly (memory stays linear in the points)."""


@functools.lru_cache(maxsize=256)
def _pair_indices(n: int, max_hypotheses: int, seed: int) -> np.ndarray:
    """(H, 2) point pairs: all of them when few enough, else a random subset drawn with
    ``seed``. The same for every frame of ``n`` points, so kept (read-only) once drawn."""
    pairs = _draw_pairs(n, max_hypotheses, np.random.default_rng(seed))
    pairs.flags.writeable = False
    return pairs


def _draw_pairs(n: int, max_hypotheses: int, rng: np.random.Generator) -> np.ndarray:
    if n * (n - 1) // 2 > ENUMERATED_PAIRS:
        drawn = np.sort(rng.integers(0, n, size=(2 * max_hypotheses, 2)), axis=1)
        drawn = drawn[drawn[:, 0] != drawn[:, 1]]
        _, first = np.unique(drawn, axis=0, return_index=True)  # distinct, in drawn order
        return drawn[np.sort(first)][:max_hypotheses]
    i, j = np.triu_indices(n, k=1)
    pairs = np.stack([i, j], axis=1)
    if len(pairs) > max_hypotheses:
        pairs = pairs[rng.choice(len(pairs), size=max_hypotheses, replace=False)]
    return pairs


def _least_squares(
    directions: np.ndarray, doppler_mps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, residuals and normal matrix of ``-directions @ v = doppler``."""
    A = -directions
    normal = A.T @ A
    velocity = np.linalg.solve(normal, A.T @ doppler_mps)
    return velocity, doppler_mps - A @ velocity, normal


def estimate_ego_velocity(
    bearings_rad: np.ndarray,
    doppler_mps: np.ndarray,
    inlier_threshold_mps: float = 0.1,
    max_hypotheses: int = 600,
    min_inliers: int = 4,
    min_sigma_mps: float = 0.02,
    seed: int = 0,
) -> EgoVelocity:
    """Estimate the sensor's planar velocity from (N,) bearings (rad, radar frame) and (N,)
    Doppler speeds (m/s, positive away), assuming most points are static.

    Points whose Doppler is unknown (NaN) take no part. Every 2-point hypothesis (or
    ``max_hypotheses`` random ones) is solved and scored at once;
    the best one's inliers (|residual| < ``inlier_threshold_mps``) are refit by least squares
    twice. The covariance is ``sigma^2 (A^T A)^-1`` with sigma from the inlier residuals,
    at least ``min_sigma_mps``.
    """
    bearings = np.asarray(bearings_rad, dtype=float).ravel()
    doppler = np.asarray(doppler_mps, dtype=float).ravel()
    known = np.isfinite(doppler) & np.isfinite(bearings)
    if not known.all():  # unknown Doppler (NaN): estimate on the others, mask over all
        estimate = estimate_ego_velocity(
            bearings[known],
            doppler[known],
            inlier_threshold_mps,
            max_hypotheses,
            min_inliers,
            min_sigma_mps,
            seed,
        )
        mask = np.zeros(bearings.size, dtype=bool)
        mask[known] = estimate.inlier_mask
        estimate.inlier_mask = mask
        return estimate
    n = bearings.size
    directions = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)
    if n < max(min_inliers, 2):
        return _invalid(n)

    pairs = _pair_indices(n, max_hypotheses, seed)
    ua, ub = directions[pairs[:, 0]], directions[pairs[:, 1]]
    det = ua[:, 0] * ub[:, 1] - ua[:, 1] * ub[:, 0]
    well_posed = np.abs(det) > np.sin(np.radians(5.0))
    if not well_posed.any():
        return _invalid(n)
    ua, ub, det = ua[well_posed], ub[well_posed], det[well_posed]
    # Solve [ua; ub] v = -[da; db] for every pair by Cramer's rule.
    da, db = -doppler[pairs[well_posed, 0]], -doppler[pairs[well_posed, 1]]
    vx = (da * ub[:, 1] - ua[:, 1] * db) / det
    vy = (ua[:, 0] * db - da * ub[:, 0]) / det
    hypotheses = np.stack([vx, vy], axis=1)  # (H, 2)
    residuals = doppler[None, :] + hypotheses @ directions.T  # (H, N)
    scores = (np.abs(residuals) < inlier_threshold_mps).sum(axis=1)
    inlier_mask = np.abs(residuals[np.argmax(scores)]) < inlier_threshold_mps

    for _ in range(2):
        if inlier_mask.sum() < min_inliers:
            return _invalid(n)
        velocity, _, normal = _least_squares(directions[inlier_mask], doppler[inlier_mask])
        inlier_mask = np.abs(doppler + directions @ velocity) < inlier_threshold_mps
    if inlier_mask.sum() < min_inliers:
        return _invalid(n)
    velocity, residual, normal = _least_squares(directions[inlier_mask], doppler[inlier_mask])
    dof = max(int(inlier_mask.sum()) - 2, 1)
    sigma2 = max(float(residual @ residual) / dof, min_sigma_mps**2)
    covariance = sigma2 * np.linalg.inv(normal)
    return EgoVelocity(velocity, covariance, int(inlier_mask.sum()), inlier_mask)


def _invalid(n: int) -> EgoVelocity:
    logger.debug("ego-velocity: no consistent static set among %d points", n)
    return EgoVelocity(np.zeros(2), np.eye(2) * 1e2, 0, np.zeros(n, dtype=bool), valid=False)
