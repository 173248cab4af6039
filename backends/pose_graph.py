"""The pose graph: Pose2 keyframe states X(i) in iSAM2, fed only new factors each update.

Poses are base_link in the map frame, ``[x_m, y_m, yaw_rad]``. Every factor comes with the
covariance its frontend reported (gtsam tangent order ``[x, y, theta]``, see ``noise.py``),
floored so that no frontend can claim more than ``floor_sigmas``.
"""

from __future__ import annotations

import logging
from collections import Counter
from typing import TYPE_CHECKING

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, X

from smokyslam.backends.gyro import gyro_turn_factor
from smokyslam.backends.noise import RobustKernel, pose2_noise
from smokyslam.errors import EstimationError

if TYPE_CHECKING:
    from smokyslam.config import BackendConfig

logger = logging.getLogger(__name__)


def _pose2(pose: np.ndarray) -> gtsam.Pose2:
    return gtsam.Pose2(float(pose[0]), float(pose[1]), float(pose[2]))


def _array(pose: gtsam.Pose2) -> np.ndarray:
    return np.array([pose.x(), pose.y(), pose.theta()])


class PoseGraph:
    """Incremental Pose2 graph over ``gtsam.ISAM2``.

    Keyframes are numbered 0, 1, 2, ... in time order. Add factors with ``add_prior`` /
    ``add_between`` (a between factor to a new index also creates that pose, initialised by
    composing the delta onto the current estimate of the other end), then call ``optimize``
    once per keyframe. Odometry keyframe steps enter as between factors (source "radar" or
    "camera"), camera factors after ``scale.metric_relative_pose`` and
    ``camera_gate.inflate_covariance`` (source "camera"), loop closures with a robust kernel.

    Only the factors and values added since the last ``optimize`` reach iSAM2; giving it the
    whole graph again would count every factor twice and make the marginals overconfident.
    """

    def __init__(
        self,
        floor_sigmas: tuple[float, float, float],
        relinearize_threshold: float,
        relinearize_skip: int,
        loop_closure_iterations: int,
        factorization: str = "qr",
    ) -> None:
        """``floor_sigmas``: smallest ``[x_m, y_m, theta_rad]`` sigmas any factor may claim.
        ``loop_closure_iterations``: extra iSAM2 updates after a factor joins two old poses.
        ``factorization``: iSAM2's linear solver, "qr" or "cholesky" (faster in theory, but
        it gives up on chains that mix near-certain steps with nearly uninformative ones)."""
        params = gtsam.ISAM2Params()
        params.setFactorization(factorization.upper())
        params.setRelinearizeThreshold(relinearize_threshold)
        params.relinearizeSkip = relinearize_skip
        self._isam = gtsam.ISAM2(params)
        self._floor_sigmas = np.asarray(floor_sigmas, dtype=float)
        self._loop_closure_iterations = loop_closure_iterations
        self._new_factors = gtsam.NonlinearFactorGraph()
        self._new_values = gtsam.Values()
        self._pending_keys: set[int] = set()
        self._optimized: set[int] = set()
        self._pending_loop = False
        self._estimates: np.ndarray | None = None
        self._biases: dict[int, int] = {}  # keyframe -> the key of its gyro bias B(key)
        self._bias_key: int | None = None  # the current span's
        self._bias_elapsed_s = 0.0
        self._bias_prior: tuple[float, float] | None = None  # (mean, sigma) to place next
        self._bias_prior_index: int | None = None  # iSAM2's index of the one in place
        self.factor_counts: Counter[str] = Counter()
        """Factors added per source ("prior", "radar", "doppler", "camera", "loop", ...)."""

    # ------------------------------------------------------------------ adding

    def __len__(self) -> int:
        return len(self._optimized) + len(self._pending_keys)

    def has_pose(self, index: int) -> bool:
        """Whether pose ``index`` exists (optimized or pending)."""
        return index in self._optimized or index in self._pending_keys

    def add_prior(self, index: int, pose: np.ndarray, covariance: np.ndarray) -> None:
        """Anchor pose ``index`` at ``pose`` (3,) with a (3, 3) covariance; creates it if new."""
        if not self.has_pose(index):
            self._insert(index, np.asarray(pose, dtype=float))
        noise = pose2_noise(covariance, self._floor_sigmas)
        self._new_factors.add(gtsam.PriorFactorPose2(X(index), _pose2(pose), noise))
        self.factor_counts["prior"] += 1

    def add_between(
        self,
        i: int,
        j: int,
        delta: np.ndarray,
        covariance: np.ndarray,
        kernel: RobustKernel = RobustKernel.GAUSSIAN,
        kernel_width: float = 1.0,
        source: str = "radar",
    ) -> None:
        """Constrain pose ``j`` relative to pose ``i``.

        delta: (3,) ``[x_m, y_m, yaw_rad]`` of frame j in frame i. covariance: (3, 3) in the
        Pose2 tangent of ``delta`` (use ``noise.tangent_covariance`` for parent-frame ones).
        kernel / kernel_width: robust M-estimator for factors that may be outliers (loop
        closures, camera). A new ``j`` is created and initialised at ``estimate(i) * delta``.
        """
        delta = np.asarray(delta, dtype=float)
        if not self.has_pose(i):
            raise EstimationError(f"between factor {i}->{j}: pose {i} does not exist yet")
        if not self.has_pose(j):
            self._insert(j, _array(_pose2(self.estimate(i)).compose(_pose2(delta))))
        elif abs(j - i) > 1:
            self._pending_loop = True  # keyframes are numbered in order: this closes a loop
        noise = pose2_noise(covariance, self._floor_sigmas, kernel, kernel_width)
        self._new_factors.add(gtsam.BetweenFactorPose2(X(i), X(j), _pose2(delta), noise))
        self.factor_counts[source] += 1

    def add_gyro_turn(
        self,
        i: int,
        j: int,
        turn_rad: float | None,
        dt_s: float,
        sigma_rad: float,
        bias_walk: float,
        first_bias_sigma_radps: float,
        bias_span_s: float = 30.0,
    ) -> None:
        """Hold the turn from pose ``i`` to pose ``j`` to the gyro's raw ``turn_rad`` less
        the bias x ``dt_s`` (``backends/gyro.py``). The bias is one variable for every
        ``bias_span_s`` seconds of keyframes, B(first keyframe of the span); each follows the
        one before within a random walk of ``bias_walk`` rad/s per sqrt(s). The first gets a
        zero-mean prior of ``first_bias_sigma_radps``. ``turn_rad`` None (no gyro over the
        pair): the turn is left to the other factors."""
        if self._bias_key is None:
            self._bias_key = i
            self._new_values.insert(B(i), np.zeros(1))
            prior = gtsam.noiseModel.Isotropic.Sigma(1, first_bias_sigma_radps)
            self._new_factors.add(gtsam.PriorFactorVector(B(i), np.zeros(1), prior))
        self._bias_elapsed_s += dt_s
        if self._bias_elapsed_s >= bias_span_s:  # a new span: its bias walks from the last
            walk = gtsam.noiseModel.Isotropic.Sigma(1, bias_walk * np.sqrt(self._bias_elapsed_s))
            self._new_values.insert(B(i), self._bias(self._bias_key))
            self._new_factors.add(
                gtsam.BetweenFactorVector(B(self._bias_key), B(i), np.zeros(1), walk)
            )
            self._bias_key, self._bias_elapsed_s = i, dt_s
        self._biases[i] = self._biases[j] = self._bias_key
        if turn_rad is not None:
            point = gtsam.Values()
            point.insert(X(i), _pose2(self.estimate(i)))
            point.insert(X(j), _pose2(self.estimate(j)))
            point.insert(B(self._bias_key), self._bias(self._bias_key))
            keys = (X(i), X(j), B(self._bias_key))
            self._new_factors.add(gyro_turn_factor(keys, point, turn_rad, dt_s, sigma_rad))
            self.factor_counts["gyro"] += 1

    def hold_gyro_bias(self, mean_radps: float, sigma_radps: float) -> None:
        """A prior on the current gyro bias at the next ``optimize``, replacing the one
        placed before: a running estimate from elsewhere (the radar odometry's), each a
        better version of the last rather than a new measurement."""
        if self._bias_key is not None:
            self._bias_prior = (float(mean_radps), float(sigma_radps))

    def _bias(self, index: int) -> np.ndarray:
        """(1,) current estimate of the gyro bias B(index) (initial guess if pending)."""
        if self._new_values.exists(B(index)):
            return self._new_values.atVector(B(index))
        return np.asarray(self._isam.calculateEstimateVector(B(index)))

    def gyro_bias(self, index: int) -> float | None:
        """Optimized gyro bias (rad/s) of keyframe ``index``, None without one."""
        key = self._biases.get(index)
        if key is None or self._new_values.exists(B(key)):
            return None
        return float(self._isam.calculateEstimateVector(B(key))[0])

    def _insert(self, index: int, pose: np.ndarray) -> None:
        self._new_values.insert(X(index), _pose2(pose))
        self._pending_keys.add(index)

    # ------------------------------------------------------------------ solving

    def optimize(self) -> None:
        """One iSAM2 update with the pending factors and values, then forget them.

        After a loop closure (a factor between two existing, non-consecutive poses) a few
        more updates let iSAM2 relinearise the moved part of the trajectory.
        """
        symbols = [gtsam.Symbol(k) for k in self._new_factors.keyVector()]
        constrained = {x.index() for x in symbols if x.chr() == ord("x")}
        unlinked = self._pending_keys - constrained
        if unlinked:
            raise EstimationError(f"poses {sorted(unlinked)} have no factor; link each new pose")
        remove = []
        if self._bias_prior is not None:  # swap in the newest bias prior
            mean, sigma = self._bias_prior
            noise = gtsam.noiseModel.Isotropic.Sigma(1, sigma)
            prior_at = self._new_factors.size()
            self._new_factors.add(gtsam.PriorFactorVector(B(self._bias_key), [mean], noise))
            remove = [] if self._bias_prior_index is None else [self._bias_prior_index]
        try:
            result = self._isam.update(self._new_factors, self._new_values, remove)
            if self._bias_prior is not None:
                self._bias_prior_index = result.getNewFactorsIndices()[prior_at]
                self._bias_prior = None
            for _ in range(self._loop_closure_iterations if self._pending_loop else 0):
                self._isam.update()
        except RuntimeError as exc:  # gtsam's text spans paragraphs: its first one says it
            reason = " ".join(str(exc).strip().split("\n\n")[0].split())
            raise EstimationError(f"iSAM2 update failed: {reason}") from exc
        self._new_factors.resize(0)
        self._new_values.clear()
        self._optimized |= self._pending_keys
        self._pending_keys.clear()
        self._pending_loop = False
        self._estimates = None

    def estimate(self, index: int) -> np.ndarray:
        """Current (3,) ``[x_m, y_m, yaw_rad]`` of pose ``index`` (initial guess if pending)."""
        if index in self._pending_keys:
            return _array(self._new_values.atPose2(X(index)))
        if index not in self._optimized:
            raise EstimationError(f"pose {index} does not exist")
        return _array(self._isam.calculateEstimatePose2(X(index)))

    def estimates(self) -> np.ndarray:
        """(N, 3) optimized poses in index order (pending poses are not included)."""
        if self._estimates is None:
            if not self._optimized:
                return np.zeros((0, 3))
            values = self._isam.calculateEstimate()
            self._estimates = gtsam.utilities.extractPose2(values).reshape(-1, 3)
        return self._estimates.copy()

    def marginal_covariance(self, index: int) -> np.ndarray:
        """(3, 3) marginal covariance of an optimized pose, tangent order ``[x, y, theta]``."""
        if index not in self._optimized:
            raise EstimationError(f"pose {index} is not optimized yet; call optimize() first")
        return np.asarray(self._isam.marginalCovariance(X(index)))


def get_pose_graph(config: BackendConfig) -> PoseGraph:
    """A PoseGraph with the iSAM2 settings and covariance floors of ``config``."""
    return PoseGraph(
        floor_sigmas=config.floor_sigmas,
        relinearize_threshold=config.relinearize_threshold,
        relinearize_skip=config.relinearize_skip,
        loop_closure_iterations=config.loop_closure_iterations,
        factorization=config.factorization,
    )
