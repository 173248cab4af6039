"""``smokyslam bench``: the project's speed and memory numbers, one JSON object.

Targets (checked by people reading bench.json, not by timed tests): ray casting >= 50x a
per-ray Python Bresenham; radar map >= 20x real time; camera rendering >= 50 frames/s; radar
odometry >= 300 frames/s and camera odometry >= 150 frames/s (estimator time only, 320x240);
the fused pipeline >= 10x real time (whole run: reading, smoke, estimation, outputs);
up-sampling a 512x512 map with the shipped GAN <= 0.5 s on the CPU.
Peak memory is the process's peak RSS over everything above.
"""

from __future__ import annotations

import resource
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from smokyslam.benchmarks.mapping import map_realtime_factor, raycast_speedup_vs_naive
from smokyslam.config import SmokySlamConfig
from smokyslam.pipelines.run import run_log
from smokyslam.pipelines.truth_mapping import run_truth_mapping
from smokyslam.rig import camera_mount, sensor_poses
from smokyslam.sim.camera import CameraRenderer
from smokyslam.sim.simulate import SimulationResult, simulate

BENCH_WORLD, BENCH_SEED, BENCH_DURATION_S = "office", 7, 60.0


def render_fps(sim: SimulationResult, config: SmokySlamConfig, frames: int = 200) -> float:
    """Camera frames rendered per second along the simulated walk (one core, 320x240)."""
    renderer = CameraRenderer(sim.world, config.simulation.camera, config.rig.camera_height_m, 0)
    stamps = np.linspace(0.0, sim.duration_s, frames)
    poses = sensor_poses(sim.trajectory.pose_at(stamps), camera_mount(config.rig))
    started = time.perf_counter()
    for pose in poses:
        renderer.render(pose)
    return frames / (time.perf_counter() - started)


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_benchmarks(
    workdir: Path, config: SmokySlamConfig, on_step: Callable[[str], None] | None = None
) -> dict[str, float]:
    """Run every benchmark; logs and run folders go under ``workdir``."""
    step = on_step or (lambda _name: None)
    results: dict[str, float] = {}
    step("ray casting vs naive Bresenham")
    results.update(raycast_speedup_vs_naive())
    step(f"simulating {BENCH_DURATION_S:.0f} s of {BENCH_WORLD}")
    log_path = workdir / "bench_office60.mcap"
    sim = simulate(BENCH_WORLD, BENCH_DURATION_S, BENCH_SEED, log_path, config, overwrite=True)
    results["simulate_60s_wall_s"] = sim.wall_s
    results["simulation_realtime_factor"] = sim.realtime_factor
    results["radar_points_per_frame"] = sim.radar_points_per_frame
    step("camera rendering")
    results["render_fps"] = render_fps(sim, config)
    step("radar map on ground-truth poses")
    in_memory = map_realtime_factor()
    results["map_realtime_factor_in_memory"] = in_memory["map_realtime_factor"]
    started = time.perf_counter()
    run_truth_mapping(log_path, config, workdir / "bench_map")
    results["map_realtime_factor"] = BENCH_DURATION_S / (time.perf_counter() - started)
    for source in ("radar", "camera", "fused"):
        step(f"{source} run on the {BENCH_DURATION_S:.0f} s log")
        run = run_log(log_path, source, config, workdir / f"bench_{source}")
        if source == "fused":
            results["pipeline_realtime_factor"] = run.metrics["realtime_factor"]
        else:
            results[f"{source}_odometry_fps"] = run.estimate.frames_per_s
    step("up-sampling a 512x512 map")
    results["upsample_512_s"] = upsample_seconds(run.out_dir / "maps/radar_sparse.yaml", config)
    step("parsing TI mmWave UART frames")
    results["ti_parse_frames_per_s"] = ti_parse_frames_per_s()
    step("localizing with 2000 particles")
    results["localize_realtime_factor"] = localize_realtime_factor()
    results["peak_rss_mb"] = peak_rss_mb()
    return results


def upsample_seconds(map_yaml: Path, config: SmokySlamConfig, side: int = 512) -> float:
    """Best of three: the shipped GAN on a ``side`` x ``side`` map (the run's sparse map,
    cropped or padded with unknown cells to that size), the whole pass included. The dense
    map keeps that grid (``extend_cells`` off), so the pass covers all of it."""
    from smokyslam.geometry import GridSpec
    from smokyslam.mapio import UNKNOWN, load_map
    from smokyslam.upsample.infer import get_upsampler, upsample

    sparse = load_map(map_yaml)
    cells = np.full((side, side), UNKNOWN, dtype=np.int8)
    rows, cols = min(side, sparse.cells.shape[0]), min(side, sparse.cells.shape[1])
    cells[:rows, :cols] = sparse.cells[:rows, :cols]
    spec = GridSpec(sparse.spec.origin_xy_m, sparse.spec.resolution_m, (side, side))
    upsampler = get_upsampler(config.upsample.model_copy(update={"extend_cells": None}), "gan")
    upsample(upsampler, cells, spec)  # warm up
    times = []
    for _ in range(3):
        started = time.perf_counter()
        upsample(upsampler, cells, spec)
        times.append(time.perf_counter() - started)
    return min(times)


def ti_parse_frames_per_s(frames: int = 5000, points: int = 40) -> float:
    """Frames per second the TI UART parser decodes (``points`` detections each, fed in 4 kB
    reads as from a serial port), best of three."""
    from smokyslam.frontends.sensors.ti_encode import encode_sdk1_frame
    from smokyslam.frontends.sensors.ti_frames import TiFrameParser

    rng = np.random.default_rng(0)
    xyz = rng.uniform([-3, 0.5, -0.5], [3, 8, 0.5], (points, 3))
    doppler, peak = rng.integers(-8, 8, points), rng.integers(100, 5000, points)
    stream = b"".join(encode_sdk1_frame(i, xyz, doppler, peak) for i in range(frames))
    best = np.inf
    for _ in range(3):
        parser = TiFrameParser(0.1)
        started = time.perf_counter()
        for offset in range(0, len(stream), 4096):
            parser.feed(stream[offset : offset + 4096])
        best = min(best, time.perf_counter() - started)
    return frames / best


def localize_realtime_factor(
    frames: int = 100, particles: int = 2000, rate_hz: float = 10.0
) -> float:
    """Real-time factor of the localizer's filter (predict + update + resample) with a fixed
    ``particles`` count and 40 radar points a frame, on a 20 x 20 m map, at ``rate_hz``."""
    from smokyslam.config import LocalizeConfig
    from smokyslam.geometry import GridSpec
    from smokyslam.localize.likelihood import LikelihoodField
    from smokyslam.localize.mcl import MonteCarloLocalizer

    cells = np.zeros((200, 200), dtype=np.int8)
    cells[[0, -1], :] = cells[:, [0, -1]] = cells[100, 50:150] = 100
    settings = LocalizeConfig(min_particles=particles, max_particles=particles)
    field = LikelihoodField(cells, GridSpec((0.0, 0.0), 0.1, cells.shape), settings)
    mcl = MonteCarloLocalizer(field, settings)
    mcl.start_tracking(np.array([5.0, 5.0, 0.0]), np.array([0.5, 0.5, 0.2]))
    rng = np.random.default_rng(0)
    points = rng.uniform([-4.0, -4.0], [4.0, 4.0], (40, 2))
    step, cov = np.array([0.1, 0.0, 0.01]), np.diag([0.02, 0.02, 0.01]) ** 2
    started = time.perf_counter()
    for _ in range(frames):
        mcl.predict(step, cov)
        mcl.update(points)
    return frames / rate_hz / (time.perf_counter() - started)
