"""``smokyslam simulate``: walk a smoky building and record every sensor as a ROS log.

The table of contents: build the world, plan the walk, set up the sensors, then emit every
sensor message in time order into the log writer.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import SmokySlamError
from smokyslam.rig import camera_mount, radar_mount, rig_extrinsics, sensor_poses, sensor_velocities
from smokyslam.sim.camera import CameraRenderer
from smokyslam.sim.imu import simulate_imu
from smokyslam.sim.observed import lidar_poses, observed_truth_cells
from smokyslam.sim.planner import plan_walk
from smokyslam.sim.radar import RadarModel
from smokyslam.sim.recorder import LogWriter
from smokyslam.sim.trajectory import Trajectory
from smokyslam.sim.world import World
from smokyslam.sim.worlds import build_world
from smokyslam.types import CameraFrame, GroundTruthMap, GroundTruthPose

log = logging.getLogger(__name__)

ProgressCallback = Callable[[float, float], None]
"""Called with (simulated seconds done, total seconds)."""


@dataclass
class SimulationResult:
    """What a simulation produced, with the numbers worth reporting."""

    log_path: Path
    world: World
    trajectory: Trajectory
    duration_s: float
    wall_s: float
    radar_frames: int
    camera_frames: int
    imu_samples: int
    radar_points_per_frame: float

    @property
    def realtime_factor(self) -> float:
        return self.duration_s / max(self.wall_s, 1e-9)


_NONE = np.zeros(0)


def _stamps(rate_hz: float, duration_s: float) -> np.ndarray:
    return np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)


SENSORS = ("radar", "camera", "imu")
"""The simulated sensors; ground truth (poses, maps, transforms) is always recorded."""


def parse_sensors(text: str) -> frozenset[str]:
    """``"radar,imu"`` as a set of :data:`SENSORS` (camera rendering dominates the time: a
    log without it simulates many times faster)."""
    names = frozenset(part.strip() for part in text.split(",") if part.strip())
    unknown = sorted(names - set(SENSORS))
    if unknown or not names:
        raise SmokySlamError(
            f"--sensors takes a comma-separated subset of {', '.join(SENSORS)}, got '{text}'"
        )
    return names


def simulate(
    world_name: str,
    duration_s: float,
    seed: int,
    out_path: Path | str,
    config: SmokySlamConfig,
    overwrite: bool = False,
    on_progress: ProgressCallback | None = None,
    sensors: frozenset[str] = frozenset(SENSORS),
    walk_seed: int | None = None,
) -> SimulationResult:
    """Simulate a walk through ``world_name`` for ``duration_s``; write the log to ``out_path``
    with the named ``sensors``. ``seed`` builds the world; ``walk_seed`` (default: ``seed``)
    plans the walk and seeds the sensor noise, so two walks can share one world (its
    textures included)."""
    if duration_s <= 0:
        raise SmokySlamError(f"duration must be positive, got {duration_s}")
    started = time.perf_counter()
    out_path = Path(out_path)
    log_writer = LogWriter(out_path, config.topics, overwrite=overwrite)  # checks the path now
    sim = config.simulation
    world = build_world(world_name, seed, sim)
    walk_seed = seed if walk_seed is None else walk_seed
    trajectory = plan_walk(world, duration_s, walk_seed, sim.trajectory)
    rng = np.random.default_rng(walk_seed)
    radar = RadarModel(sim.radar, world)
    camera = CameraRenderer(world, sim.camera, config.rig.camera_height_m, seed)
    imu_samples = simulate_imu(trajectory, sim.imu, rng)
    radar_stamps = _stamps(sim.radar.rate_hz, duration_s) if "radar" in sensors else _NONE
    camera_stamps = _stamps(sim.camera.rate_hz, duration_s) if "camera" in sensors else _NONE
    imu_samples = imu_samples if "imu" in sensors else []
    truth_stamps = _stamps(sim.trajectory.ground_truth_rate_hz, duration_s)
    progress_kind = 2 if "radar" in sensors else 3 if "camera" in sensors else 0

    schedule = sorted(
        [(t, 0, i) for i, t in enumerate(truth_stamps)]
        + [(s.stamp_s, 1, i) for i, s in enumerate(imu_samples)]
        + [(t, 2, i) for i, t in enumerate(radar_stamps)]
        + [(t, 3, i) for i, t in enumerate(camera_stamps)]
    )
    truth_poses = trajectory.pose_at(truth_stamps)
    radar_poses, radar_velocities = _sensor_motion(
        trajectory, radar_stamps, radar_mount(config.rig)
    )
    camera_poses = sensor_poses(trajectory.pose_at(camera_stamps), camera_mount(config.rig))
    lidar = lidar_poses(
        trajectory.pose_at(_stamps(10.0, duration_s)), sim.lidar.spacing_m, sim.lidar.turn_rad
    )

    points = 0
    with log_writer as writer:
        writer.write_tf_static(rig_extrinsics(config.rig), 0.0)
        writer.write_ground_truth_map(
            GroundTruthMap(stamp_s=0.0, cells=world.ground_truth_cells(), spec=world.spec)
        )
        writer.write_ground_truth_map(
            GroundTruthMap(0.0, observed_truth_cells(world, lidar, sim.lidar), world.spec),
            observed=True,
        )
        for stamp_s, kind, i in schedule:
            if kind == progress_kind and on_progress is not None:
                on_progress(stamp_s, duration_s)
            if kind == 0:
                writer.write_ground_truth_pose(GroundTruthPose(stamp_s, truth_poses[i]))
            elif kind == 1:
                writer.write_imu(imu_samples[i])
            elif kind == 2:
                scan = radar.measure(stamp_s, radar_poses[i], radar_velocities[i], rng)
                points += len(scan)
                writer.write_radar(scan)
            else:
                image, depth_m = camera.render(camera_poses[i])
                frame = CameraFrame(stamp_s, image, camera.intrinsics, depth_m)
                writer.write_camera(frame, depth_scale=sim.camera.depth_scale)
    wall_s = time.perf_counter() - started
    log.info("simulated %.1f s in %.1f s", duration_s, wall_s)
    return SimulationResult(
        log_path=out_path,
        world=world,
        trajectory=trajectory,
        duration_s=duration_s,
        wall_s=wall_s,
        radar_frames=len(radar_stamps),
        camera_frames=len(camera_stamps),
        imu_samples=len(imu_samples),
        radar_points_per_frame=points / max(len(radar_stamps), 1),
    )


def _sensor_motion(
    trajectory: Trajectory, stamps_s: np.ndarray, mount: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) sensor poses and (N, 2) sensor world velocities at ``stamps_s``."""
    base = trajectory.pose_at(stamps_s)
    velocity = sensor_velocities(
        base, trajectory.velocity_world_at(stamps_s), trajectory.yaw_rate_at(stamps_s), mount
    )
    return sensor_poses(base, mount), velocity
