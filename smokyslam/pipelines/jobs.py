"""Runs of a comparison as jobs: each one a whole ``run_log`` in a worker process.

Ctrl-C stops a comparison within a couple of seconds: jobs not started are cancelled, running
ones get the interrupt (their partial outputs are kept, as for a single run) and are waited
for up to ``STOP_WAIT_S``, then their processes are ended. Workers ignore Ctrl-C while idle,
so none prints a traceback.
"""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import (
    FIRST_COMPLETED,
    Future,
    InvalidStateError,
    ProcessPoolExecutor,
    wait,
)
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import RunInterruptedError, SmokySlamError
from smokyslam.evaluation.compare_table import CompareRow, RunStatus
from smokyslam.pipelines.run import run_log
from smokyslam.pipelines.worker_process import start_worker_process
from smokyslam.smoke import SmokeLevel

logger = logging.getLogger(__name__)

# torch, gtsam and OpenCV keep threads and locks that a forked child inherits half-held.
START_METHOD = "spawn"
ERROR_LOG = "error.log"
STOP_WAIT_S = 1.5
"""After Ctrl-C, how long running jobs get to write what they computed."""

ProgressCallback = Callable[..., None]

_DEFAULT_EXCEPTHOOK = threading.excepthook


@dataclass(frozen=True)
class CompareJob:
    """One run: ``source`` over ``log_path`` with ``config`` (smoke level applied)."""

    source: str
    level: SmokeLevel
    log_path: Path
    config: SmokySlamConfig
    run_dir: Path


def run_job(job: CompareJob) -> CompareRow:
    """Run one job (in a worker process); any exception becomes a failed row, never a raise.
    Ctrl-C during the run keeps its partial outputs: an ``interrupted`` row."""
    try:
        with _interruptible():
            result = run_log(job.log_path, job.source, job.config, job.run_dir, overwrite=True)
    except RunInterruptedError:
        return CompareRow(
            job.source,
            job.level,
            job.run_dir,
            RunStatus.INTERRUPTED,
            "interrupted",
            metrics=_metrics(job.run_dir),
        )
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


def _metrics(run_dir: Path) -> dict:
    with contextlib.suppress(OSError, ValueError):
        return json.loads((run_dir / "metrics.json").read_text())
    return {}


def default_workers(runs: int) -> int:
    """Parallel runs when not given: up to 2, at most one per core, never more than runs."""
    return max(1, min(os.cpu_count() or 1, 2, runs))


def run_jobs(
    jobs: Sequence[CompareJob], workers: int, on_progress: ProgressCallback | None = None
) -> tuple[list[CompareRow], bool]:
    """Every job's row, in job order, and whether Ctrl-C stopped them. ``workers`` > 1 runs
    them in that many spawned processes; 1 runs them here, one after another.
    ``on_progress(done, total, status=...)`` per run."""
    rows: list[CompareRow | None] = [None] * len(jobs)

    def finished(index: int, row: CompareRow) -> None:
        rows[index] = row
        if on_progress is not None:
            done = sum(r is not None for r in rows)
            on_progress(done, len(jobs), status=f"{row.run_dir.name} {row.status.value}")

    interrupted = False
    if workers <= 1:
        for index, job in enumerate(jobs):
            finished(index, run_job(job))
            if rows[index].status is RunStatus.INTERRUPTED:
                interrupted = True
                break
    else:
        interrupted = _run_in_pool(jobs, workers, finished)
    return [row or _not_run(job) for row, job in zip(rows, jobs, strict=True)], interrupted


def _run_in_pool(jobs: Sequence[CompareJob], workers: int, finished: Callable) -> bool:
    """The jobs in a process pool; True when Ctrl-C stopped them."""
    context = multiprocessing.get_context(START_METHOD)
    pool = ProcessPoolExecutor(
        workers,
        mp_context=context,
        initializer=start_worker_process,
        initargs=(os.getpid(),),
    )
    futures: dict[Future, int] = {pool.submit(run_job, job): i for i, job in enumerate(jobs)}
    pending = set(futures)
    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                finished(futures[future], _row(future, jobs[futures[future]]))
    except KeyboardInterrupt:
        _stop(pool, pending, futures, jobs, finished)
        return True
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    pool.shutdown(wait=True)
    return False


def _ignore_cancelled_future_errors(args: threading.ExceptHookArgs) -> None:
    """Python 3.11's process pool, broken by ending its workers, sets an exception on futures
    already cancelled, and its manager thread prints the InvalidStateError. Nothing is lost
    (those runs were cancelled): it is not printed. Anything else is, as usual."""
    if args.exc_type is not InvalidStateError:
        _DEFAULT_EXCEPTHOOK(args)


def _stop(pool, pending, futures, jobs, finished) -> None:
    """Cancel what has not started, interrupt what runs, give it STOP_WAIT_S, end the rest."""
    threading.excepthook = _ignore_cancelled_future_errors  # the rest of this process
    for future in pending:
        future.cancel()
    processes = list(getattr(pool, "_processes", {}).values())  # no public handle on them
    for process in processes:
        with contextlib.suppress(OSError):
            os.kill(process.pid, signal.SIGINT)
    deadline = time.monotonic() + STOP_WAIT_S
    running = {f for f in pending if not f.cancelled()}
    while running and time.monotonic() < deadline:
        done, running = wait(running, timeout=deadline - time.monotonic())
        for future in done:
            finished(futures[future], _row(future, jobs[futures[future]]))
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=1.0)


def _row(future: Future, job: CompareJob) -> CompareRow:
    try:
        return future.result()
    except Exception as exc:  # the worker process died (crash, out of memory)
        message = f"{type(exc).__name__}: {exc}"
        return CompareRow(job.source, job.level, job.run_dir, RunStatus.FAILED, message)


def _not_run(job: CompareJob) -> CompareRow:
    return CompareRow(job.source, job.level, job.run_dir, RunStatus.INTERRUPTED, "not run")
