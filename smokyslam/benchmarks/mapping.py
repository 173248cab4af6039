"""Mapping benchmarks: ray-casting speed against a per-ray Python Bresenham, and how much
faster than real time a radar map is built. Each function returns plain numbers for bench.json.

The scans come from a small synthetic stream (:func:`synthetic_radar_frames`): a sensor
walking loops in a box room, ~40 noisy returns per scan at 10 Hz, ground-truth poses at 50 Hz.
"""

from __future__ import annotations

import math
import resource
import time
import tracemalloc
from collections.abc import Callable

import numpy as np

from smokyslam.backends.keyframes import get_keyframe_gate
from smokyslam.config import KeyframeConfig, MappingConfig
from smokyslam.evaluation.map_metrics import evaluate_map
from smokyslam.geometry import transform_points_2d
from smokyslam.mapping.build import build_radar_map
from smokyslam.mapping.raycast import naive_raycast, raycast
from smokyslam.sim.raycast2d import cast_rays
from smokyslam.sim.world import World, box_world
from smokyslam.types import Extrinsics, GroundTruthTrajectory, RadarScan


def first_hit_ranges(
    world: World, pose_world_sensor: np.ndarray, azimuths_rad: np.ndarray, max_range_m: float
) -> np.ndarray:
    """(B,) range to the first occupied cell along each beam (inf if none within range), from
    the sensor at ``pose_world_sensor`` [x, y, yaw]; ``azimuths_rad`` (B,) in the sensor frame.

    The simulator's exact grid ray caster finds where each beam enters the wall cell; the range
    goes a quarter cell further, so the return lies inside that cell rather than on its edge.
    """
    angles = pose_world_sensor[2] + np.asarray(azimuths_rad, dtype=float)
    directions = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    hits = cast_rays(world, pose_world_sensor[:2], directions, max_range_m)
    return hits.distance_m + world.spec.resolution_m / 4.0


def loop_pose(world: World, stamp_s: float, period_s: float = 30.0) -> np.ndarray:
    """[x, y, yaw] on an ellipse around the room centre, heading along the path."""
    x0, x1, y0, y1 = world.spec.extent_m
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    ax, ay = 0.3 * (x1 - x0), 0.3 * (y1 - y0)
    phase = 2.0 * math.pi * stamp_s / period_s
    heading = math.atan2(ay * math.cos(phase), -ax * math.sin(phase))
    return np.array([cx + ax * math.cos(phase), cy + ay * math.sin(phase), heading])


def synthetic_radar_frames(
    world: World,
    duration_s: float = 60.0,
    rate_hz: float = 10.0,
    points_per_scan: int = 40,
    pose_rate_hz: float = 50.0,
    half_fov_rad: float = math.radians(60.0),
    max_range_m: float = 10.0,
    range_sigma_m: float = 0.03,
    azimuth_sigma_rad: float = math.radians(3.0),
    seed: int = 0,
) -> tuple[list[RadarScan], GroundTruthTrajectory]:
    """Time-ordered radar scans of a sensor looping in ``world``, and its ground truth.

    The radar is mounted at base_link (identity extrinsics). Each scan has up to
    ``points_per_scan`` returns at random azimuths, with Gaussian range and azimuth noise.
    """
    rng = np.random.default_rng(seed)
    truth_stamps = np.arange(0.0, duration_s + 1e-9, 1.0 / pose_rate_hz)
    truth = GroundTruthTrajectory(
        truth_stamps, np.array([loop_pose(world, float(t)) for t in truth_stamps])
    )
    frames: list[RadarScan] = []
    for t in np.arange(0.5 / rate_hz, duration_s, 1.0 / rate_hz):
        pose = loop_pose(world, float(t))
        azimuths = rng.uniform(-half_fov_rad, half_fov_rad, points_per_scan)
        ranges = first_hit_ranges(world, pose, azimuths, max_range_m)
        hit = np.isfinite(ranges)
        measured_range = ranges[hit] + rng.normal(0.0, range_sigma_m, hit.sum())
        measured_azimuth = azimuths[hit] + rng.normal(0.0, azimuth_sigma_rad, hit.sum())
        xy = measured_range[:, None] * np.stack(
            [np.cos(measured_azimuth), np.sin(measured_azimuth)], axis=1
        )
        points = np.column_stack([xy, np.zeros(len(xy))])
        n = len(points)
        frames.append(RadarScan(float(t), points, np.full(n, 20.0), np.zeros(n)))
    return frames, truth


def _best_of(repeats: int, function: Callable[[], object]) -> float:
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def raycast_speedup_vs_naive(repeats: int = 3, seed: int = 0) -> dict[str, float]:
    """Cells per second of :func:`raycast` over :func:`naive_raycast` on the same scans.

    The scans are the 600 radar scans of the 60 s synthetic stream, in world cells at 0.1 m.
    ``raycast_speedup_vs_naive``: every scan's rays cast in one call (as a rebuild or the
    flattening does); ``raycast_speedup_per_scan``: one call per scan (as live mapping does).
    Best of ``repeats`` runs each, the two casters interleaved so machine load hits both.
    """
    world = box_world(12.0, 9.0)
    scans, truth = synthetic_radar_frames(world, seed=seed)
    stamps = truth.stamps_s
    origins, ends = [], []
    for scan in scans:
        pose = truth.poses_world_base[np.argmin(np.abs(stamps - scan.stamp_s))]
        cells = np.floor(transform_points_2d(pose, scan.points_xy_m) / 0.1).astype(np.int64)
        origins.append(np.broadcast_to(np.floor(pose[:2] / 0.1).astype(np.int64), cells.shape))
        ends.append(cells)
    all_origins, all_ends = np.concatenate(origins), np.concatenate(ends)
    n_cells = len(raycast(all_origins, all_ends)[0])

    def per_scan() -> None:
        for o, e in zip(origins, ends, strict=True):
            raycast(o, e)

    naive_s = batched_s = per_scan_s = math.inf
    for _ in range(repeats):
        naive_s = min(naive_s, _best_of(1, lambda: naive_raycast(all_origins, all_ends)))
        batched_s = min(batched_s, _best_of(3, lambda: raycast(all_origins, all_ends)))
        per_scan_s = min(per_scan_s, _best_of(1, per_scan))
    return {
        "raycast_speedup_vs_naive": naive_s / batched_s,
        "raycast_speedup_per_scan": naive_s / per_scan_s,
        "raycast_cells_per_s": n_cells / batched_s,
        "naive_raycast_cells_per_s": n_cells / naive_s,
        "raycast_benchmark_cells": float(n_cells),
    }


def map_realtime_factor(
    duration_s: float = 60.0, repeats: int = 3, seed: int = 0
) -> dict[str, float]:
    """Log seconds per wall second to build the radar map of a synthetic stream.

    ``map_realtime_factor``: best of ``repeats`` timed builds (default config, frames already
    decoded in memory). ``map_peak_traced_mb``: peak Python/numpy allocation during one build
    (tracemalloc); ``process_peak_rss_mb``: the process's peak resident memory so far.
    ``map_error_index``: the built map against the room's ground truth.
    """
    world = box_world(12.0, 9.0)
    scans, truth = synthetic_radar_frames(world, duration_s=duration_s, seed=seed)
    config, gate = MappingConfig(), get_keyframe_gate(KeyframeConfig())

    def build():
        return build_radar_map(scans, truth, Extrinsics(), config, gate)

    build_s = _best_of(repeats, build)
    tracemalloc.start()
    grid = build()
    _, peak_bytes = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    metrics = evaluate_map(grid.to_cells(), grid.spec, world.ground_truth_cells(), world.spec)
    return {
        "map_realtime_factor": duration_s / build_s,
        "map_build_s": build_s,
        "map_peak_traced_mb": peak_bytes / 2**20,
        "process_peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "map_error_index": metrics["error_index"],
    }


def run_mapping_benchmarks() -> dict[str, float]:
    """Every mapping number for ``smokyslam bench``."""
    return {**raycast_speedup_vs_naive(), **map_realtime_factor()}
