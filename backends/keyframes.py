"""Keyframes: the paper's gate, and odometry steps composed into keyframe between factors.

:class:`KeyframeGate` is the one gate of the project (``keyframes:`` in the config): the pose
graph takes a keyframe when it passes, and the maps are stitched at exactly those keyframes,
online or after the run (:func:`keyframe_mask` applies it to a finished trajectory).

An odometry source reports one step per frame (``Odometry.delta``, sensor frame, covariance
of ``(tx, ty, yaw)`` with the translation in the previous frame). :class:`Keyframer` composes
those steps until the gate passes, then hands out one between factor in base_link with the
covariance propagated through every composition, never identity. Covariances are in gtsam's
Pose2 tangent ``[x, y, theta]`` (right perturbation, see ``backends/noise.py``).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.backends.noise import tangent_covariance
from smokyslam.geometry import (
    first_per_voxel,
    se2_between,
    se2_compose,
    se2_compose_with_covariance,
    se2_conjugate,
    se2_inverse,
    transform_points_2d,
)
from smokyslam.types import Odometry

if TYPE_CHECKING:
    from smokyslam.config import KeyframeConfig


class KeyframeGate:
    """A new keyframe once base_link has moved ``translation_m`` along x or y of the last
    keyframe's frame, or turned ``rotation_rad``, since that keyframe."""

    def __init__(self, translation_m: float, rotation_rad: float) -> None:
        self.translation_m = translation_m
        self.rotation_rad = rotation_rad

    def passes(self, delta: np.ndarray) -> bool:
        """Whether the (3,) motion ``[x_m, y_m, yaw_rad]`` since the last keyframe (in its
        base_link frame) makes a new keyframe."""
        moved = np.abs(delta[:2]).max() >= self.translation_m
        return bool(moved or abs(delta[2]) >= self.rotation_rad)


def get_keyframe_gate(config: KeyframeConfig) -> KeyframeGate:
    """The gate of the ``keyframes`` config section."""
    return KeyframeGate(config.translation_m, config.rotation_rad)


def keyframe_mask(gate: KeyframeGate, poses_world_base: np.ndarray) -> np.ndarray:
    """(N,) bool: the frames of an (N, 3) base_link trajectory that the gate makes keyframes
    (the first always is), each judged against the keyframe before it, as online."""
    poses = np.asarray(poses_world_base, dtype=float).reshape(-1, 3)
    mask = np.zeros(len(poses), dtype=bool)
    last = None
    for i, pose in enumerate(poses):  # sequential by nature: one test per frame
        if last is None or gate.passes(se2_between(last, pose)):
            mask[i], last = True, pose
    return mask


@dataclass(frozen=True)
class Keyframe:
    """A new keyframe ``index``: ``delta`` (3,) base_link pose of it in keyframe ``index - 1``
    (identity for the first) with its (3, 3) tangent ``covariance``; ``stamp_s`` its frame;
    ``pose_odom_base`` (3,) where the odometry put it (its own world frame)."""

    index: int
    stamp_s: float
    delta: np.ndarray
    covariance: np.ndarray
    pose_odom_base: np.ndarray


class Keyframer:
    """Turns a sensor's odometry frames into keyframes; remembers each frame's place.

    gate: the keyframe gate. pose_base_sensor: (3,) planar mount of the sensor whose odometry
    arrives. submap_frames: recent frames whose points make a keyframe's loop-closure submap.
    """

    def __init__(self, gate: KeyframeGate, pose_base_sensor: np.ndarray, submap_frames: int):
        self._gate = gate
        self._mount = np.asarray(pose_base_sensor, dtype=float)
        self._delta = np.zeros(3)
        self._covariance = np.zeros((3, 3))
        self._recent: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=submap_frames)
        self.index = -1
        self.frame_keyframe: list[int] = []
        """Per frame so far: the keyframe it hangs from."""
        self.frame_offset: list[np.ndarray] = []
        """Per frame: (3,) its base_link pose in that keyframe's base_link."""

    def add(self, odometry: Odometry, points_base_xy: np.ndarray) -> Keyframe | None:
        """Take one odometry frame and its (N, 2) points in base_link (for submaps; may be
        empty); returns the keyframe it starts, or None."""
        pose_odom_base = se2_compose(odometry.pose_world_sensor, se2_inverse(self._mount))
        self._recent.append((pose_odom_base, np.asarray(points_base_xy, dtype=float)))
        keyframe = None
        if self.index < 0:
            keyframe = self._start(odometry.stamp_s, pose_odom_base)
        else:
            covariance = tangent_covariance(odometry.delta, odometry.covariance)
            step, step_cov = se2_conjugate(odometry.delta, covariance, self._mount)
            self._delta, self._covariance = se2_compose_with_covariance(
                self._delta, self._covariance, step, step_cov
            )
            if self._gate.passes(self._delta):
                keyframe = self._start(odometry.stamp_s, pose_odom_base)
        self.frame_keyframe.append(self.index)
        self.frame_offset.append(self._delta.copy())
        return keyframe

    def _start(self, stamp_s: float, pose_odom_base: np.ndarray) -> Keyframe:
        """Close the composed step into keyframe ``index + 1`` and start a new one."""
        self.index += 1
        keyframe = Keyframe(self.index, stamp_s, self._delta, self._covariance, pose_odom_base)
        self._delta, self._covariance = np.zeros(3), np.zeros((3, 3))
        return keyframe

    def submap(self, voxel_m: float) -> tuple[np.ndarray, np.ndarray]:
        """(points, origins), each (N, 2) in the latest frame's base_link, metres: the recent
        frames' points, and where the sensor was when it saw each; with ``voxel_m`` > 0 one
        point (the first) per square voxel of that side."""
        if not self._recent:
            return np.zeros((0, 2)), np.zeros((0, 2))
        latest = self._recent[-1][0]
        points, origins = [], []
        for pose, frame_points in self._recent:
            in_latest = se2_between(latest, pose)
            points.append(transform_points_2d(in_latest, frame_points))
            sensor = se2_compose(in_latest, self._mount)[:2]
            origins.append(np.broadcast_to(sensor, (len(frame_points), 2)))
        xy, origin_xy = np.concatenate(points), np.concatenate(origins)
        keep = first_per_voxel(xy, voxel_m)
        return xy[keep], origin_xy[keep]
