"""Radar keyframes for the pose graph: the paper's gate, composed steps, submaps.

Radar odometry reports one step per radar frame (``Odometry.delta``, radar frame, covariance
of ``(tx, ty, yaw)`` with the translation in the previous frame). :class:`RadarKeyframer`
composes those steps until the rig has moved ``keyframe_translation_m`` or turned
``keyframe_rotation_rad`` (0.2 m or pi/8, the paper's gate), then hands out one between factor
in base_link with the covariance propagated through every composition, never identity.

Covariances here are in gtsam's Pose2 tangent ``[x, y, theta]`` (right perturbation, see
``backends/noise.py``).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from smokyslam.backends.noise import tangent_covariance
from smokyslam.geometry import (
    se2_between,
    se2_compose,
    se2_from_matrix,
    se2_inverse,
    transform_points_2d,
)
from smokyslam.mapping.build import level_scan
from smokyslam.types import Odometry, RadarScan


def se2_adjoint(pose: np.ndarray) -> np.ndarray:
    """(3, 3) adjoint of a planar pose in tangent order ``[x, y, theta]``:
    ``pose * Exp(xi) = Exp(Ad @ xi) * pose``."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.array([[c, -s, pose[1]], [s, c, -pose[0]], [0.0, 0.0, 1.0]])


def compose_with_covariance(
    delta_a: np.ndarray, cov_a: np.ndarray, delta_b: np.ndarray, cov_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``delta_a * delta_b`` and its (3, 3) tangent covariance, for independent steps.

    ``a * Exp(xi_a) * b * Exp(xi_b) = (a * b) * Exp(Ad(b^-1) xi_a + xi_b)``.
    """
    adjoint = se2_adjoint(se2_inverse(delta_b))
    return se2_compose(delta_a, delta_b), adjoint @ cov_a @ adjoint.T + cov_b


def conjugate(
    delta: np.ndarray, covariance: np.ndarray, pose_base_sensor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A sensor-frame relative pose and tangent covariance expressed in base_link.

    ``D_base = M * D_sensor * M^-1`` with the mount ``M = pose_base_sensor``; a right
    perturbation ``xi`` of ``D_sensor`` becomes ``Ad(M) xi`` of ``D_base``.
    """
    adjoint = se2_adjoint(pose_base_sensor)
    moved = se2_compose(se2_compose(pose_base_sensor, delta), se2_inverse(pose_base_sensor))
    return moved, adjoint @ covariance @ adjoint.T


@dataclass(frozen=True)
class RadarKeyframe:
    """A new keyframe ``index``: ``delta`` (3,) base_link pose of it in keyframe ``index - 1``
    (identity for the first) with its (3, 3) tangent ``covariance``; ``stamp_s`` its radar
    frame; ``pose_odom_base`` (3,) where radar odometry put it (its own world frame)."""

    index: int
    stamp_s: float
    delta: np.ndarray
    covariance: np.ndarray
    pose_odom_base: np.ndarray


class RadarKeyframer:
    """Turns radar odometry frames into keyframes; remembers each frame's place for outputs.

    ``T_base_radar``: (4, 4) mount. ``submap_frames``: radar frames whose points make a
    keyframe's loop-closure submap.
    """

    def __init__(
        self,
        T_base_radar: np.ndarray,
        translation_m: float = 0.2,
        rotation_rad: float = np.pi / 8,
        submap_frames: int = 12,
    ) -> None:
        self._T_base_radar = np.asarray(T_base_radar, dtype=float)
        self._mount = se2_from_matrix(self._T_base_radar)
        self._translation_m = translation_m
        self._rotation_rad = rotation_rad
        self._delta = np.zeros(3)
        self._covariance = np.zeros((3, 3))
        self._recent: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=submap_frames)
        self.index = -1
        self.frame_keyframe: list[int] = []
        """Per radar frame so far: the keyframe it hangs from."""
        self.frame_offset: list[np.ndarray] = []
        """Per radar frame: (3,) its base_link pose in that keyframe's base_link."""

    def add(self, odometry: Odometry, scan: RadarScan) -> RadarKeyframe | None:
        """Take one radar odometry frame (and the scan it registered); a keyframe or None."""
        pose_odom_base = se2_compose(odometry.pose_world_sensor, se2_inverse(self._mount))
        levelled, pose_base_radar = level_scan(scan, self._T_base_radar)
        points_base = transform_points_2d(pose_base_radar, levelled.points_xyz_m[:, :2])
        self._recent.append((pose_odom_base, points_base))
        keyframe = None
        if self.index < 0:
            keyframe = self._start(odometry.stamp_s, pose_odom_base)
        else:
            covariance = tangent_covariance(odometry.delta, odometry.covariance)
            step, step_cov = conjugate(odometry.delta, covariance, self._mount)
            self._delta, self._covariance = compose_with_covariance(
                self._delta, self._covariance, step, step_cov
            )
            moved = np.abs(self._delta[:2]).max() >= self._translation_m
            if moved or abs(self._delta[2]) >= self._rotation_rad:
                keyframe = self._start(odometry.stamp_s, pose_odom_base)
        self.frame_keyframe.append(self.index)
        self.frame_offset.append(self._delta.copy())
        return keyframe

    def _start(self, stamp_s: float, pose_odom_base: np.ndarray) -> RadarKeyframe:
        """Close the composed step into keyframe ``index + 1`` and start a new one."""
        self.index += 1
        keyframe = RadarKeyframe(self.index, stamp_s, self._delta, self._covariance, pose_odom_base)
        self._delta, self._covariance = np.zeros(3), np.zeros((3, 3))
        return keyframe

    def submap(self, voxel_m: float = 0.0) -> np.ndarray:
        """(N, 2) points of the recent radar frames in the latest frame's base_link, metres;
        with ``voxel_m`` > 0 one point (the first) per square voxel of that side."""
        if not self._recent:
            return np.zeros((0, 2))
        latest = self._recent[-1][0]
        parts = [
            transform_points_2d(se2_between(latest, pose), points) for pose, points in self._recent
        ]
        points = np.concatenate(parts)
        if voxel_m <= 0.0 or len(points) == 0:
            return points
        cells = np.floor(points / voxel_m).astype(np.int64)
        _, first = np.unique(cells, axis=0, return_index=True)
        return points[np.sort(first)]
