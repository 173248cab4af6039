"""PoseGraph: iSAM2 sees only new factors, the square closes, chains grow their covariance."""

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X

from smokyslam.backends.pose_graph import PoseGraph, get_pose_graph
from smokyslam.config import BackendConfig
from smokyslam.errors import EstimationError
from smokyslam.geometry import se2_between, se2_compose

ODOMETRY_SIGMAS = np.array([0.05, 0.05, 0.03])  # m, m, rad per 1 m step
PRIOR_COVARIANCE = np.diag([1e-6, 1e-6, 1e-8])


def square_truth(side_steps: int = 5, step_m: float = 1.0) -> np.ndarray:
    """(4 * side_steps + 1, 3) poses around a square, turning left at each corner."""
    poses = [np.zeros(3)]
    for _edge in range(4):
        for step in range(side_steps):
            turn = np.pi / 2 if step == side_steps - 1 else 0.0
            poses.append(se2_compose(poses[-1], [step_m, 0.0, turn]))
    return np.array(poses)


def noisy_square_graph(seed: int, with_loop: bool) -> tuple[PoseGraph, np.ndarray, list]:
    truth = square_truth()
    rng = np.random.default_rng(seed)
    graph = get_pose_graph(BackendConfig(floor_sigmas=(1e-4, 1e-4, 1e-5)))
    graph.add_prior(0, truth[0], PRIOR_COVARIANCE)
    graph.optimize()
    measurements = []
    for j in range(1, len(truth)):
        delta = se2_between(truth[j - 1], truth[j]) + rng.normal(0.0, ODOMETRY_SIGMAS)
        measurements.append((j - 1, j, delta, np.diag(ODOMETRY_SIGMAS**2)))
        graph.add_between(*measurements[-1])
        graph.optimize()
    if with_loop:
        # The walk ends where it started: a precise closure from the last pose to the first.
        closure = (0, len(truth) - 1, np.zeros(3), np.diag([0.01, 0.01, 0.005]) ** 2)
        measurements.append(closure)
        graph.add_between(*closure, source="loop")
        graph.optimize()
    return graph, truth, measurements


def batch_solution(truth: np.ndarray, measurements: list) -> np.ndarray:
    """The same graph solved in one Levenberg-Marquardt batch: the known answer."""
    graph = gtsam.NonlinearFactorGraph()
    graph.add(
        gtsam.PriorFactorPose2(
            X(0), gtsam.Pose2(0, 0, 0), gtsam.noiseModel.Gaussian.Covariance(PRIOR_COVARIANCE)
        )
    )
    initial = gtsam.Values()
    for k in range(len(truth)):
        initial.insert(X(k), gtsam.Pose2(*truth[k]))
    for i, j, delta, covariance in measurements:
        noise = gtsam.noiseModel.Gaussian.Covariance(covariance)
        graph.add(gtsam.BetweenFactorPose2(X(i), X(j), gtsam.Pose2(*delta), noise))
    result = gtsam.LevenbergMarquardtOptimizer(graph, initial).optimize()
    return gtsam.utilities.extractPose2(result)


def position_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.linalg.norm(estimate[:, :2] - truth[:, :2], axis=1)


def test_square_loop_closure_matches_batch_and_beats_odometry():
    closed, truth, measurements = noisy_square_graph(seed=3, with_loop=True)
    open_loop, _, _ = noisy_square_graph(seed=3, with_loop=False)
    estimate = closed.estimates()

    # iSAM2 relinearises lazily (threshold 0.01): measured within 3e-4 of the batch optimum.
    np.testing.assert_allclose(estimate, batch_solution(truth, measurements), atol=1e-3)
    # The closure pulls the end back onto the start.
    assert np.linalg.norm(estimate[-1, :2] - estimate[0, :2]) < 0.03
    odometry_end_error = position_errors(open_loop.estimates(), truth)[-1]
    assert odometry_end_error > 0.8  # measured 1.12 m with seed 3
    errors_closed = position_errors(estimate, truth)
    errors_open = position_errors(open_loop.estimates(), truth)
    # Measured RMS: 0.15 m closed vs 0.59 m open loop with seed 3.
    assert np.sqrt(np.mean(errors_closed**2)) < 0.4 * np.sqrt(np.mean(errors_open**2))
    assert closed.factor_counts == {"prior": 1, "radar": 20, "loop": 1}


def chain_graph(steps: int, step_covariance: np.ndarray) -> PoseGraph:
    graph = get_pose_graph(BackendConfig(floor_sigmas=(1e-4, 1e-4, 1e-5)))
    graph.add_prior(0, np.zeros(3), PRIOR_COVARIANCE)
    graph.optimize()
    for j in range(1, steps + 1):
        graph.add_between(j - 1, j, np.array([1.0, 0.0, 0.0]), step_covariance)
        graph.optimize()
    return graph


def test_chain_covariance_grows_as_propagated():
    step_covariance = np.diag([0.02, 0.01, 0.005]) ** 2
    steps = 10
    graph = chain_graph(steps, step_covariance)
    # Right-perturbation propagation: cov_j = Ad(delta^-1) cov_i Ad(delta^-1)^T + cov_step.
    adjoint = gtsam.Pose2(1.0, 0.0, 0.0).inverse().AdjointMap()
    expected = PRIOR_COVARIANCE.copy()
    for _ in range(steps):
        expected = adjoint @ expected @ adjoint.T + step_covariance
    np.testing.assert_allclose(graph.marginal_covariance(steps), expected, rtol=1e-6, atol=1e-12)
    # Closed form for a straight chain: variances add along the path, and heading errors reach
    # the lateral position through lever arms of 0..9 m. Counting factors twice would halve all.
    variances = np.diag(graph.marginal_covariance(steps))
    lateral = 1e-6 + steps * 0.01**2 + 0.005**2 * sum(k**2 for k in range(steps)) + 1e-8 * 100
    np.testing.assert_allclose(variances, [1e-6 + 10 * 0.02**2, lateral, 1e-8 + 10 * 0.005**2])


def test_optimize_without_new_factors_changes_nothing():
    graph = chain_graph(5, np.diag([0.02, 0.01, 0.005]) ** 2)
    before = [graph.marginal_covariance(k) for k in range(6)]
    estimates = graph.estimates()
    graph.optimize()
    graph.optimize()
    for k in range(6):
        np.testing.assert_allclose(graph.marginal_covariance(k), before[k], rtol=1e-9)
    np.testing.assert_allclose(graph.estimates(), estimates, atol=1e-12)


def test_new_pose_is_initialised_from_the_delta_and_pending_until_optimized():
    graph = get_pose_graph(BackendConfig())
    graph.add_prior(0, np.array([1.0, 2.0, np.pi / 2]), PRIOR_COVARIANCE)
    graph.add_between(0, 1, np.array([1.0, 0.0, 0.0]), np.diag([0.1, 0.1, 0.05]) ** 2)
    np.testing.assert_allclose(graph.estimate(1), [1.0, 3.0, np.pi / 2], atol=1e-12)
    assert graph.estimates().shape == (0, 3)
    with pytest.raises(EstimationError, match="not optimized"):
        graph.marginal_covariance(1)
    graph.optimize()
    assert graph.estimates().shape == (2, 3)
    assert len(graph) == 2


def test_unlinked_or_unknown_poses_are_refused():
    graph = get_pose_graph(BackendConfig())
    with pytest.raises(EstimationError, match="pose 0 does not exist"):
        graph.add_between(0, 1, np.zeros(3), np.eye(3))
    graph.add_prior(0, np.zeros(3), PRIOR_COVARIANCE)
    graph.optimize()
    graph._insert(1, np.zeros(3))  # a pose with no factor, as a buggy caller would leave it
    with pytest.raises(EstimationError, match=r"poses \[1\] have no factor"):
        graph.optimize()


def test_factory_reads_backend_config():
    graph = get_pose_graph(BackendConfig(floor_sigmas=(0.1, 0.1, 0.1)))
    graph.add_prior(0, np.zeros(3), PRIOR_COVARIANCE)
    graph.optimize()
    # The floor (0.1 m, 0.1 rad) overrides the too-confident prior.
    np.testing.assert_allclose(np.diag(graph.marginal_covariance(0)), [0.01] * 3, rtol=1e-6)


def _coasting_chain(graph: PoseGraph, seed: int, poses: int = 200) -> int:
    """Camera-like steps of millimetres, and now and then a lost camera's coasting step of
    metres and radians; returns how many poses were solved before iSAM2 gave up."""
    rng = np.random.default_rng(seed)
    graph.add_prior(0, np.zeros(3), PRIOR_COVARIANCE)
    graph.optimize()
    for i in range(1, poses):
        delta = np.array([0.21, rng.normal(0, 0.02), rng.normal(0, 0.2)])
        A = rng.normal(size=(3, 3))
        if rng.random() < 0.03:
            covariance = 2.0 * A @ A.T + 2.0 * np.eye(3)
        else:
            covariance = 9e-6 * A @ A.T + np.diag([1e-7, 1e-6, 1e-6])
        graph.add_between(i - 1, i, delta, covariance, source="camera")
        try:
            graph.optimize()
        except EstimationError:
            return i
    return poses


def test_a_chain_with_coasting_steps_is_solved_to_its_end():
    # Measured: Cholesky gave up ("indeterminate linear system") on 54 of 60 such chains, and
    # on a camera-only office run whose camera was lost for a few frames; QR solves them all.
    for seed in range(3):
        graph = get_pose_graph(BackendConfig())
        assert _coasting_chain(graph, seed) == 200
        assert np.isfinite(graph.estimates()).all()
    cholesky = get_pose_graph(BackendConfig(factorization="cholesky"))
    assert _coasting_chain(cholesky, 0) < 200  # the failure the default avoids
