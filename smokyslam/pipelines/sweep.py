"""``smokyslam sweep``: every (world, smoke level, source, config) run as a task on Dask.

The table of contents of :func:`sweep`: load and check the sweep file; plan the runs
(``DIR/runs/<world>/<config>/<source>-<level>/``, logs simulated into ``DIR/logs/``); leave
out the runs already finished (a complete ``metrics.json``); on the cluster, one task per
world to simulate and one per run depending on it; gather the rows as they finish (a failed
or killed run is a row with its error); write ``sweep.csv``, ``summary.md`` and the plots.
Ctrl-C sets the sweep's stop flag (running runs keep what they computed, queued ones and
simulations do not start), closes the cluster and writes the rows so far.

A sweep's runs track the camera and up-sample in their own process (``slam.camera_process`` and
``upsample.worker_process`` off): a worker is a core, and the results do not depend on it.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig, write_config
from smokyslam.errors import RunInterruptedError, SmokySlamError
from smokyslam.evaluation.compare_table import CompareRow, RunStatus
from smokyslam.pipelines.executor import dask_client, new_stop_name, wind_down
from smokyslam.pipelines.jobs import STOP_WAIT_S, CompareJob, cut_off_row, written_metrics
from smokyslam.sweep.plots import plot_ate_by_source, plot_fused_vs_best
from smokyslam.sweep.results import SweepRow, write_csv, write_summary
from smokyslam.sweep.spec import Sweep, World, load_sweep
from smokyslam.sweep.tasks import run_one, simulate_world

logger = logging.getLogger(__name__)

ProgressCallback = Callable[..., None]


@dataclass(frozen=True)
class SweepJob:
    """One planned run: its world, its config's name, and the compare job that runs it."""

    world: World
    config: str
    job: CompareJob


@dataclass
class SweepResult:
    rows: list[SweepRow]
    out_dir: Path
    skipped: int
    """Runs already finished in ``out_dir`` before this sweep started."""
    wall_s: float

    @property
    def failed(self) -> list[SweepRow]:
        return [row for row in self.rows if not row.row.ok]


def plan(spec: Sweep, out_dir: Path) -> list[SweepJob]:
    """Every run of the sweep, world by world, config by config, level by level."""
    jobs = []
    for world in spec.worlds:
        for name, config in spec.configs.items():
            inline = config.model_copy(
                update={
                    "slam": config.slam.model_copy(update={"camera_process": False}),
                    "upsample": config.upsample.model_copy(update={"worker_process": False}),
                }
            )
            for level in spec.levels:
                for source in spec.sources:
                    run_dir = out_dir / "runs" / world.name / name / f"{source}-{level.label}"
                    job = CompareJob(
                        source, level, world.log_path(out_dir), level.apply(inline), run_dir
                    )
                    jobs.append(SweepJob(world, name, job))
    return jobs


def finished(run_dir: Path) -> dict | None:
    """The metrics of a run that finished (neither interrupted nor failed), else None."""
    metrics = written_metrics(run_dir)
    if "realtime_factor" in metrics and not (metrics.get("interrupted") or metrics.get("failed")):
        return metrics
    return None


def sweep(
    sweep_path: Path | str,
    out_dir: Path | str,
    base: SmokySlamConfig,
    scheduler: str | None = None,
    workers: int | None = None,
    on_progress: ProgressCallback | None = None,
    on_dashboard: Callable[[str], None] | None = None,
) -> SweepResult:
    """Run the sweep file at ``sweep_path`` into ``out_dir`` (see the module docstring)."""
    started = time.perf_counter()
    spec = load_sweep(sweep_path, base)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_config(base, out_dir / "config.yaml")
    jobs = plan(spec, out_dir)
    rows: dict[int, SweepRow] = {}
    for i, planned in enumerate(jobs):
        if (metrics := finished(planned.job.run_dir)) is not None:
            rows[i] = _row(planned, RunStatus.OK, metrics=metrics)
    skipped = len(rows)
    pending = [i for i in range(len(jobs)) if i not in rows]
    logger.info("sweep: %d runs, %d already finished", len(jobs), skipped)
    interrupted = False
    if pending:
        try:
            _run(base, jobs, pending, rows, out_dir, scheduler, workers, on_progress, on_dashboard)
        except KeyboardInterrupt:
            interrupted = True
    ordered = [
        rows.get(i) or _row(jobs[i], RunStatus.INTERRUPTED, "interrupted") for i in range(len(jobs))
    ]
    write_csv(ordered, out_dir)
    if interrupted:
        raise RunInterruptedError(out_dir)
    title = f"sweep {Path(sweep_path).name}: {len(spec.worlds)} worlds x {len(spec.levels)} levels"
    write_summary(ordered, out_dir, title)
    plot_ate_by_source(ordered, out_dir / "ate_by_source.png")
    plot_fused_vs_best(ordered, out_dir / "fused_vs_best.png")
    return SweepResult(ordered, out_dir, skipped, time.perf_counter() - started)


def _run(base, jobs, pending, rows, out_dir, scheduler, workers, on_progress, on_dashboard):
    """The pending runs (and the simulations they need, with the ``base`` config's simulator)
    on Dask; ``rows`` filled as they end."""
    from dask.distributed import Event, as_completed

    needed = {jobs[i].world.name: jobs[i].world for i in pending}
    to_simulate = [
        w for w in needed.values() if w.log is None and not w.log_path(out_dir).is_file()
    ]
    total = len(to_simulate) + len(pending)
    stop_name = new_stop_name()
    with dask_client(scheduler, workers) as client:
        if on_dashboard is not None:
            on_dashboard(client.dashboard_link)
        stop = Event(stop_name, client=client)
        simulations = {
            world.name: client.submit(
                simulate_world,
                world,
                world.log_path(out_dir),
                base,
                key=f"simulate-{world.name}",
                pure=False,
            )
            for world in to_simulate
        }
        runs = {
            client.submit(
                run_one,
                dataclasses.replace(jobs[i].job, stop_event=stop_name),
                simulations.get(jobs[i].world.name),
                key=f"run-{jobs[i].world.name}-{jobs[i].config}-{jobs[i].job.run_dir.name}",
                pure=False,
            ): i
            for i in pending
        }
        done = 0
        futures = as_completed([*simulations.values(), *runs])
        try:
            for future in futures:
                done += 1
                if future in runs:
                    rows[runs[future]] = _collect(future, jobs[runs[future]])
                if on_progress is not None:
                    on_progress(done, total, status=_status(future, runs, jobs, rows))
        except KeyboardInterrupt:
            # Running runs stop as a Ctrl-C'd run does, keeping what they computed; queued
            # runs and simulations do not start.
            stop.set()
            client.cancel(list(simulations.values()))

            def collect(future) -> None:
                if future in runs:
                    rows[runs[future]] = _collect(future, jobs[runs[future]])

            waiting = {f for f in runs if runs[f] not in rows}
            for future in wind_down(client, waiting, collect, STOP_WAIT_S):
                planned = jobs[runs[future]]
                if (row := cut_off_row(planned.job)) is not None:
                    rows[runs[future]] = SweepRow(planned.world, planned.config, row)
            raise


def _collect(future, planned: SweepJob) -> SweepRow:
    """The row of a finished run task; a task that raised (its simulation failed, its worker
    was killed) is a failed row carrying the error."""
    try:
        row: CompareRow = future.result()
    except Exception as exc:  # whatever ended the task on its worker
        message = str(exc) if isinstance(exc, SmokySlamError) else f"{type(exc).__name__}: {exc}"
        return _row(planned, RunStatus.FAILED, message)
    return SweepRow(planned.world, planned.config, row)


def _row(planned: SweepJob, status: RunStatus, error: str = "", metrics=None) -> SweepRow:
    job = planned.job
    row = CompareRow(job.source, job.level, job.run_dir, status, error, metrics=metrics or {})
    return SweepRow(planned.world, planned.config, row)


def _status(future, runs, jobs, rows) -> str:
    if future not in runs:
        return f"{future.key} done"
    row = rows[runs[future]].row
    return f"{jobs[runs[future]].world.name}/{row.run_dir.name} {row.status.value}"
