"""The fused backend: radar keyframes, camera factors and loop closures in one iSAM2 graph.

Per keyframe: a radar between factor (steps composed with their covariance, never identity),
a camera between factor once the camera has seen past the keyframe (when healthy, metric and
consistent with radar: see ``camera_factors.py``), a loop closure when the keyframe's radar
submap matches an old one (robust kernel), and one iSAM2 update.

Doppler and gyro enter only through the radar odometry's step: it already solved them jointly
with scan matching, so a separate velocity factor over the same interval would count that
information twice.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from smokyslam.backends.camera_gate import get_camera_gate
from smokyslam.backends.loop_closure import get_loop_closer
from smokyslam.backends.noise import RobustKernel
from smokyslam.backends.pose_graph import get_pose_graph
from smokyslam.backends.scale import get_scale_estimator
from smokyslam.config import SmokySlamConfig
from smokyslam.frontends.camera.odometry import CameraOdometryResult
from smokyslam.geometry import se2_compose
from smokyslam.pipelines.camera_factors import CameraFactorMaker
from smokyslam.pipelines.keyframes import RadarKeyframer
from smokyslam.pipelines.visual_map import VisualKeyframes
from smokyslam.types import Extrinsics, Odometry, RadarScan

logger = logging.getLogger(__name__)

FIRST_POSE_SIGMAS = (1e-3, 1e-3, 1e-4)
"""Prior on keyframe 0 (m, m, rad): it fixes the gauge, the map frame is the first keyframe."""

PENDING_PAIR_S = 5.0
"""Seconds a keyframe pair waits for the camera to see past it before it is given up."""


@dataclass
class SlamStatus:
    """Live health of the run, for a progress bar (``text()``)."""

    stamp_s: float = 0.0
    radar_frames: int = 0
    camera_frames: int = 0
    keyframes: int = 0
    radar_inliers: int = 0
    radar_lost: bool = False
    camera_weight: float = 0.0
    camera_tracked: int = 0
    loop_closures: int = 0

    def text(self) -> str:
        radar = "LOST" if self.radar_lost else f"{self.radar_inliers} inl"
        return (
            f"kf {self.keyframes} | radar {radar} | camera w={self.camera_weight:.2f} "
            f"{self.camera_tracked} trk | loops {self.loop_closures}"
        )


@dataclass(frozen=True)
class _Pair:
    """A keyframe pair waiting for the camera to pass its second stamp."""

    index: int
    stamp_a_s: float
    stamp_b_s: float
    radar_delta: np.ndarray
    radar_covariance: np.ndarray


class FusedSlam:
    """The graph and its feeders. Verbs: ``add_radar`` per radar frame, ``add_camera`` per
    camera frame (time order), then ``poses_world_base`` for every radar frame so far."""

    def __init__(self, config: SmokySlamConfig, extrinsics: Extrinsics) -> None:
        backend, slam = config.backend, config.slam
        self._slam = slam
        self._graph = get_pose_graph(backend)
        self._keyframer = RadarKeyframer(
            extrinsics.T_base_radar,
            backend.keyframe_translation_m,
            backend.keyframe_rotation_rad,
            slam.submap_frames,
        )
        self._loops = get_loop_closer(backend.loop_closure) if slam.loop_closures else None
        self._loop_kernel = RobustKernel(backend.loop_closure.kernel)
        self._loop_width = backend.loop_closure.kernel_width
        self._camera_kernel = RobustKernel(backend.camera_gate.kernel)
        self._camera_width = backend.camera_gate.kernel_width
        self._camera = CameraFactorMaker(
            extrinsics.T_base_camera,
            get_camera_gate(backend.camera_gate),
            get_scale_estimator(backend.scale),
            slam.camera_covariance_scale,
            slam.camera_consistency_chi2,
        )
        self.visual = VisualKeyframes(np.asarray(extrinsics.T_base_camera, dtype=float))
        self._pending: list[_Pair] = []
        self._last_keyframe: tuple[int, float] | None = None
        self.keyframe_stamps_s: list[float] = []
        self.keyframe_camera: list[bool] = []
        self.camera_weight: list[float] = []
        self.status = SlamStatus()

    @property
    def factor_counts(self) -> dict[str, int]:
        return dict(self._graph.factor_counts)

    @property
    def camera_pairs(self) -> dict[str, int]:
        return dict(self._camera.outcomes)

    def add_radar(self, odometry: Odometry, scan: RadarScan) -> None:
        """One radar odometry frame and the scan it registered (smoke already applied)."""
        self.camera_weight.append(self._camera.weight)
        self._update_status(odometry)
        keyframe = self._keyframer.add(odometry, scan)
        if keyframe is None:
            return
        self.keyframe_stamps_s.append(keyframe.stamp_s)
        self.keyframe_camera.append(False)
        if keyframe.index == 0:
            self._graph.add_prior(0, np.zeros(3), np.diag(np.square(FIRST_POSE_SIGMAS)))
        else:
            previous_index, previous_stamp_s = self._last_keyframe
            covariance = keyframe.covariance * self._slam.radar_covariance_scale
            self._graph.add_between(previous_index, keyframe.index, keyframe.delta, covariance)
            if self._slam.camera_factors:
                self._pending.append(
                    _Pair(
                        keyframe.index,
                        previous_stamp_s,
                        keyframe.stamp_s,
                        keyframe.delta,
                        covariance,
                    )
                )
                self._add_camera_factors()
        self._last_keyframe = (keyframe.index, keyframe.stamp_s)
        self._graph.optimize()
        self._close_loop(keyframe.index)
        self.status.keyframes = keyframe.index + 1

    def add_camera(self, result: CameraOdometryResult) -> None:
        """One camera odometry frame; completes the keyframe pairs it has seen past."""
        weight = self._camera.add(result)
        self.status.camera_frames += 1
        self.status.camera_weight = weight
        self.status.camera_tracked = 0 if result.lost else result.health.tracked
        scale_m = self._camera.scale_m
        if result.is_keyframe and weight > 0.0 and scale_m is not None and self._slam.visual_map:
            self.visual.add(result, scale_m)
        self._add_camera_factors()

    def poses_world_base(self) -> np.ndarray:
        """(N, 3) base_link pose of every radar frame so far: its keyframe's current estimate
        composed with the radar odometry's motion since that keyframe."""
        estimates = self._graph.estimates()
        keyframes = np.asarray(self._keyframer.frame_keyframe, dtype=int)
        offsets = np.asarray(self._keyframer.frame_offset).reshape(-1, 3)
        return se2_compose(estimates[keyframes], offsets)

    def _add_camera_factors(self) -> None:
        seen_s = self._camera.latest_stamp_s
        ready = [p for p in self._pending if p.stamp_b_s <= seen_s]
        # Pairs the camera never reached (it stopped or is silent) are given up after a while.
        expired_s = self.status.stamp_s - PENDING_PAIR_S
        waiting = [p for p in self._pending if p.stamp_b_s > seen_s]
        self._pending = [p for p in waiting if p.stamp_a_s >= expired_s]
        self._camera.outcomes["untracked"] += len(waiting) - len(self._pending)
        for pair in ready:
            factor = self._camera.factor(
                pair.stamp_a_s, pair.stamp_b_s, pair.radar_delta, pair.radar_covariance
            )
            if factor is None:
                continue
            self._graph.add_between(
                pair.index - 1,
                pair.index,
                factor.delta,
                factor.covariance,
                self._camera_kernel,
                self._camera_width,
                source="camera",
            )
            self.keyframe_camera[pair.index] = True

    def _close_loop(self, index: int) -> None:
        if self._loops is None or index % self._slam.loop_check_every:
            return
        submap = self._keyframer.submap(self._slam.submap_voxel_m)
        closure = self._loops.check(index, self._graph.estimates(), submap)
        if closure is None:
            return
        self._graph.add_between(
            closure.old_index,
            closure.new_index,
            closure.delta,
            closure.covariance * self._slam.loop_covariance_scale,
            self._loop_kernel,
            self._loop_width,
            source="loop_closure",
        )
        self._graph.optimize()
        self.status.loop_closures += 1

    def _update_status(self, odometry: Odometry) -> None:
        self.status.stamp_s = odometry.stamp_s
        self.status.radar_frames += 1
        self.status.radar_inliers = odometry.health.inliers
        self.status.radar_lost = odometry.health.lost
