"""The carried sensor rig: where the radar and the camera sit on ``base_link``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from smokyslam.config import RigConfig
from smokyslam.errors import ConfigError
from smokyslam.geometry import (
    R_BODY_OPTICAL,
    quat_wxyz_from_xyzw,
    se2_compose,
    se2_from_matrix,
    se2_inverse,
    se3_from_se2,
    se3_matrix,
    transform_points_2d,
)
from smokyslam.types import Extrinsics, RadarScan

CALIBRATION_KEYS = ("l_b_r_x", "l_b_r_y", "l_b_r_z", "q_b_r_x", "q_b_r_y", "q_b_r_z", "q_b_r_w")
"""Radar-to-body keys of a radar calibration YAML (as shipped with the TI demo bag)."""


def radar_mount(rig: RigConfig) -> np.ndarray:
    """Planar pose ``[x, y, yaw]`` of the radar in base_link."""
    return np.array([*rig.radar_xy_m, rig.radar_yaw_rad])


def camera_mount(rig: RigConfig) -> np.ndarray:
    """Planar pose ``[x, y, yaw]`` of the camera body (x forward) in base_link."""
    return np.array([*rig.camera_xy_m, rig.camera_yaw_rad])


def rig_extrinsics(rig: RigConfig) -> Extrinsics:
    """``T_base_radar`` and ``T_base_camera`` (camera in optical axes: z forward, y down)."""
    T_base_radar = se3_from_se2(radar_mount(rig), rig.radar_height_m)
    T_base_camera = se3_from_se2(camera_mount(rig), rig.camera_height_m)
    T_base_camera[:3, :3] = T_base_camera[:3, :3] @ R_BODY_OPTICAL
    return Extrinsics(T_base_radar=T_base_radar, T_base_camera=T_base_camera)


def extrinsics_from_calibration(path: Path | str) -> Extrinsics:
    """``T_base_radar`` from a radar calibration YAML, base_link being its body (IMU) frame.

    ``l_b_r_{x,y,z}``: the radar origin in the body frame, metres; ``q_b_r_{x,y,z,w}``: the
    rotation from the radar frame to the body frame (so ``p_body = R p_radar + l``). The
    camera stays at base_link. Raises ConfigError naming the file and what is wrong.
    """
    path = Path(path)
    try:
        values = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"radar calibration {path}: cannot read it ({exc})") from None
    if not isinstance(values, dict):
        raise ConfigError(f"radar calibration {path}: not a YAML mapping")
    if missing := [key for key in CALIBRATION_KEYS if key not in values]:
        raise ConfigError(f"radar calibration {path}: missing {', '.join(missing)}")
    try:
        numbers = np.array([float(values[key]) for key in CALIBRATION_KEYS])
    except (TypeError, ValueError):
        raise ConfigError(f"radar calibration {path}: {CALIBRATION_KEYS} must be numbers") from None
    norm = float(np.linalg.norm(numbers[3:]))
    if not np.isfinite(numbers).all() or abs(norm - 1.0) > 0.01:
        raise ConfigError(f"radar calibration {path}: q_b_r is not a unit quaternion ({norm:.3f})")
    T_base_radar = se3_matrix(numbers[:3], quat_wxyz_from_xyzw(numbers[3:] / norm))
    return Extrinsics(T_base_radar=T_base_radar)


def level_scan(scan: RadarScan, T_base_radar: np.ndarray) -> tuple[RadarScan, np.ndarray]:
    """Express a scan in the radar's levelled frame (radar position and heading, z up from
    the radar's height).

    Returns the levelled scan and ``pose_base_radar`` [x_m, y_m, yaw_rad]. A tilted or rolled
    radar's points are rotated fully into base_link first, so only the planar part is lost.
    """
    T = np.asarray(T_base_radar, dtype=float)
    pose_base_radar = se2_from_matrix(T)
    points_base = scan.points_xyz_m @ T[:3, :3].T + T[:3, 3]
    levelled = points_base - [0.0, 0.0, T[2, 3]]
    levelled[:, :2] = transform_points_2d(se2_inverse(pose_base_radar), points_base[:, :2])
    out = RadarScan(scan.stamp_s, levelled, scan.intensity, scan.doppler_mps, scan.frame_id)
    return out, pose_base_radar


def sensor_poses(poses_world_base: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """(N, 3) world poses of a sensor mounted at ``mount`` on base_link, from (N, 3) base poses."""
    return se2_compose(np.asarray(poses_world_base, dtype=float), mount)


def sensor_velocities(
    poses_world_base: np.ndarray,
    velocity_world_base: np.ndarray,
    yaw_rate_radps: np.ndarray,
    mount: np.ndarray,
) -> np.ndarray:
    """(N, 2) world-frame velocity of a sensor point: v_base + omega x (R(yaw) @ lever arm)."""
    yaw = np.asarray(poses_world_base, dtype=float)[..., 2]
    c, s = np.cos(yaw), np.sin(yaw)
    lever_x = c * mount[0] - s * mount[1]
    lever_y = s * mount[0] + c * mount[1]
    omega = np.asarray(yaw_rate_radps, dtype=float)
    return np.asarray(velocity_world_base, dtype=float) + np.stack(
        [-omega * lever_y, omega * lever_x], axis=-1
    )
