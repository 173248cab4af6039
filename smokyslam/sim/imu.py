"""Simulated planar IMU on base_link: gyro and accelerometer with constant bias and white noise.

The truth comes from the walk: yaw rate about +z, and specific force = the base_link
acceleration expressed in the body frame (x forward, y left) with +9.81 m/s^2 on z (the
accelerometer holds the rig up against gravity). Gyro x/y read zero truth.

Noise model, per axis: one constant bias drawn uniformly in ``±config.*_bias_*`` for the
whole log, plus white noise with standard deviation ``config.*_noise_*`` per sample.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import ImuModelConfig
from smokyslam.sim.trajectory import Trajectory
from smokyslam.types import ImuSample

GRAVITY_MPS2 = 9.81


def imu_truth(trajectory: Trajectory, stamps_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free (M, 3) gyro rad/s and (M, 3) specific force m/s^2 in the body frame."""
    t = trajectory.stamps_s
    poses = trajectory.poses_world_base
    accel_world = np.stack([np.gradient(np.gradient(poses[:, i], t), t) for i in (0, 1)], axis=-1)
    ax = np.interp(stamps_s, t, accel_world[:, 0])
    ay = np.interp(stamps_s, t, accel_world[:, 1])
    yaw = trajectory.pose_at(stamps_s)[:, 2]
    c, s = np.cos(yaw), np.sin(yaw)
    accel = np.stack([c * ax + s * ay, -s * ax + c * ay, np.full_like(ax, GRAVITY_MPS2)], axis=-1)
    gyro = np.zeros_like(accel)
    gyro[:, 2] = trajectory.yaw_rate_at(stamps_s)
    return gyro, accel


def simulate_imu(
    trajectory: Trajectory, config: ImuModelConfig, rng: np.random.Generator
) -> list[ImuSample]:
    """IMU samples at ``config.rate_hz`` over the whole trajectory, in time order."""
    stamps = np.arange(trajectory.stamps_s[0], trajectory.stamps_s[-1] + 1e-9, 1.0 / config.rate_hz)
    gyro, accel = imu_truth(trajectory, stamps)
    gyro_bias = rng.uniform(-1.0, 1.0, 3) * config.gyro_bias_radps
    accel_bias = rng.uniform(-1.0, 1.0, 3) * config.accel_bias_mps2
    gyro = gyro + gyro_bias + rng.normal(0.0, config.gyro_noise_radps, gyro.shape)
    accel = accel + accel_bias + rng.normal(0.0, config.accel_noise_mps2, accel.shape)
    return [
        ImuSample(stamp_s=float(t), gyro_radps=g, accel_mps2=a)
        for t, g, a in zip(stamps, gyro, accel, strict=True)
    ]
