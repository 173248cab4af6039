"""The dense radar map during a run: refreshed in the background from the online sparse map.

Every ``refresh_period_s`` of log time the online maps hand the current sparse grid to one
background thread, which up-samples it while the run goes on (a refresh still running when
the next is due is not queued: the next keyframe after it finishes starts one). The
up-sampler itself (torch and the weights) is loaded on that thread first, so the run does
not wait for it either; a weights file that cannot be used stops the run at the next
keyframe with the error. The run's final dense map is made from the final sparse map, drawn
on the final poses, by :meth:`DenseRefresher.final`, in the background too: the run writes its
other maps meanwhile.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from smokyslam.config.upsample import UpsampleConfig
from smokyslam.geometry import GridSpec
from smokyslam.upsample.infer import DenseMap, Upsampler, get_upsampler, upsample

logger = logging.getLogger(__name__)

BACKGROUND_THREADS = 1
"""torch threads while the run goes on beside it (the final pass uses torch's default)."""

BACKGROUND_NICENESS = 10
"""The up-sampling thread yields the cores to the run loop and the camera worker."""


class DenseRefresher:
    """Background up-sampling; verbs :meth:`due` / :meth:`refresh` per keyframe, then
    :meth:`final` once."""

    def __init__(self, config: UpsampleConfig) -> None:
        self.period_s = config.refresh_period_s
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="upsample")
        self._torch_threads: int | None = None
        self._loading: Future[Upsampler] = self._pool.submit(self._load, config)
        self._job: Future[DenseMap] | None = None
        self._last_stamp_s: float | None = None
        self.latest: DenseMap | None = None
        self.latest_stamp_s: float | None = None
        self.refreshes = 0
        self.busy_s = 0.0

    def _load(self, config: UpsampleConfig) -> Upsampler:
        with contextlib.suppress(OSError, AttributeError):  # Linux: a nicer thread
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), BACKGROUND_NICENESS)
        upsampler = get_upsampler(config)
        if upsampler.method == "gan":
            import torch

            self._torch_threads = torch.get_num_threads()
            torch.set_num_threads(BACKGROUND_THREADS)
        return upsampler

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
        self._job = self._pool.submit(self._run, stamp_s, cells, spec)

    def _run(self, stamp_s: float, cells: np.ndarray, spec: GridSpec) -> DenseMap:
        started = time.perf_counter()
        dense = upsample(self._loading.result(), cells, spec)
        self.busy_s += time.perf_counter() - started
        self.latest_stamp_s = stamp_s
        return dense

    def _collect(self) -> None:
        if self._job is not None and self._job.done():
            job, self._job = self._job, None
            self.latest = job.result()
            self.refreshes += 1

    def final(self, cells: np.ndarray, spec: GridSpec) -> Future[DenseMap]:
        """The dense map of the final sparse map, made in the background (after the loading
        and any refresh still running) while the caller goes on: its future."""
        return self._pool.submit(self._final, cells, spec)

    def _final(self, cells: np.ndarray, spec: GridSpec) -> DenseMap:
        upsampler = self._loading.result()  # done: the pool runs one job at a time
        if self._torch_threads is not None:
            import torch

            torch.set_num_threads(self._torch_threads)  # the run is over: every core
        return upsample(upsampler, cells, spec)

    def stats(self) -> dict[str, float | int]:
        """``upsample`` in metrics.json: refreshes done and their mean seconds."""
        self._collect()
        mean_s = self.busy_s / self.refreshes if self.refreshes else 0.0
        return {"refreshes": self.refreshes, "refresh_mean_s": mean_s}

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)
