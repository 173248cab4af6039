"""Radar odometry: Doppler ego-velocity, gyro integration, scan matching, dead reckoning."""

from smokyslam.frontends.radar.doppler import EgoVelocity, estimate_ego_velocity
from smokyslam.frontends.radar.odometry import DeadReckoning, RadarOdometry, poses_world_base

__all__ = [
    "DeadReckoning",
    "EgoVelocity",
    "RadarOdometry",
    "estimate_ego_velocity",
    "poses_world_base",
]
