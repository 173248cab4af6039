"""Runs of a comparison as jobs: each one a whole ``run_log``, on Dask workers (the executor
layer ``sweep`` runs on, :mod:`smokyslam.pipelines.executor`) or, with one worker, here.

Ctrl-C stops a comparison within a couple of seconds: the batch's stop flag is set, so
running runs end as a Ctrl-C'd run does (their partial outputs kept) and queued ones do not
start; they are waited for up to ``STOP_WAIT_S``, then the cluster is closed. Workers ignore
Ctrl-C, so none prints a traceback.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import signal
import threading
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import RunInterruptedError, SmokySlamError
from smokyslam.evaluation.compare_table import CompareRow, RunStatus
from smokyslam.pipelines.executor import StopFlag, dask_client, new_stop_name, wind_down
from smokyslam.pipelines.run import run_log
from smokyslam.smoke import SmokeLevel

logger = logging.getLogger(__name__)

ERROR_LOG = "error.log"
STOP_WAIT_S = 1.0
"""After Ctrl-C, how long running jobs get to write what they computed."""

ProgressCallback = Callable[..., None]


@dataclass(frozen=True)
class CompareJob:
    """One run: ``source`` over ``log_path`` with ``config`` (smoke level applied)."""

    source: str
    level: SmokeLevel
    log_path: Path
    config: SmokySlamConfig
    run_dir: Path
    stop_event: str | None = None
    """The Dask Event that stops the job's batch (:class:`StopFlag`), if it has one."""


def run_job(job: CompareJob) -> CompareRow:
    """Run one job; any exception becomes a failed row, never a raise. Ctrl-C (or the
    batch's stop) during the run keeps its partial outputs: an ``interrupted`` row; a job
    whose batch was stopped before it started is ``not run``."""
    should_stop = StopFlag(job.stop_event) if job.stop_event else None
    if should_stop is not None and should_stop():
        return _not_run(job)
    try:
        with _interruptible():
            result = run_log(
                job.log_path,
                job.source,
                job.config,
                job.run_dir,
                overwrite=True,
                should_stop=should_stop,
            )
    except RunInterruptedError:
        return _stopped(job, written_metrics(job.run_dir))
    except KeyboardInterrupt:
        return CompareRow(job.source, job.level, job.run_dir, RunStatus.INTERRUPTED, "interrupted")
    except Exception as exc:
        message = str(exc) if isinstance(exc, SmokySlamError) else f"{type(exc).__name__}: {exc}"
        # The folder itself may be what failed; the row carries the message either way.
        with contextlib.suppress(OSError):
            job.run_dir.mkdir(parents=True, exist_ok=True)
            (job.run_dir / ERROR_LOG).write_text(traceback.format_exc())
        return CompareRow(job.source, job.level, job.run_dir, RunStatus.FAILED, message)
    return CompareRow(job.source, job.level, job.run_dir, RunStatus.OK, metrics=result.metrics)


def _interrupt_once(signum: int, frame: object) -> None:
    """The first Ctrl-C stops the run; later ones (the terminal's and the comparison's own
    stop signal) must not cut off the writing of what it computed."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


@contextlib.contextmanager
def _interruptible():
    """Ctrl-C reaches the run in a worker process (which otherwise ignores it). Elsewhere,
    and off the main thread (a Dask worker's task), the caller's own handling applies."""
    main = threading.current_thread() is threading.main_thread()
    if not main or signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        yield
        return
    signal.signal(signal.SIGINT, _interrupt_once)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def written_metrics(run_dir: Path) -> dict:
    """What a run has written into its ``metrics.json`` so far ({} if nothing)."""
    with contextlib.suppress(OSError, ValueError):
        return json.loads((run_dir / "metrics.json").read_text())
    return {}


def default_workers(runs: int) -> int:
    """Parallel runs when not given: up to 2, at most one per core, never more than runs."""
    return max(1, min(os.cpu_count() or 1, 2, runs))


def run_jobs(
    jobs: Sequence[CompareJob],
    workers: int,
    on_progress: ProgressCallback | None = None,
    scheduler: str | None = None,
) -> tuple[list[CompareRow], bool]:
    """Every job's row, in job order, and whether Ctrl-C stopped them. On Dask: on a
    LocalCluster of ``workers`` processes, or on the cluster at ``scheduler``; one worker
    and no scheduler runs them here, one after another. ``on_progress(done, total,
    status=...)`` per run."""
    rows: list[CompareRow | None] = [None] * len(jobs)

    def finished(index: int, row: CompareRow) -> None:
        rows[index] = row
        if on_progress is not None:
            done = sum(r is not None for r in rows)
            on_progress(done, len(jobs), status=f"{row.run_dir.name} {row.status.value}")

    interrupted = False
    if workers <= 1 and scheduler is None:
        for index, job in enumerate(jobs):
            finished(index, run_job(job))
            if rows[index].status is RunStatus.INTERRUPTED:
                interrupted = True
                break
    else:
        interrupted = _run_on_dask(jobs, workers, scheduler, finished)
    return [row or _not_run(job) for row, job in zip(rows, jobs, strict=True)], interrupted


def _run_on_dask(
    jobs: Sequence[CompareJob], workers: int, scheduler: str | None, finished: Callable
) -> bool:
    """The jobs as Dask tasks; True when Ctrl-C stopped them."""
    stop_name = new_stop_name()
    jobs = [dataclasses.replace(job, stop_event=stop_name) for job in jobs]
    try:
        with dask_client(scheduler, workers) as client:
            return _gather(client, jobs, stop_name, finished)
    except KeyboardInterrupt:  # while the cluster started: no run had begun
        return True


def _gather(client, jobs: Sequence[CompareJob], stop_name: str, finished: Callable) -> bool:
    """Submit the jobs and hand each row to ``finished`` as it comes; on Ctrl-C set the
    batch's stop flag and collect what ends within ``STOP_WAIT_S`` (True)."""
    from dask.distributed import Event, as_completed

    stop = Event(stop_name, client=client)
    futures = {
        client.submit(run_job, job, key=f"run-{job.run_dir.name}-{stop_name}", pure=False): i
        for i, job in enumerate(jobs)
    }
    pending = set(futures)

    def collect(future) -> None:
        pending.discard(future)
        finished(futures[future], _row(future, jobs[futures[future]]))

    try:
        for future in as_completed(futures):
            collect(future)
    except KeyboardInterrupt:
        stop.set()  # running runs keep what they computed; queued ones do not start
        for future in wind_down(client, pending, collect, STOP_WAIT_S):
            job = jobs[futures[future]]
            finished(futures[future], cut_off_row(job) or _not_run(job))
        return True
    return False


def cut_off_row(job: CompareJob) -> CompareRow | None:
    """The ``interrupted`` row of a run ended while it wrote its outputs (its numbers come
    first), or None if it had written none."""
    metrics = written_metrics(job.run_dir)
    return _stopped(job, metrics) if metrics else None


def _stopped(job: CompareJob, metrics: dict) -> CompareRow:
    return CompareRow(
        job.source, job.level, job.run_dir, RunStatus.INTERRUPTED, "interrupted", metrics=metrics
    )


def _row(future, job: CompareJob) -> CompareRow:
    try:
        return future.result()
    except Exception as exc:  # the task's worker died (crash, out of memory) or was lost
        message = f"{type(exc).__name__}: {exc}"
        return CompareRow(job.source, job.level, job.run_dir, RunStatus.FAILED, message)


def _not_run(job: CompareJob) -> CompareRow:
    return CompareRow(job.source, job.level, job.run_dir, RunStatus.INTERRUPTED, "not run")
