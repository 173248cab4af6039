"""What a Dask worker does for a sweep: simulate a world, or run one (log, level, source,
config). Both are plain functions of picklable arguments, importable on any worker."""

from __future__ import annotations

from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.compare_table import CompareRow
from smokyslam.pipelines.jobs import CompareJob, run_job
from smokyslam.sweep.spec import World


def simulate_world(world: World, log_path: Path, config: SmokySlamConfig) -> Path:
    """Simulate ``world`` into ``log_path``; the log appears whole or not at all (a killed
    simulation leaves only its ``.partial`` file, simulated again on a restart)."""
    from smokyslam.sim.simulate import simulate

    log_path.parent.mkdir(parents=True, exist_ok=True)
    partial = log_path.with_name(f"{log_path.stem}.partial{log_path.suffix}")
    simulate(
        world.simulate,
        world.duration_s,
        world.seed,
        partial,
        config,
        overwrite=True,
        sensors=frozenset(world.sensors),
    )
    partial.replace(log_path)
    return log_path


def run_one(job: CompareJob, log_ready: Path | None = None) -> CompareRow:
    """One run, its failure a row (``log_ready``: the simulation it waits for, if any)."""
    return run_job(job)
