"""Noise models honour the reported covariance, floor over-confidence, and down-weight
outliers."""

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X

from smokyslam.backends.noise import (
    RobustKernel,
    floored_covariance,
    pose2_noise,
    tangent_covariance,
)
from smokyslam.errors import EstimationError

FLOOR = np.array([0.01, 0.01, 0.002])


def between_error(noise, measured: np.ndarray, predicted: np.ndarray) -> float:
    factor = gtsam.BetweenFactorPose2(X(0), X(1), gtsam.Pose2(*measured), noise)
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose2(0.0, 0.0, 0.0))
    values.insert(X(1), gtsam.Pose2(*predicted))
    return factor.error(values)


def test_pose2_tangent_order_is_x_y_theta():
    np.testing.assert_allclose(gtsam.Pose2.Logmap(gtsam.Pose2(0.1, 0.0, 0.0)), [0.1, 0, 0])
    np.testing.assert_allclose(gtsam.Pose2.Logmap(gtsam.Pose2(0.0, 0.0, 0.1)), [0, 0, 0.1])


def test_gaussian_noise_whitens_with_the_given_covariance():
    correlated = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.0025]])
    noise = pose2_noise(correlated, FLOOR)
    measured = np.array([1.0, 0.5, 0.2])
    predicted = np.array([1.1, 0.45, 0.23])
    tangent = gtsam.Pose2.Logmap(gtsam.Pose2(*measured).between(gtsam.Pose2(*predicted)))
    mahalanobis = tangent @ np.linalg.solve(correlated, tangent)
    assert between_error(noise, measured, predicted) == pytest.approx(0.5 * mahalanobis, rel=1e-9)
    whitened = noise.whiten(tangent)
    assert whitened @ whitened == pytest.approx(mahalanobis, rel=1e-9)


def test_floor_raises_over_confident_directions_only():
    tiny = np.diag([1e-8, 0.04, 1e-10])
    floored = floored_covariance(tiny, FLOOR)
    np.testing.assert_allclose(np.diag(floored), [1e-4, 0.04, 4e-6], rtol=1e-9)
    generous = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.01]])
    np.testing.assert_allclose(floored_covariance(generous, FLOOR), generous, atol=1e-15)
    # Nearly singular but large: the thin direction is raised, the result is invertible.
    thin = np.full((3, 3), 0.01)
    assert np.linalg.cond(floored_covariance(thin, FLOOR)) < 1e5
    with pytest.raises(EstimationError, match="finite"):
        floored_covariance(np.full((3, 3), np.nan), FLOOR)


@pytest.mark.parametrize("kernel", [RobustKernel.HUBER, RobustKernel.CAUCHY])
def test_robust_kernels_cap_large_errors_only(kernel):
    covariance = np.diag([0.1, 0.1, 0.05]) ** 2
    gaussian = pose2_noise(covariance, FLOOR)
    robust = pose2_noise(covariance, FLOOR, kernel, width=1.0)
    measured = np.array([1.0, 0.0, 0.0])
    small = np.array([1.02, 0.0, 0.0])  # 0.2 sigma
    large = np.array([3.0, 2.0, 1.0])  # tens of sigmas
    assert between_error(robust, measured, small) == pytest.approx(
        between_error(gaussian, measured, small), rel=0.05
    )
    assert between_error(robust, measured, large) < 0.1 * between_error(gaussian, measured, large)


def test_tangent_covariance_matches_sampled_logmap():
    rng = np.random.default_rng(0)
    delta = np.array([1.0, 0.3, 1.2])
    parent = np.array([[0.01, 0.004, 0.0], [0.004, 0.02, 0.001], [0.0, 0.001, 0.002]])
    samples = rng.multivariate_normal(delta, parent, size=20000)
    base = gtsam.Pose2(*delta)
    xi = np.array([gtsam.Pose2.Logmap(base.between(gtsam.Pose2(*s))) for s in samples])
    np.testing.assert_allclose(np.cov(xi.T), tangent_covariance(delta, parent), atol=6e-4)
