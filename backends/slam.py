"""The backend every source runs: keyframes, their factors and loop closures in one iSAM2 graph.

One primary odometry (radar, dead reckoning, or the camera for camera-only runs) carries the
trajectory: its frames go through the keyframe gate, and each keyframe becomes a pose with a
between factor (steps composed with their covariance, never identity). Switched on per source:

- camera factors: a camera between factor for a radar keyframe pair once the camera has seen
  past it (when healthy, metric and consistent with radar: ``camera_factors.py``);
- loop closures: the keyframe's radar submap matched against old ones (robust kernel);
- gyro factors: the gyro's turn over each keyframe pair, less a bias the graph estimates,
  held to the radar odometry's running estimate (``gyro.py``; ``slam.gyro_factors``).

One iSAM2 update per keyframe. With none switched on the graph is a chain and reproduces
the odometry exactly. Doppler enters only through the radar odometry's step: it already
solved it jointly with scan matching, so a separate velocity factor over the same interval
would count that information twice. The gyro is in the radar step too, as the prior of each
frame's match with the bias estimated so far; the gyro factors give the graph its turns again
with the bias left to hindsight.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from smokyslam.backends.camera_factors import CameraFactorMaker, get_camera_factor_maker
from smokyslam.backends.gyro import GyroTurns
from smokyslam.backends.keyframes import Keyframe, Keyframer, get_keyframe_gate
from smokyslam.backends.loop_closure import OUTCOMES as LOOP_OUTCOMES
from smokyslam.backends.loop_closure import get_loop_closer
from smokyslam.backends.noise import RobustKernel
from smokyslam.backends.pose_graph import get_pose_graph
from smokyslam.backends.scale import ScaleEstimator
from smokyslam.config import SmokySlamConfig
from smokyslam.frontends.camera.odometry import CameraOdometryResult
from smokyslam.geometry import se2_between, se2_compose
from smokyslam.types import ImuSample, Odometry, StepPairs

logger = logging.getLogger(__name__)

FIRST_POSE_SIGMAS = (1e-3, 1e-3, 1e-4)
"""Prior on keyframe 0 (m, m, rad): it fixes the gauge, the map frame is the first keyframe."""

PENDING_PAIR_S = 5.0
"""Seconds a keyframe pair waits for the camera to see past it before it is given up."""


@dataclass(frozen=True)
class Primary:
    """The odometry that carries the trajectory: ``name`` (the factor source, "radar" or
    "camera"), ``pose_base_sensor`` (3,) its planar mount, ``covariance_scale`` a variance
    multiplier on its keyframe steps."""

    name: str
    pose_base_sensor: np.ndarray
    covariance_scale: float


@dataclass
class SlamStatus:
    """Live health of the run, for a progress bar (``text()``)."""

    stamp_s: float = 0.0
    frames: int = 0
    keyframes: int = 0
    inliers: int = 0
    lost: bool = False
    camera_frames: int = 0
    camera_weight: float = 0.0
    camera_tracked: int = 0
    loop_closures: int = 0

    def text(self) -> str:
        odometry = "LOST" if self.lost else f"{self.inliers} inl"
        text = f"kf {self.keyframes} | odometry {odometry}"
        if self.camera_frames:
            text += f" | camera w={self.camera_weight:.2f} {self.camera_tracked} trk"
        return text + f" | loops {self.loop_closures}"


@dataclass(frozen=True)
class _Pair:
    """A keyframe pair waiting for the camera to pass its second stamp."""

    index: int
    stamp_a_s: float
    stamp_b_s: float
    delta: np.ndarray
    covariance: np.ndarray


class SlamBackend:
    """The pose graph and its feeders. Verbs: ``add_odometry`` per primary frame,
    ``add_camera`` per camera frame, ``add_imu`` per IMU sample (time order, the IMU ahead of
    the frames it spans); ``poses_world_base`` for every primary frame so far,
    ``keyframe_poses`` for every keyframe."""

    def __init__(
        self,
        config: SmokySlamConfig,
        primary: Primary,
        T_base_camera: np.ndarray | None,
        loop_closures: bool,
        gyro_factors: bool = False,
    ) -> None:
        """``T_base_camera``: (4, 4) camera mount for camera factors, None for none.
        ``gyro_factors``: the gyro's turns join the graph (``add_imu`` feeds them)."""
        backend, slam = config.backend, config.slam
        self._slam = slam
        self._primary = primary
        self._graph = get_pose_graph(backend)
        self._keyframer = Keyframer(
            get_keyframe_gate(config.keyframes), primary.pose_base_sensor, slam.submap_frames
        )
        self._loops = (
            get_loop_closer(backend.loop_closure, slam.submap_voxel_m) if loop_closures else None
        )
        self._loop_kernel = RobustKernel(backend.loop_closure.kernel)
        self._loop_width = backend.loop_closure.kernel_width
        self._camera_kernel = RobustKernel(backend.camera_gate.kernel)
        self._camera_width = backend.camera_gate.kernel_width
        self._camera: CameraFactorMaker | None = None
        if T_base_camera is not None:
            self._camera = get_camera_factor_maker(backend, slam, T_base_camera)
        self._gyro = GyroTurns() if gyro_factors else None
        self._pending: list[_Pair] = []
        self._last_keyframe: tuple[int, float] | None = None
        self.frame_stamps_s: list[float] = []
        """Per primary frame: its stamp."""
        self.frame_lost: list[bool] = []
        """Per primary frame: its odometry could not measure it."""
        self.keyframe_stamps_s: list[float] = []
        self.keyframe_camera: list[bool] = []
        """Per keyframe: a camera factor ends there."""
        self.camera_weight: list[float] = []
        """Per primary frame: gate weight of the latest camera frame."""
        self.loop_edges: list[tuple[int, int]] = []
        """(old, new) keyframe indices of every loop closure, in the order they were made."""
        self.status = SlamStatus()

    # ------------------------------------------------------------------ numbers

    @property
    def factor_counts(self) -> dict[str, int]:
        return dict(self._graph.factor_counts)

    @property
    def gyro_bias_radps(self) -> float | None:
        """The graph's gyro bias at the latest keyframe (rad/s), None without gyro factors."""
        n = len(self.keyframe_stamps_s)
        return self._graph.gyro_bias(n - 1) if self._gyro is not None and n else None

    @property
    def camera_pairs(self) -> dict[str, int]:
        """Keyframe pairs by camera outcome (used, untracked, gated, no_scale, inconsistent)."""
        return dict(self._camera.outcomes) if self._camera is not None else {}

    @property
    def loop_searches(self) -> dict[str, int]:
        """Loop-closure searches and candidates by outcome (every key of
        :data:`~smokyslam.backends.loop_closure.OUTCOMES`; empty without loop closures)."""
        if self._loops is None:
            return {}
        return {key: self._loops.outcomes[key] for key in LOOP_OUTCOMES}

    @property
    def step_pairs(self) -> StepPairs | None:
        """The radar and camera steps of the keyframe pairs (None without camera factors)."""
        return self._camera.steps if self._camera is not None else None

    @property
    def camera_scale(self) -> ScaleEstimator | None:
        """The camera factors' windowed metric scale (None without camera factors)."""
        return self._camera.scale if self._camera is not None else None

    @property
    def camera_scale_m(self) -> float | None:
        """Metres per camera unit of the camera factors' current scale (None until known)."""
        return self._camera.scale_m if self._camera is not None else None

    # ------------------------------------------------------------------ verbs

    def add_odometry(self, odometry: Odometry, points_base_xy: np.ndarray) -> Keyframe | None:
        """One primary odometry frame and its (N, 2) points in base_link (loop-closure
        submaps; empty for the camera). Returns the keyframe it made, or None."""
        self.frame_stamps_s.append(odometry.stamp_s)
        self.frame_lost.append(odometry.health.lost)
        self.camera_weight.append(self._camera.weight if self._camera is not None else 0.0)
        self._update_status(odometry)
        keyframe = self._keyframer.add(odometry, points_base_xy)
        if keyframe is None:
            return None
        self.keyframe_stamps_s.append(keyframe.stamp_s)
        self.keyframe_camera.append(False)
        if keyframe.index == 0:
            self._graph.add_prior(0, np.zeros(3), np.diag(np.square(FIRST_POSE_SIGMAS)))
        else:
            previous_index, previous_stamp_s = self._last_keyframe
            covariance = keyframe.covariance * self._primary.covariance_scale
            self._graph.add_between(
                previous_index,
                keyframe.index,
                keyframe.delta,
                covariance,
                source=self._primary.name,
            )
            if self._gyro is not None:
                self._add_gyro_turn(
                    previous_index, keyframe.index, previous_stamp_s, keyframe.stamp_s
                )
                self._hold_gyro_bias(odometry)
            if self._camera is not None:
                pair = _Pair(
                    keyframe.index, previous_stamp_s, keyframe.stamp_s, keyframe.delta, covariance
                )
                self._pending.append(pair)
                self._add_camera_factors()
        self._last_keyframe = (keyframe.index, keyframe.stamp_s)
        self._graph.optimize()
        self._close_loop(keyframe.index)
        self.status.keyframes = keyframe.index + 1
        return keyframe

    def add_imu(self, sample: ImuSample) -> None:
        """One IMU sample; its gyro feeds the gyro factors (nothing without them)."""
        if self._gyro is not None:
            self._gyro.add(sample)

    def add_camera(self, result: CameraOdometryResult) -> float:
        """One camera odometry frame; completes the keyframe pairs it has seen past. Returns
        the frame's gate weight (0 without camera factors)."""
        if self._camera is None:
            return 0.0
        weight = self._camera.add(result)
        self.status.camera_frames += 1
        self.status.camera_weight = weight
        self.status.camera_tracked = 0 if result.lost else result.health.tracked
        self._add_camera_factors()
        return weight

    # ------------------------------------------------------------------ estimates

    def keyframe_poses(self) -> np.ndarray:
        """(K, 3) current base_link estimate of every keyframe, map frame."""
        return self._graph.estimates()

    def keyframe_pose(self, index: int) -> np.ndarray:
        """(3,) current base_link estimate of keyframe ``index``."""
        return self._graph.estimate(index)

    def latest_pose(self) -> np.ndarray:
        """(3,) current base_link estimate of the newest primary frame (origin before any)."""
        if not self._keyframer.frame_keyframe:
            return np.zeros(3)
        keyframe = self._graph.estimate(self._keyframer.frame_keyframe[-1])
        return se2_compose(keyframe, self._keyframer.frame_offset[-1])

    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """(N,) stamps and (N, 3) base_link poses of every primary frame so far."""
        poses = self.poses_world_base()
        return np.asarray(self.frame_stamps_s[: len(poses)], dtype=float), poses

    def poses_world_base(self) -> np.ndarray:
        """(N, 3) base_link pose of every primary frame so far: its keyframe's current
        estimate composed with the odometry's motion since that keyframe. (A run stopped in
        the middle of a frame gives the frames whose keyframe the graph already holds.)"""
        estimates = self._graph.estimates()
        keyframes = np.asarray(self._keyframer.frame_keyframe[: self._complete()], dtype=int)
        offsets = np.asarray(self._keyframer.frame_offset[: len(keyframes)]).reshape(-1, 3)
        return se2_compose(estimates[keyframes], offsets).reshape(-1, 3)

    def _complete(self) -> int:
        """Frames whose every record (stamp, place, keyframe estimate) exists."""
        keyframes = np.asarray(self._keyframer.frame_keyframe, dtype=int)
        known = len(self._graph.estimates())
        n = min(len(self.frame_stamps_s), len(keyframes), len(self._keyframer.frame_offset))
        missing = np.flatnonzero(keyframes[:n] >= known)
        return int(missing[0]) if len(missing) else n

    # ------------------------------------------------------------------ policies

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
                pair.stamp_a_s, pair.stamp_b_s, pair.delta, pair.covariance
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
            self._add_long_turn(pair.index, pair.stamp_b_s)

    def _add_long_turn(self, index: int, stamp_s: float) -> None:
        """The camera's turn since its last long-turn keyframe (``slam.camera_long_turn_s``),
        its translation the graph's current one, left free."""
        turn = self._camera.long_turn(index, stamp_s)
        if turn is None:
            return
        step = se2_between(self._graph.estimate(turn.old_index), self._graph.estimate(index))
        delta = np.array([step[0], step[1], turn.yaw_rad])
        self._graph.add_between(
            turn.old_index,
            index,
            delta,
            turn.covariance,
            self._camera_kernel,
            self._camera_width,
            source="camera_long_turn",
        )

    def _add_gyro_turn(self, i: int, j: int, start_s: float, end_s: float) -> None:
        slam = self._slam
        self._graph.add_gyro_turn(
            i,
            j,
            self._gyro.turn(start_s, end_s),
            end_s - start_s,
            np.radians(slam.gyro_turn_sigma_deg),
            np.radians(slam.gyro_bias_walk_degps),
            np.radians(slam.gyro_bias_sigma_degps),
            slam.gyro_bias_span_s,
        )

    def _hold_gyro_bias(self, odometry: Odometry) -> None:
        """The radar odometry's running bias estimate, where it makes one, as a prior on the
        graph's (``slam.gyro_bias_prior``), its sigma at least ``gyro_bias_prior_floor_degps``:
        the estimate's own sigma ignores the radar heading's drift, which biases it."""
        extra = odometry.health.extra
        if self._slam.gyro_bias_prior and "gyro_bias_radps" in extra:
            sigma = max(
                extra["gyro_bias_sigma_radps"] * self._slam.gyro_bias_prior_scale,
                np.radians(self._slam.gyro_bias_prior_floor_degps),
            )
            self._graph.hold_gyro_bias(extra["gyro_bias_radps"], sigma)

    def _close_loop(self, index: int) -> None:
        if self._loops is None or index % self._slam.loop_check_every:
            return
        submap_xy, origins_xy = self._keyframer.submap(self._slam.submap_voxel_m)
        closure = self._loops.check(index, self._graph.estimates(), submap_xy, origins_xy)
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
        self.loop_edges.append((closure.old_index, closure.new_index))
        self.status.loop_closures += 1

    def _update_status(self, odometry: Odometry) -> None:
        self.status.stamp_s = odometry.stamp_s
        self.status.frames += 1
        self.status.inliers = odometry.health.inliers
        self.status.lost = odometry.health.lost
