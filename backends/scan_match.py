"""2D scan matching for loop closures: point-to-point ICP between radar submaps whose points
carry the side of the surface they were seen from.

A solid object has two faces: a rack 1 m deep seen from the aisle on its south side shows its
south face, and from the aisle on its north side its north face. Points alone cannot tell the
faces apart, so ICP happily lays one face onto the other, a metre off: measured on simulated
warehouses, every loop closure more than 0.3 m wrong was such a match, from the opposite aisle
or from the opposite direction along rack ends, and there the true alignment fit worse than the
wrong one. Each point of a :class:`Scan` therefore gets an oriented normal: the normal of the
line through its neighbours (PCA), turned towards the sensor that saw it. Two points only
correspond when their normals point less than 90 degrees apart; a point without a line-like
neighbourhood (a pillar, clutter) or without a known view origin has no normal and matches any.

A match's covariance (:func:`match_covariance`) comes from the information of its matches along
the target's normals. Measured against the truth on 139 closures of simulated offices,
warehouses and corridors, the error along the direction this covariance calls weakest was 2.2x
that along the strongest (point-to-point information saw no such direction), and a closure's
error grew with its sigma.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from smokyslam.geometry import line_fit_2d, rotation_2d, transform_points_2d, wrap_angle

NORMAL_NEIGHBOURS = 48
"""Nearest points (the point itself included) whose spread gives a point's normal."""

MAX_FLATNESS = 0.3
"""A neighbourhood is line-like when its smaller spread (variance) is at most this share of its
larger one; otherwise the point has no normal."""

MATCH_CANDIDATES = 4
"""Nearest target points searched for the nearest one with a compatible normal."""

RIVAL_DIRECTIONS = 8
"""Shifts per ring radius from which ICP is restarted around a far match."""

WEAKEST_INFORMATION = np.diag([1e-2, 1e-2, 1.0])
"""Information (1 / (10 m)^2, 1 / (1 rad)^2) added to a match's, so that a direction no match
constrains gets a large but finite variance."""


def oriented_normals(
    xy: np.ndarray, origins_xy: np.ndarray | None, radius_m: float | None
) -> np.ndarray:
    """(N, 2) unit normals of the (N, 2) points ``xy`` turned towards ``origins_xy`` (N, 2),
    the sensor position each point was seen from; zero rows where a point has fewer than 3
    neighbours within ``radius_m``, a neighbourhood that is not line-like, or where there are
    no origins or no radius (normals off)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    normals = np.zeros_like(xy)
    if origins_xy is None or radius_m is None or len(xy) < 3:
        return normals
    k = min(NORMAL_NEIGHBOURS, len(xy))
    distance, index = cKDTree(xy).query(xy, k=k, distance_upper_bound=radius_m)
    near = np.isfinite(distance)
    _, normals, across, along = line_fit_2d(xy[np.where(near, index, 0)], near.astype(float))
    line_like = (near.sum(axis=1) >= 3) & (across <= MAX_FLATNESS * along)
    towards = np.einsum("nd,nd->n", normals, np.asarray(origins_xy, dtype=float) - xy)
    normals[towards < 0.0] *= -1.0
    normals[~line_like] = 0.0
    return normals


class Scan:
    """(N, 2) points of one frame with their KD-tree and, computed on first use, their (N, 2)
    oriented normals (zero rows: none; :func:`oriented_normals`).

    origins_xy: (N, 2) the sensor position each point was seen from; normal_radius_m: the
    normals' neighbourhood. Without either the points get no normals and match any point.
    """

    def __init__(
        self,
        xy: np.ndarray,
        origins_xy: np.ndarray | None = None,
        normal_radius_m: float | None = None,
    ) -> None:
        self.xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        self.tree = cKDTree(self.xy)
        self.origins_xy = None if origins_xy is None else np.asarray(origins_xy, dtype=float)
        self._normal_radius_m = normal_radius_m

    @cached_property
    def normals(self) -> np.ndarray:
        """(N, 2) oriented unit normals, zero rows where none."""
        return oriented_normals(self.xy, self.origins_xy, self._normal_radius_m)

    @cached_property
    def _padded_normals(self) -> np.ndarray:
        """(N + 1, 2) the normals and a zero row for the index a missed query returns."""
        return np.vstack([self.normals, np.zeros((1, 2))])

    def moved(self, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(points, normals) moved by ``delta`` (3,) ``[x_m, y_m, yaw_rad]``."""
        return transform_points_2d(delta, self.xy), self.normals @ rotation_2d(delta[2]).T

    def match(
        self, xy: np.ndarray, normals: np.ndarray, upper_m: float = np.inf
    ) -> tuple[np.ndarray, np.ndarray]:
        """(distance, index) (M,) of each of the (M, 2) points ``xy`` with (M, 2) ``normals``
        to its nearest point of this scan whose normal points less than 90 degrees away (or
        either has none); inf and ``len(self.xy)`` where there is none within ``upper_m``."""
        distance, index = self.tree.query(xy, distance_upper_bound=upper_m)
        padded = self._padded_normals
        clash = np.einsum("md,md->m", padded[index], normals) < 0.0
        if clash.any():  # the nearest point faces the other way: the nearest that does not
            k = min(MATCH_CANDIDATES, len(self.xy))
            near_d, near_i = self.tree.query(xy[clash], k=k, distance_upper_bound=upper_m)
            near_d, near_i = near_d.reshape(-1, k), near_i.reshape(-1, k)
            agree = np.einsum("mkd,md->mk", padded[near_i], normals[clash]) >= 0.0
            near_d = np.where(agree, near_d, np.inf)
            best = np.argmin(near_d, axis=1)
            rows = np.arange(len(best))
            distance[clash] = near_d[rows, best]
            index[clash] = np.where(np.isfinite(distance[clash]), near_i[rows, best], len(self.xy))
        return distance, index


@dataclass(frozen=True)
class IcpResult:
    """delta: (3,) ``[x_m, y_m, yaw_rad]`` of the source frame in the target frame.
    inlier_fraction: source points within the inlier distance of a target point.
    rms_m: RMS distance of those inliers."""

    delta: np.ndarray
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
    translation = mu_t - rotation_2d(yaw) @ mu_s
    return np.array([translation[0], translation[1], yaw])


def icp_2d(
    source: Scan,
    target: Scan,
    initial: np.ndarray,
    inlier_distance_m: float = 0.3,
    huber_m: float = 0.1,
    iterations: int = 40,
) -> IcpResult:
    """Align the ``source`` scan to the ``target`` scan, from ``initial`` (3,).

    Each iteration matches every source point to its nearest target point with a compatible
    normal (:meth:`Scan.match`), keeps matches closer than a match distance, weights them with
    Huber (``huber_m``) and refits the rigid transform in closed form. The match distance
    shrinks from 3x ``inlier_distance_m`` to it over the first half of the iterations
    (point-to-point ICP crawls from a rough guess with a tight gate). Stops early when the
    update falls below 1e-5 m / rad.
    """
    delta = np.asarray(initial, dtype=float).copy()
    coarse_to_fine = np.geomspace(3.0 * inlier_distance_m, inlier_distance_m, iterations // 2)
    schedule = np.r_[coarse_to_fine, np.full(iterations - coarse_to_fine.size, inlier_distance_m)]
    for match_distance_m in schedule:
        distance, nearest = target.match(*source.moved(delta), match_distance_m)
        inlier = np.isfinite(distance)
        if inlier.sum() < 3:
            return IcpResult(delta, 0.0, np.inf)
        weights = np.minimum(1.0, huber_m / np.maximum(distance[inlier], 1e-12))
        updated = _rigid_fit(source.xy[inlier], target.xy[nearest[inlier]], weights)
        step = np.abs(np.r_[updated[:2] - delta[:2], wrap_angle(updated[2] - delta[2])])
        delta = updated
        if step.max() < 1e-5:
            break
    moved, normals = source.moved(delta)
    distance, nearest = target.match(moved, normals, inlier_distance_m)
    inlier = np.isfinite(distance)
    if inlier.sum() < 3:
        return IcpResult(delta, 0.0, np.inf)
    residual = moved[inlier] - target.xy[nearest[inlier]]
    rms = float(np.sqrt((residual**2).sum(axis=1).mean()))
    return IcpResult(delta, float(inlier.mean()), rms)


def match_covariance(
    source: Scan,
    target: Scan,
    delta: np.ndarray,
    inlier_distance_m: float,
    sigmas_m: tuple[float, float],
) -> np.ndarray:
    """(3, 3) covariance of the match ``delta`` (3,) of ``source`` onto ``target``: of (tx, ty,
    yaw) perturbed additively, translation in the target frame.

    It is the inverse of the information of the source points' matches within
    ``inlier_distance_m``: a match to a target point with a normal fixes only the offset along
    that normal (sigma ``sigmas_m[0]``), a match to one without a normal both axes
    (``sigmas_m[1]``). So a closure in a corridor or aisle, whose walls all face across it,
    claims little along it; point-to-point information would count every wall point as fixing
    that direction too.
    """
    moved, normals = source.moved(delta)
    distance, nearest = target.match(moved, normals, inlier_distance_m)
    matched = np.isfinite(distance)
    # Residual Jacobian in (tx, ty, yaw): [I, perp(R p)] with perp(v) = (-v_y, v_x).
    rotated = moved[matched] - delta[:2]
    J = np.zeros((len(rotated), 2, 3))
    J[:, 0, 0] = J[:, 1, 1] = 1.0
    J[:, 0, 2], J[:, 1, 2] = -rotated[:, 1], rotated[:, 0]
    normal = target.normals[nearest[matched]]
    has_normal = normal.any(axis=1)
    along_normal = np.einsum("nk,nkj->nj", normal[has_normal], J[has_normal])
    information = along_normal.T @ along_normal / sigmas_m[0] ** 2
    information += np.einsum("nki,nkj->ij", J[~has_normal], J[~has_normal]) / sigmas_m[1] ** 2
    return np.linalg.inv(information + WEAKEST_INFORMATION)


def fit_score(delta: np.ndarray, source: Scan, target: Scan, sigma_m: float) -> float:
    """Mean Gaussian likelihood of the source points moved by ``delta`` (3,) against their
    nearest compatible target points, at point distance scale ``sigma_m``: 1 for a perfect fit.
    Sharper than the inlier fraction, whose 0.3 m gate counts a slid copy's points as well."""
    distance, _ = target.match(*source.moved(delta))
    return float(np.mean(np.exp(-0.5 * (distance / sigma_m) ** 2)))


def best_rival(
    source: Scan,
    target: Scan,
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
        rival = icp_2d(source, target, match + np.r_[shift, 0.0], inlier_distance_m)
        if (
            np.isfinite(rival.rms_m)
            and np.hypot(*(rival.delta[:2] - match[:2])) > inlier_distance_m
        ):
            best = max(best, fit_score(rival.delta, source, target, sigma_m))
    return best
