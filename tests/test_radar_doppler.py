"""Doppler ego-velocity: RANSAC over point pairs, then least squares on the static inliers."""

import numpy as np
import pytest

from smokyslam.frontends.radar.doppler import estimate_ego_velocity


def _frame(velocity, n=40, outlier_fraction=0.3, sigma=0.02, seed=0):
    rng = np.random.default_rng(seed)
    bearings = rng.uniform(-np.radians(60), np.radians(60), n)
    directions = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)
    doppler = -directions @ np.asarray(velocity) + sigma * rng.normal(size=n)
    outliers = np.zeros(n, dtype=bool)
    outliers[rng.choice(n, round(outlier_fraction * n), replace=False)] = True
    # Moving people and ghosts: radial speeds unrelated to the sensor's motion.
    doppler[outliers] = rng.uniform(-2.5, 2.5, outliers.sum())
    return bearings, doppler, outliers


@pytest.mark.parametrize("seed", range(5))
def test_recovers_a_known_velocity_with_30_percent_outliers(seed):
    velocity = np.array([0.8, -0.25])
    bearings, doppler, outliers = _frame(velocity, seed=seed)
    result = estimate_ego_velocity(bearings, doppler)
    assert result.valid
    np.testing.assert_allclose(result.velocity_mps, velocity, atol=0.03)
    # Outliers that happen to agree with the static world cannot be told apart; most can.
    assert (result.inlier_mask & outliers).sum() <= 2
    assert result.inliers >= 0.65 * len(bearings)
    # The covariance describes the actual error (within 4 sigma) and is not identity.
    error = result.velocity_mps - velocity
    assert error @ np.linalg.solve(result.covariance, error) < 16.0
    assert np.all(np.linalg.eigvalsh(result.covariance) > 0)
    assert np.sqrt(result.covariance[0, 0]) < 0.02


def test_lateral_velocity_is_less_certain_than_forward_in_a_narrow_field_of_view():
    bearings, doppler, _ = _frame([0.5, 0.0], n=60, outlier_fraction=0.0, sigma=0.05, seed=3)
    result = estimate_ego_velocity(bearings, doppler)
    assert result.covariance[1, 1] > 2.0 * result.covariance[0, 0]


def test_standing_still_and_too_few_points():
    bearings, doppler, _ = _frame([0.0, 0.0], outlier_fraction=0.2, seed=1)
    result = estimate_ego_velocity(bearings, doppler)
    np.testing.assert_allclose(result.velocity_mps, 0.0, atol=0.02)
    few = estimate_ego_velocity(bearings[:3], doppler[:3])
    assert not few.valid and few.inliers == 0
    np.testing.assert_array_equal(few.velocity_mps, 0.0)
    empty = estimate_ego_velocity(np.zeros(0), np.zeros(0))
    assert not empty.valid and empty.inlier_mask.shape == (0,)


def test_all_pairs_along_one_bearing_are_degenerate():
    bearings = np.full(10, 0.3)
    result = estimate_ego_velocity(bearings, np.full(10, -0.5))
    assert not result.valid


def test_many_points_use_a_random_subset_of_hypotheses():
    velocity = np.array([1.2, 0.3])
    bearings, doppler, _ = _frame(velocity, n=400, outlier_fraction=0.3, seed=4)
    result = estimate_ego_velocity(bearings, doppler, max_hypotheses=200)
    np.testing.assert_allclose(result.velocity_mps, velocity, atol=0.01)
