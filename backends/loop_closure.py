"""Loop closures: align the current radar submap to old keyframes near the current estimate.

Candidates are old keyframes (at least ``min_index_gap`` back) within ``search_radius_m`` of the
current estimate. The current submap is aligned to each by a Huber-weighted point-to-point ICP
started from the odometry guess, in which points only correspond when they were seen from the
same side of a surface (:mod:`smokyslam.backends.scan_match`); a match is kept only if enough
points agree, the residual is small and ICP did not move far from the guess. A near match (ICP
moved the guess little) needs fewer agreeing points than a far one. Two passes of one aisle in
opposite directions see its two ends, so their 6 s submaps share too few points to verify;
where the old submap alone does not verify, the current one is matched again to it joined with
its stored neighbours on each side, placed by the current estimates (locally consistent:
drift over a few seconds is small). A far match must also be
the best fit around it: in an aisle or corridor of repeating structure ICP from a drifted guess
stops at whichever copy it reaches first, so ICP is restarted from a ring of shifts around the
match, and the match is dropped if an optimum elsewhere fits as well (:func:`best_rival`). Even
so a wrong match can slip through, so the caller adds the result with a robust kernel.
"""

from __future__ import annotations

import logging
from collections import Counter, OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.backends.noise import floored_covariance, tangent_covariance
from smokyslam.backends.scan_match import (
    IcpResult,
    Scan,
    best_rival,
    fit_score,
    icp_2d,
    match_covariance,
)
from smokyslam.geometry import first_per_voxel, se2_between, transform_points_2d, wrap_angle

if TYPE_CHECKING:
    from smokyslam.config import LoopClosureConfig

logger = logging.getLogger(__name__)

JOINED_REUSE_TOLERANCE = np.array([0.01, 0.01, 0.002])
"""A joined target (metres, metres, radians) is built again only once one of its submaps'
placements has moved more than this since it was built; its normals cost more than the ICP."""

OUTCOMES = (
    "searches",
    "candidates",
    "overcorrected",
    "few_inliers",
    "high_rms",
    "rival",
    "accepted",
)
"""Keys of :attr:`LoopCloser.outcomes`: keyframes searched (checked, past the spacing after a
closure, with an old keyframe far enough back); candidate matches tried (old keyframes within
the search radius, at most ``max_candidates`` a search); candidates refused because ICP moved
the guess too far, too few points agreed, or the residual was too large; searches whose best
match was dropped for a rival optimum; and closures accepted."""

JOINED_CACHE_SIZE = 32
"""Joined targets kept (the most recently used): the same few old keyframes are candidates for
several new keyframes in a row, so a small cache serves them and memory stays bounded."""


@dataclass(frozen=True)
class LoopClosure:
    """A verified relative pose between an old keyframe and the current one.

    delta: (3,) pose of keyframe ``new_index`` in the frame of ``old_index``.
    covariance: (3, 3) in gtsam's Pose2 tangent ``[x, y, theta]``: the match's
    (:func:`match_covariance`), floored.
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
        near: tuple[float, float, float],
        rival_radii_m: tuple[float, ...],
        rival_sigma_m: float,
        normal_radius_m: float | None,
        match_sigmas_m: tuple[float, float],
        target_neighbours: int,
        voxel_m: float,
    ) -> None:
        """max_correction: largest (metres, radians) ICP may move away from the odometry guess.
        min_spacing: keyframes to wait after an accepted closure before looking again.
        floor_sigmas: smallest [x_m, y_m, theta_rad] sigmas a closure may claim. match_sigmas_m:
        (along a target normal, without one) sigma of one matched point in the closure's
        covariance (:func:`match_covariance`). near: (metres, inlier fraction, RMS metres) a
        match that shifts the guess at most that far needs only that inlier fraction and may
        have that RMS. Where the estimate was already right, a partial overlap or noisy
        long-range points rarely align wrongly; a far correction on such evidence is as often an
        aisle or corridor slid along as a real one.
        rival_radii_m, rival_sigma_m: the far match's rival search (:func:`best_rival`); empty
        radii: none. normal_radius_m: neighbourhood of a submap point's oriented normal
        (:mod:`smokyslam.backends.scan_match`); None: no normals, any points may match."""
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
        self._near_correction_m, self._near_min_inlier_fraction, self._near_max_rms_m = near
        self._rival_radii_m = tuple(rival_radii_m)
        self._rival_sigma_m = rival_sigma_m
        self._normal_radius_m = normal_radius_m
        self._match_sigmas_m = match_sigmas_m
        self._target_neighbours = target_neighbours
        self._voxel_m = voxel_m
        self._submaps: dict[int, Scan] = {}
        self._joined_cache: OrderedDict[int, tuple[np.ndarray, np.ndarray, Scan]] = OrderedDict()
        self._last_closure = -(10**9)
        self.outcomes: Counter[str] = Counter()
        """Searches and candidates so far, by outcome (:data:`OUTCOMES`)."""

    def check(
        self,
        index: int,
        poses: np.ndarray,
        submap_xy: np.ndarray,
        origins_xy: np.ndarray | None = None,
    ) -> LoopClosure | None:
        """Store keyframe ``index``'s submap and return a verified loop closure or None.

        poses: (>= index + 1, 3) current estimates ``[x_m, y_m, yaw_rad]`` of keyframes 0..index
        (map frame). submap_xy: (N, 2) radar points in keyframe ``index``'s base_link frame;
        origins_xy: (N, 2) where the sensor was when it saw each, in the same frame (None:
        unknown, the points get no normals).
        """
        submap_xy = np.asarray(submap_xy, dtype=float).reshape(-1, 2)
        if len(submap_xy) < self._min_points:  # too few points to match or to keep
            return None
        submap = Scan(submap_xy, origins_xy, self._normal_radius_m)
        closure = None
        if index - self._last_closure >= self._min_spacing:
            closure = self._search(index, np.asarray(poses, dtype=float), submap)
        self._submaps[index] = submap
        if closure is not None:
            self._last_closure = index
        return closure

    def _search(self, index: int, poses: np.ndarray, submap: Scan) -> LoopClosure | None:
        old = np.array([k for k in self._submaps if k <= index - self._min_index_gap], dtype=int)
        if old.size == 0:
            return None
        self.outcomes["searches"] += 1
        distance = np.linalg.norm(poses[old, :2] - poses[index, :2], axis=1)
        near = old[distance < self._search_radius_m]
        near = near[np.argsort(distance[distance < self._search_radius_m])]
        best = None
        for old_index in near[: self._max_candidates]:
            result, correction, target = self._match(submap, index, int(old_index), old, poses)
            rejection = self._rejection(result, correction)
            self.outcomes["candidates"] += 1
            if rejection is not None:
                self.outcomes[rejection] += 1
            elif best is None or result.rms_m < best[1].rms_m:
                best = (int(old_index), result, correction, target)
        if best is None:
            return None
        old_index, result, correction, target = best
        if self._ambiguous(submap, target, result, correction):
            logger.debug("loop closure %d -> %d dropped: a rival fits as well", old_index, index)
            self.outcomes["rival"] += 1
            return None
        self.outcomes["accepted"] += 1
        covariance = match_covariance(
            submap,
            target,
            result.delta,
            self._inlier_distance_m,
            self._match_sigmas_m,
        )
        covariance = floored_covariance(
            tangent_covariance(result.delta, covariance), self._floor_sigmas
        )
        logger.debug("loop closure %d -> %d, rms %.3f m", old_index, index, result.rms_m)
        return LoopClosure(
            old_index, index, result.delta, covariance, result.inlier_fraction, result.rms_m
        )

    def _match(
        self, submap: Scan, index: int, old_index: int, old: np.ndarray, poses: np.ndarray
    ) -> tuple[IcpResult, np.ndarray, Scan]:
        """ICP of keyframe ``index``'s ``submap`` onto old keyframe ``old_index``'s from the
        odometry guess and, if that does not verify, onto it joined with its neighbours
        (:meth:`_joined`). Returns the result, its correction of the guess and the target."""
        guess = se2_between(poses[old_index], poses[index])
        target = self._submaps[old_index]
        result = icp_2d(submap, target, guess, self._inlier_distance_m)
        correction = se2_between(guess, result.delta)
        if self._target_neighbours > 0 and not self._verified(result, correction):
            target = self._joined(old_index, old, poses)
            result = icp_2d(submap, target, guess, self._inlier_distance_m)
            correction = se2_between(guess, result.delta)
        return result, correction, target

    def _joined(self, old_index: int, old: np.ndarray, poses: np.ndarray) -> Scan:
        """The submap of ``old_index`` joined with those of its ``target_neighbours`` stored
        neighbours on each side among ``old`` (ascending keyframe indices), placed in its frame
        by the current estimates ``poses`` and thinned to one point a voxel."""
        at = int(np.searchsorted(old, old_index))
        span = old[max(0, at - self._target_neighbours) : at + self._target_neighbours + 1]
        placed = np.array([se2_between(poses[old_index], poses[k]) for k in span])
        cached = self._joined_cache.get(old_index)
        if cached is not None and np.array_equal(cached[0], span):
            moved = np.abs(cached[1] - placed)
            moved[:, 2] = np.abs(wrap_angle(moved[:, 2]))
            if np.all(moved <= JOINED_REUSE_TOLERANCE):
                self._joined_cache.move_to_end(old_index)
                return cached[2]
        scans = [self._submaps[int(k)] for k in span]
        xy = np.concatenate(
            [transform_points_2d(p, s.xy) for p, s in zip(placed, scans, strict=True)]
        )
        origins_xy = None
        if all(s.origins_xy is not None for s in scans):
            origins_xy = np.concatenate(
                [transform_points_2d(p, s.origins_xy) for p, s in zip(placed, scans, strict=True)]
            )
        keep = first_per_voxel(xy, self._voxel_m)
        joined = Scan(
            xy[keep], None if origins_xy is None else origins_xy[keep], self._normal_radius_m
        )
        self._joined_cache[old_index] = (span, placed, joined)
        self._joined_cache.move_to_end(old_index)
        while len(self._joined_cache) > JOINED_CACHE_SIZE:
            self._joined_cache.popitem(last=False)
        return joined

    def _ambiguous(
        self, submap: Scan, old: Scan, result: IcpResult, correction: np.ndarray
    ) -> bool:
        """Whether a far match (``correction``: its move from the odometry guess) has a rival
        optimum around it that fits at least as well."""
        if not self._rival_radii_m or _shift_m(correction) <= self._near_correction_m:
            return False
        own = fit_score(result.delta, submap, old, self._rival_sigma_m)
        rival = best_rival(
            submap,
            old,
            result.delta,
            self._rival_radii_m,
            self._inlier_distance_m,
            self._rival_sigma_m,
        )
        return rival >= own

    def _verified(self, result: IcpResult, correction: np.ndarray) -> bool:
        return self._rejection(result, correction) is None

    def _rejection(self, result: IcpResult, correction: np.ndarray) -> str | None:
        """Why a match (``correction``: its move from the odometry guess) is refused, as an
        :data:`OUTCOMES` key, or None if it verifies."""
        shift_m = _shift_m(correction)
        if shift_m > self._max_correction[0] or abs(correction[2]) > self._max_correction[1]:
            return "overcorrected"
        near = shift_m <= self._near_correction_m
        min_inliers = self._near_min_inlier_fraction if near else self._min_inlier_fraction
        if result.inlier_fraction < min_inliers:
            return "few_inliers"
        if result.rms_m > (self._near_max_rms_m if near else self._max_rms_m):
            return "high_rms"
        return None


def _shift_m(correction: np.ndarray) -> float:
    """How far (m) ICP moved the keyframe from the odometry guess (``correction``: the match
    in the guess's frame)."""
    return float(np.hypot(correction[0], correction[1]))


def get_loop_closer(config: LoopClosureConfig, voxel_m: float) -> LoopCloser:
    """A LoopCloser with the search and verification settings of ``config``; ``voxel_m``:
    the submaps' thinning, also of joined targets."""
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
        near=(
            config.near_correction_m,
            config.near_min_inlier_fraction,
            config.near_max_rms_m,
        ),
        rival_radii_m=config.rival_radii_m,
        rival_sigma_m=config.rival_sigma_m,
        normal_radius_m=config.normal_radius_m,
        match_sigmas_m=config.match_sigmas_m,
        target_neighbours=config.target_neighbours,
        voxel_m=voxel_m,
    )
