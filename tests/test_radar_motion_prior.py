"""The motion prior: SE(2) exp/log, gyro integration convention, heading/bias filter."""

import numpy as np
import pytest

from smokyslam.config import RadarOdometryConfig
from smokyslam.frontends.radar.map_age_bias import scan_yaw
from smokyslam.frontends.radar.motion_prior import (
    GyroIntegrator,
    HeadingFilter,
    MotionPriorEstimator,
    exp_jacobian,
)
from smokyslam.geometry import se2_compose, se2_exp, se2_log
from smokyslam.types import ImuSample, RadarScan


def test_se2_exp_and_log_are_inverse_and_match_small_steps():
    twists = np.array([[1.0, 0.2, 0.5], [0.3, -0.1, -2.0], [0.5, 0.0, 0.0], [0.0, 0.0, 1e-9]])
    np.testing.assert_allclose(se2_log(se2_exp(twists)), twists, atol=1e-12)
    # Holding a twist: exp of its parts composes to exp of the whole, and many tiny straight
    # steps approach it.
    twist = np.array([1.0, 0.3, 1.2])
    exact, approx = np.zeros(3), np.zeros(3)
    for _ in range(1000):
        exact = se2_compose(exact, se2_exp(twist / 1000))
        approx = se2_compose(approx, twist / 1000)
    np.testing.assert_allclose(se2_exp(twist), exact, atol=1e-10)
    np.testing.assert_allclose(se2_exp(twist), approx, atol=1e-3)


def test_exp_jacobian_is_the_derivative():
    twist = np.array([0.6, -0.2, 0.4])
    J = exp_jacobian(twist)
    step = np.array([1e-4, -2e-4, 3e-4])
    np.testing.assert_allclose(se2_exp(twist + step) - se2_exp(twist), J @ step, atol=1e-7)


def _gyro(stamp, rate):
    return ImuSample(stamp, np.array([0.0, 0.0, rate]), np.zeros(3))


def test_gyro_rates_hold_since_the_previous_sample():
    gyro = GyroIntegrator()
    assert gyro.integrate([], start_s=0.0) is None
    # One sample per frame carrying delta / dt integrates back to delta.
    assert gyro.integrate([_gyro(1.0, 0.3)], start_s=0.0) == pytest.approx(0.3)
    # 100 Hz samples between frames at 1.0 and 1.1 s.
    samples = [_gyro(1.0 + 0.01 * k, 2.0) for k in range(1, 11)]
    assert gyro.integrate(samples, start_s=1.0) == pytest.approx(0.2)


def test_heading_filter_learns_a_constant_bias_from_map_anchored_yaw():
    rng = np.random.default_rng(0)
    bias, dt = np.radians(0.5), 0.1
    heading = HeadingFilter(np.radians(0.2), np.radians(2.0), 0.0)
    yaw_true = yaw_est = 0.0
    scan_sigma = np.radians(1.0)
    for _ in range(600):
        step = 0.05
        gyro = step + bias * dt + np.radians(0.2) * dt * rng.normal()
        yaw_true += step
        predicted = yaw_est + gyro - heading.bias_radps * dt
        prior_var = heading.predict(dt)
        # A scan measures yaw against the map, combined with the prediction.
        measured = yaw_true + scan_sigma * rng.normal()
        posterior_var = 1.0 / (1.0 / prior_var + 1.0 / scan_sigma**2)
        yaw_est = predicted + posterior_var / scan_sigma**2 * (measured - predicted)
        heading.correct(scan_yaw(prior_var, posterior_var, yaw_est - predicted))
    assert heading.bias_radps == pytest.approx(bias, abs=np.radians(0.1))
    assert abs(yaw_est - yaw_true) < np.radians(1.0)


def _scan(stamp, velocity, n=30, seed=0):
    rng = np.random.default_rng(seed)
    bearings = rng.uniform(-1.0, 1.0, n)
    d = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)
    xyz = np.column_stack([4.0 * d, np.zeros(n)])
    return RadarScan(stamp, xyz, np.ones(n), -d @ np.asarray(velocity))


def test_prior_is_the_constant_twist_step_with_a_consistent_covariance():
    estimator = MotionPriorEstimator(RadarOdometryConfig())
    first = estimator.predict(_scan(0.0, [0.0, 0.0]))
    np.testing.assert_array_equal(first.delta, 0.0)
    prior = estimator.predict(_scan(0.5, [1.0, 0.2], seed=1), [_gyro(0.5, 0.4)])
    np.testing.assert_allclose(prior.delta, se2_exp([0.5, 0.1, 0.2]), atol=1e-3)
    assert np.all(np.linalg.eigvalsh(prior.covariance) > 0)
    assert np.sqrt(prior.covariance[2, 2]) == pytest.approx(np.radians(1.0) * 0.5, rel=1e-3)
    # Without a gyro the yaw is unconstrained.
    free = estimator.predict(_scan(1.0, [1.0, 0.2], seed=2))
    assert free.covariance[2, 2] > 1.0


def test_prior_coasts_when_doppler_fails():
    estimator = MotionPriorEstimator(RadarOdometryConfig())
    estimator.predict(_scan(0.0, [0.0, 0.0]))
    estimator.predict(_scan(1.0, [0.6, 0.0]), [_gyro(1.0, 0.0)])
    empty = RadarScan(2.0, np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    coast = estimator.predict(empty, [_gyro(2.0, 0.0)])
    assert not coast.doppler.valid
    assert coast.delta[0] == pytest.approx(0.6, abs=1e-3)
    assert coast.covariance[0, 0] > 0.5
