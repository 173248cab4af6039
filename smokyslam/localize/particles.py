"""A weighted set of SE(2) poses, and the three things both the localizer and its scouts do
with one: move it by an odometry step, weigh it by a scan, tell when its weights have
degenerated. Numpy over particles (and particles x points inside the likelihood field)."""

from __future__ import annotations

import numpy as np

from smokyslam.geometry import se2_compose, wrap_angle
from smokyslam.localize.likelihood import LikelihoodField
from smokyslam.localize.sampling import low_variance


class ParticleSet:
    """(P, 3) ``poses`` (x m, y m, yaw rad) with (P,) normalised ``weights``."""

    def __init__(self) -> None:
        self.poses = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.version = 0
        """Counts every change of poses or weights (for results cached between changes)."""

    def __len__(self) -> int:
        return len(self.poses)

    def reset(self, poses: np.ndarray, weights: np.ndarray | None = None) -> None:
        """Take (P, 3) ``poses`` (yaw wrapped), equally weighted or by (P,) ``weights``
        (normalised here)."""
        self.poses = np.asarray(poses, dtype=float)
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        if weights is None:
            self.weights = np.full(len(self.poses), 1.0 / max(len(self.poses), 1))
        else:
            self.weights = np.asarray(weights, dtype=float) / float(np.sum(weights))
        self.version += 1

    def move(self, delta: np.ndarray, covariance: np.ndarray, rng: np.random.Generator) -> None:
        """Compose every pose with the (3,) step ``delta`` plus a draw of its (3, 3)
        ``covariance``."""
        if not len(self.poses):
            return
        noise = rng.multivariate_normal(np.zeros(3), covariance, len(self.poses))
        self.poses = se2_compose(self.poses, np.asarray(delta, dtype=float) + noise)
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        self.version += 1

    def weigh(
        self,
        field: LikelihoodField,
        points_xy: np.ndarray,
        points_weight: float,
        p_unknown: float | None = None,
    ) -> tuple[np.ndarray, float]:
        """Multiply the weights by the likelihood of the (N, 2) ``points_xy`` (each point's
        log-likelihood tempered by ``points_weight``). Returns ((P,) raw log-likelihoods,
        how well the set explained a point before this scan reweighed it: the weighted mean
        of each pose's per-point geometric-mean likelihood, untempered, so it depends neither
        on the points' count nor on the exponent)."""
        raw = field.log_likelihood(self.poses, points_xy, p_unknown)
        mean_l = float(self.weights @ np.exp(raw / len(points_xy)))
        log_l = raw * points_weight
        weights = self.weights * np.exp(log_l - log_l.max())
        total = weights.sum()
        if not np.isfinite(total) or total <= 0:
            weights, total = np.ones(len(weights)), float(len(weights))
        self.weights = weights / total
        self.version += 1
        return raw, mean_l

    def degenerate(self, share: float) -> bool:
        """Whether the effective sample size is below ``share`` of the set's size."""
        return 1.0 / float(np.sum(self.weights**2)) < share * len(self.weights)

    def draw(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) poses drawn by weight (low-variance resampling)."""
        return self.poses[low_variance(self.weights, n, rng)]

    def mean(self, keep: np.ndarray | None = None) -> np.ndarray:
        """(3,) weighted mean pose (circular in yaw) of the set, or of its ``keep`` part."""
        return weighted_mean(
            self.poses if keep is None else self.poses[keep],
            self.weights if keep is None else self.weights[keep],
        )


def weighted_mean(poses: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(3,) mean of (P, 3) poses weighted by (P,) ``weights`` (circular in yaw)."""
    w = weights / weights.sum()
    xy = w @ poses[:, :2]
    yaw = np.arctan2(w @ np.sin(poses[:, 2]), w @ np.cos(poses[:, 2]))
    return np.array([xy[0], xy[1], yaw])


def near(poses: np.ndarray, centre: np.ndarray, radius_m: float, radius_rad: float) -> np.ndarray:
    """(P,) bool: which of the (P, 3) ``poses`` lie within ``radius_m`` and ``radius_rad``
    (heading, wrapped) of the (3,) ``centre``."""
    d = poses - centre
    return (np.hypot(d[:, 0], d[:, 1]) < radius_m) & (np.abs(wrap_angle(d[:, 2])) < radius_rad)


def smoothed(average: float, value: float, rate: float) -> float:
    """An exponential moving average moved towards ``value`` at ``rate``; it starts at the
    first value (an average of 0 is one not started)."""
    return average + rate * (value - average) if average else value
