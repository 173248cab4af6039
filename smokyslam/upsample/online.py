"""The dense radar map during a run: refreshed in the background from the online sparse map.

Every ``refresh_period_s`` of log time the online maps hand the current sparse grid to the
up-sampler, which works on it while the run goes on (a refresh still running when the next is
due is not queued: the next keyframe after it finishes starts one). The up-sampler (torch and
the weights) is loaded in the background first, so the run does not wait for it either; a
weights file that cannot be used stops the run at the next keyframe with the error. The run's
final dense map is made from the final sparse map, drawn on the final poses, by
:meth:`DenseRefresher.final`, in the background too: the run writes its other maps meanwhile.

The up-sampler lives in a worker process of its own (``upsample.worker_process``), with
lowered priority: loading torch takes 1.2-1.5 s of imports that hold Python's lock, and on a
thread of the run's own process that lock held the run loop back. On a thread instead
(``worker_process`` off: a sweep's runs, where a Dask worker is one core) it works the same.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
import uuid
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from smokyslam.config.upsample import UpsampleConfig
from smokyslam.geometry import GridSpec
from smokyslam.upsample.infer import DenseMap, Upsampler, get_upsampler, upsample

logger = logging.getLogger(__name__)

BACKGROUND_THREADS = 1
"""torch threads while the run goes on beside it (the final pass uses torch's default)."""

BACKGROUND_NICENESS = 10
"""The up-sampler yields the cores to the run loop and the camera worker."""

_LOADED: dict[str, tuple[Upsampler, int | None] | Exception] = {}
"""The up-samplers loaded in this process, by refresher, each with torch's thread count from
before the load (None: no torch); or why it could not be loaded."""


def _start_worker(parent_pid: int) -> None:
    from smokyslam.pipelines.worker_process import start_worker_process

    start_worker_process(parent_pid)


def _load(key: str, config: dict[str, Any]) -> None:
    """Load the up-sampler ``config`` names (a plain dict: it may cross to a worker) under
    ``key``, then leave torch one thread while the run goes on."""
    with contextlib.suppress(OSError, AttributeError):  # Linux: a nicer thread
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), BACKGROUND_NICENESS)
    try:
        upsampler = get_upsampler(UpsampleConfig.model_validate(config))
    except Exception as exc:  # each later job raises it too
        _LOADED[key] = exc
        raise
    threads = None
    if upsampler.method == "gan":
        import torch

        threads = torch.get_num_threads()
        torch.set_num_threads(BACKGROUND_THREADS)
    _LOADED[key] = (upsampler, threads)


def _loaded(key: str) -> tuple[Upsampler, int | None]:
    loaded = _LOADED[key]
    if isinstance(loaded, Exception):
        raise loaded
    return loaded


def _refresh(key: str, cells: np.ndarray, spec: GridSpec) -> tuple[DenseMap, float]:
    """The dense map of ``cells`` by the up-sampler under ``key``, and its seconds."""
    started = time.perf_counter()
    dense = upsample(_loaded(key)[0], cells, spec)
    return dense, time.perf_counter() - started


def _final(key: str, cells: np.ndarray, spec: GridSpec) -> DenseMap:
    """As :func:`_refresh`, with torch's own thread count (the run is over: every core)."""
    upsampler, threads = _loaded(key)
    if threads is not None:
        import torch

        torch.set_num_threads(threads)
    return upsample(upsampler, cells, spec)


class DenseRefresher:
    """Background up-sampling; verbs :meth:`due` / :meth:`refresh` per keyframe, then
    :meth:`final` once."""

    def __init__(self, config: UpsampleConfig) -> None:
        self.period_s = config.refresh_period_s
        self._key = uuid.uuid4().hex
        self._pool: Executor
        if config.worker_process:
            from smokyslam.pipelines.worker_process import start_worker_pool

            self._pool = start_worker_pool(
                _start_worker, (os.getpid(),), niceness=BACKGROUND_NICENESS
            )
        else:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="upsample")
        self._loading: Future[None] = self._pool.submit(
            _load, self._key, config.model_dump(mode="json")
        )
        self._job: Future[tuple[DenseMap, float]] | None = None
        self._last_stamp_s: float | None = None
        self.latest: DenseMap | None = None
        self.latest_stamp_s: float | None = None
        self.refreshes = 0
        self.busy_s = 0.0

    def due(self, stamp_s: float) -> bool:
        """Whether a refresh should start at log time ``stamp_s`` (none is running, and the
        period has passed since the last one started). Raises the loading error, if any."""
        self._collect()
        if self._loading.done() and self._loading.exception() is not None:
            self._loading.result()  # the weights cannot be used: stop the run now
        if self._job is not None:
            return False
        return self._last_stamp_s is None or stamp_s - self._last_stamp_s >= self.period_s

    def refresh(self, stamp_s: float, cells: np.ndarray, spec: GridSpec) -> None:
        """Up-sample ``cells`` over ``spec`` in the background."""
        self._last_stamp_s = stamp_s
        self._job = self._pool.submit(_refresh, self._key, cells, spec)

    @property
    def failure(self) -> str | None:
        """Why the up-sampler could not be loaded (None: it was, or it is still loading)."""
        if self._loading.done() and (error := self._loading.exception()) is not None:
            return str(error)
        return None

    def _collect(self) -> None:
        if self._job is None or not self._job.done():
            return
        job, self._job = self._job, None
        if job.exception() is not None and self.failure is not None:
            return  # the refresh failed for want of an up-sampler: the loading error tells
        self.latest, seconds = job.result()
        self.latest_stamp_s = self._last_stamp_s
        self.busy_s += seconds
        self.refreshes += 1

    def final(self, cells: np.ndarray, spec: GridSpec) -> Future[DenseMap]:
        """The dense map of the final sparse map, made in the background (after the loading
        and any refresh still running) while the caller goes on: its future."""
        return self._pool.submit(_final, self._key, cells, spec)

    def stats(self) -> dict[str, float | int]:
        """``upsample`` in metrics.json: refreshes done and their mean seconds."""
        self._collect()
        mean_s = self.busy_s / self.refreshes if self.refreshes else 0.0
        return {"refreshes": self.refreshes, "refresh_mean_s": mean_s}

    def close(self) -> None:
        """Stop the up-sampler (a refresh still running is waited for)."""
        self._pool.shutdown(wait=True, cancel_futures=True)
        _LOADED.pop(self._key, None)
