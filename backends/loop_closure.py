"""Loop closures: align the current radar submap to old keyframes near the current estimate.

Candidates are old keyframes (at least ``min_index_gap`` back) within ``search_radius_m`` of the
current estimate. The current submap is aligned to each by a Huber-weighted point-to-point ICP
started from the odometry guess; a match is kept only if enough points agree, the residual is
small and ICP did not move far from the guess. A near match (ICP moved the guess little) needs
fewer agreeing points than a far one. A far match must also be the best fit around it: in an
aisle or corridor of repeating structure ICP from a drifted guess stops at whichever copy it
reaches first, so ICP is restarted from a ring of shifts around the match, and the match is
dropped if an optimum elsewhere fits as well (:func:`best_rival`). Even so a wrong match can
slip through, so the caller adds the result with a robust kernel.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from smokyslam.backends.noise import floored_covariance, tangent_covariance
from smokyslam.geometry import se2_between, transform_points_2d, wrap_angle

if TYPE_CHECKING:
    from smokyslam.config import LoopClosureConfig

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class IcpResult:
    """delta: (3,) ``[x_m, y_m, yaw_rad]`` of the source frame in the target frame.
    covariance: (3, 3) of (tx, ty, yaw) perturbed additively, translation in the target frame.
    inlier_fraction: source points within the inlier distance of a target point.
    rms_m: RMS distance of those inliers."""

    delta: np.ndarray
    covariance: np.ndarray
    inlier_fraction: float
    rms_m: float


def _rigid_fit(source: np.ndarray, target: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted least-squares ``[x, y, yaw]`` mapping (N, 2) source onto (N, 2) target."""
    w = weights / weights.sum()
    mu_s, mu_t = w @ source, w @ target
    s, t = source - mu_s, target - mu_t
    cos_term = w @ (s[:, 0] * t[:, 0] + s[:, 1] * t[:, 1])
    sin_term = w @ (s[:, 0] * t[:, 1] - s[:, 1] * t[:, 0])
    yaw = np.arctan2(sin_term, cos_term)
    c, sn = np.cos(yaw), np.sin(yaw)
    translation = mu_t - np.array([[c, -sn], [sn, c]]) @ mu_s
    return np.array([translation[0], translation[1], yaw])


def icp_2d(
    source_xy: np.ndarray,
    target_tree: cKDTree,
    initial: np.ndarray,
    inlier_distance_m: float = 0.3,
    huber_m: float = 0.1,
    iterations: int = 40,
) -> IcpResult:
    """Align (N, 2) ``source_xy`` to the points in ``target_tree``, from ``initial`` (3,).

    Each iteration matches every source point to its nearest target point, keeps matches
    closer than a match distance, weights them with Huber (``huber_m``) and refits the rigid
    transform in closed form. The match distance shrinks from 3x ``inlier_distance_m`` to it
    over the first half of the iterations (point-to-point ICP crawls from a rough guess with a
    tight gate). Stops early when the update falls below 1e-5 m / rad.
    """
    target_xy = target_tree.data
    delta = np.asarray(initial, dtype=float).copy()
    coarse_to_fine = np.geomspace(3.0 * inlier_distance_m, inlier_distance_m, iterations // 2)
    schedule = np.r_[coarse_to_fine, np.full(iterations - coarse_to_fine.size, inlier_distance_m)]
    for match_distance_m in schedule:
        moved = transform_points_2d(delta, source_xy)
        distance, nearest = target_tree.query(moved, distance_upper_bound=match_distance_m)
        inlier = np.isfinite(distance)
        if inlier.sum() < 3:
            return IcpResult(delta, np.eye(3) * 1e6, 0.0, np.inf)
        weights = np.minimum(1.0, huber_m / np.maximum(distance[inlier], 1e-12))
        updated = _rigid_fit(source_xy[inlier], target_xy[nearest[inlier]], weights)
        step = np.abs(np.r_[updated[:2] - delta[:2], wrap_angle(updated[2] - delta[2])])
        delta = updated
        if step.max() < 1e-5:
            break
    moved = transform_points_2d(delta, source_xy)
    distance, nearest = target_tree.query(moved, distance_upper_bound=inlier_distance_m)
    inlier = np.isfinite(distance)
    if inlier.sum() < 3:
        return IcpResult(delta, np.eye(3) * 1e6, 0.0, np.inf)
    residual = moved[inlier] - target_xy[nearest[inlier]]
    # Residual Jacobian in (tx, ty, yaw): [I, perp(R p)] with perp(v) = (-v_y, v_x).
    rotated = moved[inlier] - delta[:2]
    J = np.zeros((inlier.sum(), 2, 3))
    J[:, 0, 0] = J[:, 1, 1] = 1.0
    J[:, 0, 2], J[:, 1, 2] = -rotated[:, 1], rotated[:, 0]
    hessian = np.einsum("nki,nkj->ij", J, J)
    sigma2 = float((residual**2).sum()) / max(2 * int(inlier.sum()) - 3, 1)
    covariance = sigma2 * np.linalg.inv(hessian)
    rms = float(np.sqrt((residual**2).sum(axis=1).mean()))
    return IcpResult(delta, covariance, float(inlier.mean()), rms)


RIVAL_DIRECTIONS = 8
"""Shifts per ring radius from which ICP is restarted around a far match."""


def fit_score(
    delta: np.ndarray, source_xy: np.ndarray, target_tree: cKDTree, sigma_m: float
) -> float:
    """Mean Gaussian likelihood of the (N, 2) source points moved by ``delta`` (3,) against
    their nearest target points, at point distance scale ``sigma_m``: 1 for a perfect fit.
    Sharper than the inlier fraction, whose 0.3 m gate counts a slid copy's points as well."""
    distance, _ = target_tree.query(transform_points_2d(delta, source_xy))
    return float(np.mean(np.exp(-0.5 * (distance / sigma_m) ** 2)))


def best_rival(
    source_xy: np.ndarray,
    target_tree: cKDTree,
    match: np.ndarray,
    radii_m: tuple[float, ...],
    inlier_distance_m: float,
    sigma_m: float,
) -> float:
    """The best :func:`fit_score` of an ICP optimum more than ``inlier_distance_m`` from
    ``match`` (3,), over ICP restarted from ``RIVAL_DIRECTIONS`` shifts of each radius around
    it (0 if every restart comes back)."""
    angles = np.arange(RIVAL_DIRECTIONS) * (2.0 * np.pi / RIVAL_DIRECTIONS)
    shifts = np.concatenate(
        [r * np.column_stack([np.cos(angles), np.sin(angles)]) for r in radii_m]
    )
    best = 0.0
    for shift in shifts:
        start = match + np.r_[shift, 0.0]
        rival = icp_2d(source_xy, target_tree, start, inlier_distance_m)
        if (
            np.isfinite(rival.rms_m)
            and np.hypot(*(rival.delta[:2] - match[:2])) > inlier_distance_m
        ):
            best = max(best, fit_score(rival.delta, source_xy, target_tree, sigma_m))
    return best


@dataclass(frozen=True)
class LoopClosure:
    """A verified relative pose between an old keyframe and the current one.

    delta: (3,) pose of keyframe ``new_index`` in the frame of ``old_index``.
    covariance: (3, 3) in gtsam's Pose2 tangent ``[x, y, theta]``, floored.
    """

    old_index: int
    new_index: int
    delta: np.ndarray
    covariance: np.ndarray
    inlier_fraction: float
    rms_m: float


class LoopCloser:
    """Keeps every keyframe's radar submap; ``check`` looks for a loop at each new keyframe."""

    def __init__(
        self,
        search_radius_m: float,
        min_index_gap: int,
        max_candidates: int,
        min_points: int,
        inlier_distance_m: float,
        min_inlier_fraction: float,
        max_rms_m: float,
        max_correction: tuple[float, float],
        min_spacing: int,
        floor_sigmas: tuple[float, float, float],
        near: tuple[float, float],
        rival_radii_m: tuple[float, ...],
        rival_sigma_m: float,
    ) -> None:
        """max_correction: largest (metres, radians) ICP may move away from the odometry guess.
        min_spacing: keyframes to wait after an accepted closure before looking again.
        floor_sigmas: smallest [x_m, y_m, theta_rad] sigmas a closure may claim (point-to-point
        ICP is overconfident on sparse radar points). near: (metres, inlier fraction) a match
        that shifts the guess at most that far needs only that inlier fraction. Where the
        estimate was already right, a partial overlap rarely aligns wrongly; a far correction on
        partial overlap is as often an aisle or corridor slid along as a real one.
        rival_radii_m, rival_sigma_m: the far match's rival search (:func:`best_rival`); empty
        radii: none."""
        self._search_radius_m = search_radius_m
        self._min_index_gap = min_index_gap
        self._max_candidates = max_candidates
        self._min_points = min_points
        self._inlier_distance_m = inlier_distance_m
        self._min_inlier_fraction = min_inlier_fraction
        self._max_rms_m = max_rms_m
        self._max_correction = max_correction
        self._min_spacing = min_spacing
        self._floor_sigmas = np.asarray(floor_sigmas, dtype=float)
        self._near_correction_m, self._near_min_inlier_fraction = near
        self._rival_radii_m = tuple(rival_radii_m)
        self._rival_sigma_m = rival_sigma_m
        self._trees: dict[int, cKDTree] = {}
        self._last_closure = -(10**9)

    def check(self, index: int, poses: np.ndarray, submap_xy: np.ndarray) -> LoopClosure | None:
        """Store keyframe ``index``'s submap and return a verified loop closure or None.

        poses: (>= index + 1, 3) current estimates ``[x_m, y_m, yaw_rad]`` of keyframes 0..index
        (map frame). submap_xy: (N, 2) radar points in keyframe ``index``'s base_link frame.
        """
        submap_xy = np.asarray(submap_xy, dtype=float).reshape(-1, 2)
        closure = None
        if len(submap_xy) >= self._min_points and index - self._last_closure >= self._min_spacing:
            closure = self._search(index, np.asarray(poses, dtype=float), submap_xy)
        if len(submap_xy) >= self._min_points:
            self._trees[index] = cKDTree(submap_xy)
        if closure is not None:
            self._last_closure = index
        return closure

    def _search(self, index: int, poses: np.ndarray, submap_xy: np.ndarray) -> LoopClosure | None:
        old = np.array([k for k in self._trees if k <= index - self._min_index_gap], dtype=int)
        if old.size == 0:
            return None
        distance = np.linalg.norm(poses[old, :2] - poses[index, :2], axis=1)
        near = old[distance < self._search_radius_m]
        near = near[np.argsort(distance[distance < self._search_radius_m])]
        best = None
        for old_index in near[: self._max_candidates]:
            guess = se2_between(poses[old_index], poses[index])
            result = icp_2d(submap_xy, self._trees[old_index], guess, self._inlier_distance_m)
            correction = se2_between(guess, result.delta)
            if self._verified(result, correction) and (
                best is None or result.rms_m < best[1].rms_m
            ):
                best = (int(old_index), result, correction)
        if best is None:
            return None
        old_index, result, correction = best
        if self._ambiguous(submap_xy, self._trees[old_index], result, correction):
            logger.debug("loop closure %d -> %d dropped: a rival fits as well", old_index, index)
            return None
        covariance = floored_covariance(
            tangent_covariance(result.delta, result.covariance), self._floor_sigmas
        )
        logger.debug("loop closure %d -> %d, rms %.3f m", old_index, index, result.rms_m)
        return LoopClosure(
            old_index, index, result.delta, covariance, result.inlier_fraction, result.rms_m
        )

    def _ambiguous(
        self, submap_xy: np.ndarray, tree: cKDTree, result: IcpResult, correction: np.ndarray
    ) -> bool:
        """Whether a far match (``correction``: its move from the odometry guess) has a rival
        optimum around it that fits at least as well."""
        if not self._rival_radii_m or _shift_m(correction) <= self._near_correction_m:
            return False
        own = fit_score(result.delta, submap_xy, tree, self._rival_sigma_m)
        rival = best_rival(
            submap_xy,
            tree,
            result.delta,
            self._rival_radii_m,
            self._inlier_distance_m,
            self._rival_sigma_m,
        )
        return rival >= own

    def _verified(self, result: IcpResult, correction: np.ndarray) -> bool:
        shift_m = _shift_m(correction)
        min_inliers = (
            self._near_min_inlier_fraction
            if shift_m <= self._near_correction_m
            else self._min_inlier_fraction
        )
        return bool(
            result.inlier_fraction >= min_inliers
            and result.rms_m <= self._max_rms_m
            and shift_m <= self._max_correction[0]
            and abs(correction[2]) <= self._max_correction[1]
        )


def _shift_m(correction: np.ndarray) -> float:
    """How far (m) ICP moved the keyframe from the odometry guess (``correction``: the match
    in the guess's frame)."""
    return float(np.hypot(correction[0], correction[1]))


def get_loop_closer(config: LoopClosureConfig) -> LoopCloser:
    """A LoopCloser with the search and verification settings of ``config``."""
    return LoopCloser(
        search_radius_m=config.search_radius_m,
        min_index_gap=config.min_index_gap,
        max_candidates=config.max_candidates,
        min_points=config.min_points,
        inlier_distance_m=config.inlier_distance_m,
        min_inlier_fraction=config.min_inlier_fraction,
        max_rms_m=config.max_rms_m,
        max_correction=(config.max_correction_m, config.max_correction_rad),
        min_spacing=config.min_spacing,
        floor_sigmas=config.floor_sigmas,
        near=(config.near_correction_m, config.near_min_inlier_fraction),
        rival_radii_m=config.rival_radii_m,
        rival_sigma_m=config.rival_sigma_m,
    )
