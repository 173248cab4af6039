"""Simulated IMU against walks with known yaw rate and acceleration."""

from __future__ import annotations

import numpy as np
import pytest

from smokyslam.config import ImuModelConfig
from smokyslam.sim.imu import GRAVITY_MPS2, imu_truth, simulate_imu
from smokyslam.sim.trajectory import Trajectory

RATE_HZ = 200.0


def circle_walk(speed_mps=0.8, yaw_rate_radps=0.3, duration_s=30.0) -> Trajectory:
    """Constant speed on a circle: body acceleration (0, v * omega), yaw rate omega."""
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    radius = speed_mps / yaw_rate_radps
    yaw = yaw_rate_radps * t
    poses = np.stack([radius * np.sin(yaw), radius * (1.0 - np.cos(yaw)), yaw], axis=-1)
    return Trajectory(t, poses)


def accelerating_walk(accel_mps2=0.2, heading_rad=0.7, duration_s=10.0) -> Trajectory:
    """Straight line from rest at constant acceleration: body acceleration (a, 0), no turning."""
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    d = 0.5 * accel_mps2 * t**2
    poses = np.stack(
        [d * np.cos(heading_rad), d * np.sin(heading_rad), np.full_like(t, heading_rad)], axis=-1
    )
    return Trajectory(t, poses)


def as_arrays(samples):
    stamps = np.array([s.stamp_s for s in samples])
    return (
        stamps,
        np.stack([s.gyro_radps for s in samples]),
        np.stack([s.accel_mps2 for s in samples]),
    )


def test_truth_of_a_circle_walk():
    walk = circle_walk()
    stamps = np.arange(1.0, 29.0, 0.01)
    gyro, accel = imu_truth(walk, stamps)
    np.testing.assert_allclose(gyro[:, 2], 0.3, atol=1e-6)
    np.testing.assert_allclose(accel[:, 0], 0.0, atol=1e-4)
    np.testing.assert_allclose(accel[:, 1], 0.8 * 0.3, atol=1e-4)
    np.testing.assert_allclose(accel[:, 2], GRAVITY_MPS2)


def test_samples_are_at_the_configured_rate_over_the_whole_walk():
    walk = circle_walk(duration_s=5.0)
    stamps, _, _ = as_arrays(simulate_imu(walk, ImuModelConfig(), np.random.default_rng(0)))
    np.testing.assert_allclose(np.diff(stamps), 0.01, atol=1e-9)
    assert stamps[0] == walk.stamps_s[0] and walk.stamps_s[-1] - stamps[-1] < 0.01


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_integrated_gyro_matches_yaw_change_within_bias_and_noise(seed):
    config = ImuModelConfig()
    walk = circle_walk()
    stamps, gyro, _ = as_arrays(simulate_imu(walk, config, np.random.default_rng(seed)))
    dt = 1.0 / config.rate_hz
    yaw_change = np.sum(gyro[:-1, 2]) * dt
    true_change = np.unwrap(walk.pose_at(stamps)[:, 2])[-1] - walk.pose_at(stamps[0])[2]
    duration = stamps[-1] - stamps[0]
    bound = config.gyro_bias_radps * duration + 4.0 * config.gyro_noise_radps * dt * np.sqrt(
        len(stamps)
    )
    assert abs(yaw_change - true_change) <= bound + 1e-3
    # The bias is really there: the mean error is constant and within its bound.
    error = gyro[:, 2] - 0.3
    assert abs(np.mean(error)) <= config.gyro_bias_radps + 4 * config.gyro_noise_radps / 50
    assert np.std(error) == pytest.approx(config.gyro_noise_radps, rel=0.1)


@pytest.mark.parametrize(
    ("walk", "expected_xy"),
    [(circle_walk(), (0.0, 0.24)), (accelerating_walk(), (0.2, 0.0))],
)
def test_mean_accel_matches_the_walk(walk, expected_xy):
    config = ImuModelConfig()
    _, _, accel = as_arrays(simulate_imu(walk, config, np.random.default_rng(4)))
    core = slice(10, -10)  # central differences are one-sided at the ends
    tolerance = config.accel_bias_mps2 + 4 * config.accel_noise_mps2 / np.sqrt(len(accel))
    np.testing.assert_allclose(accel[core, :2].mean(axis=0), expected_xy, atol=tolerance)
    assert accel[core, 2].mean() == pytest.approx(GRAVITY_MPS2, abs=tolerance)
    assert np.std(accel[core, 0]) == pytest.approx(config.accel_noise_mps2, rel=0.1)


def test_noise_free_config_reproduces_the_truth():
    config = ImuModelConfig(
        gyro_noise_radps=0.0, gyro_bias_radps=0.0, accel_noise_mps2=0.0, accel_bias_mps2=0.0
    )
    walk = accelerating_walk()
    _, gyro, accel = as_arrays(simulate_imu(walk, config, np.random.default_rng(0)))
    np.testing.assert_allclose(gyro, 0.0, atol=1e-9)
    np.testing.assert_allclose(accel[10:-10, 0], 0.2, atol=1e-6)
    np.testing.assert_allclose(accel[10:-10, 1], 0.0, atol=1e-6)
