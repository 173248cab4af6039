"""The carried sensor rig: where the radar and the camera sit on ``base_link``."""

from __future__ import annotations

import numpy as np

from smokyslam.config import RigConfig
from smokyslam.geometry import R_BODY_OPTICAL, se2_compose, se3_from_se2
from smokyslam.types import Extrinsics


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
