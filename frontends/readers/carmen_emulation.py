"""A laser scanner and logged poses turned into a radar rig: sparse noisy points with Doppler,
and a gyro.

Used by the CARMEN reader. Real radar gives no yaw rate, so the emulated Doppler ego-velocity
is translation only; the yaw comes from an emulated gyro with noise and bias. Both are built
from the differences of the logged (SLAM-corrected) poses, not from the logs' timestamps.

The Doppler model assumes the sensor held a constant body twist over each step (the SE(2)
exponential), so ``se2_exp([v * dt, dyaw])`` with the true ``v`` and ``dyaw`` reproduces the
logged step exactly; noise then enters as configured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.config import CarmenConfig, RadarModelConfig
from smokyslam.geometry import se2_between, se2_log, wrap_angle


@dataclass
class EmulatedMotion:
    """Per-scan emulated motion sensors, for N scans.

    velocity_mps: (N, 2) radar-frame Doppler ego-velocity (scan 0: zero).
    gyro_yaw_rad: (N,) yaw increment since the previous scan as the gyro reports it (scan 0: 0).
    """

    velocity_mps: np.ndarray
    gyro_yaw_rad: np.ndarray


def emulate_motion(
    poses_world_sensor: np.ndarray, dt_s: float, config: CarmenConfig, rng: np.random.Generator
) -> EmulatedMotion:
    """Doppler velocity and gyro increments from (N, 3) sensor poses one ``dt_s`` apart.

    Step noise: each step's translation gets isotropic noise of sigma
    ``velocity_noise_rel * |step| + velocity_noise_abs_m``, then the scale error; the gyro
    increment gets ``gyro_noise_deg`` white noise plus ``gyro_bias_deg``, per scan.
    """
    poses = np.asarray(poses_world_sensor, dtype=float)
    steps = se2_between(poses[:-1], poses[1:])  # (N-1, 3), in the earlier pose's frame
    sigma = config.velocity_noise_rel * np.linalg.norm(steps[:, :2], axis=1)
    sigma += config.velocity_noise_abs_m
    noisy = steps.copy()
    noisy[:, :2] += rng.normal(size=(len(steps), 2)) * sigma[:, None]
    noisy[:, :2] *= 1.0 + config.doppler_scale_error
    # The true yaw sets how the chord maps to a body velocity; the radar never sees the yaw.
    noisy[:, 2] = steps[:, 2]
    twist = se2_log(noisy)
    velocity = np.vstack([np.zeros((1, 2)), twist[:, :2] / dt_s])
    gyro = steps[:, 2] + np.radians(
        config.gyro_bias_deg + config.gyro_noise_deg * rng.normal(size=len(steps))
    )
    return EmulatedMotion(velocity, np.concatenate([[0.0], gyro]))


@dataclass
class BeamGeometry:
    """Beam bearings of a laser and the range that means "no return"."""

    bearings_rad: np.ndarray
    no_return_m: float


def beam_bearings(n_beams: int) -> np.ndarray:
    """(n,) bearings (rad, sensor frame, counter-clockwise from forward) of n beams over 180°.

    The resolution is 180/n rounded to 0.25° (180 -> 1°, 360 and 361 -> 0.5°) and the first
    beam looks right, at -90° (CARMEN's convention; on the Intel log, consecutive scans placed
    with the logged poses overlap best with this start, against a centred fan).
    """
    resolution_deg = round(180.0 / n_beams * 4.0) / 4.0
    return np.radians(-90.0 + np.arange(n_beams) * resolution_deg)


def detect_no_return(ranges_m: np.ndarray, min_share: float = 0.01) -> float:
    """The no-return range of a log: the most frequent per-scan maximum, when it repeats in at
    least ``min_share`` of the (S, n) scans (and 3 of them); ``inf`` otherwise."""
    maxima = np.asarray(ranges_m, dtype=float).max(axis=1)
    values, counts = np.unique(maxima, return_counts=True)
    best = int(np.argmax(counts))
    if counts[best] >= max(3, min_share * len(maxima)):
        return float(values[best])
    return float("inf")


def emulate_radar_points(
    ranges_m: np.ndarray,
    geometry: BeamGeometry,
    velocity_mps: np.ndarray,
    radar: RadarModelConfig,
    config: CarmenConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """One laser scan as radar detections: (M, 3) points (m, sensor frame, z = 0) and (M,)
    Doppler speeds (m/s) of a static world seen at ``velocity_mps`` (2,).

    Valid beams lie inside the radar's field of view and range limits and are not no-returns;
    ``points_per_scan`` of them are drawn at random, ``dropout`` of those are lost, and the
    rest get the radar model's range and azimuth noise. Doppler uses the true bearing.
    """
    bearings = geometry.bearings_rad
    ranges = np.asarray(ranges_m, dtype=float)
    valid = (
        np.isfinite(ranges)
        & (ranges >= radar.min_range_m)
        & (ranges <= radar.max_range_m)
        & (ranges < geometry.no_return_m - 1e-6)
    )
    if config.emulate_radar:
        valid &= np.abs(bearings) <= np.radians(radar.fov_deg)
        index = np.flatnonzero(valid)
        if index.size > config.points_per_scan:
            index = np.sort(rng.choice(index, size=config.points_per_scan, replace=False))
        index = index[rng.random(index.size) >= config.dropout]
        range_noise = radar.range_sigma_m * rng.normal(size=index.size)
        azimuth_noise = np.radians(radar.azimuth_sigma_deg) * rng.normal(size=index.size)
    else:
        index = np.flatnonzero(valid)
        range_noise = azimuth_noise = np.zeros(index.size)
    true_bearing = bearings[index]
    directions = np.stack([np.cos(true_bearing), np.sin(true_bearing)], axis=1)
    doppler = -directions @ np.asarray(velocity_mps, dtype=float)
    if config.emulate_radar:
        doppler += config.doppler_point_sigma_mps * rng.normal(size=index.size)
    measured = wrap_angle(true_bearing + azimuth_noise)
    r = ranges[index] + range_noise
    points = np.stack([r * np.cos(measured), r * np.sin(measured), np.zeros(index.size)], axis=1)
    return points, doppler
