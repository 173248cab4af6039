"""The executor layer of ``compare`` and ``sweep``: a Dask cluster, and the stop flag its
runs poll.

The cluster is a LocalCluster sized to this machine, or an existing scheduler (``dask
scheduler`` / ``dask worker`` on other machines). A task runs on a worker thread, where no
Ctrl-C arrives, so a batch is stopped cooperatively: the main process sets a Dask Event, and
each run's loop polls it (:class:`StopFlag`) and ends as a Ctrl-C'd run does, keeping what it
computed.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

from smokyslam.errors import ConfigError
from smokyslam.pipelines.worker_process import interrupt_held, worker_context

logger = logging.getLogger(__name__)

CONNECT_TIMEOUT_S = 10
STOP_POLL_S = 0.2
"""How often a run asks whether its batch was stopped (a round trip to the scheduler)."""


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A ``distributed.Client``: on ``scheduler`` (an address), or on a LocalCluster of
    ``workers`` single-threaded worker processes (default: one per core). Everything it
    started is closed on the way out, Ctrl-C included: no worker process stays behind."""
    import dask
    from dask.distributed import Client, LocalCluster

    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be 1 or more, got {workers}")
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"--scheduler {scheduler}: cannot reach it ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    # Workers fork from the fork server that ignores Ctrl-C (worker_context): the terminal's
    # Ctrl-C reaches the whole process group, and only this process handles it. Workers may
    # start processes of their own (a run's camera worker), so they are no daemons; quiet
    # logs keep the progress readable.
    worker_context()
    settings = {
        "distributed.worker.multiprocessing-method": "forkserver",
        "distributed.worker.daemon": False,
        "distributed.admin.tick.limit": "10s",
    }
    cluster = None
    try:
        with dask.config.set(settings), interrupt_held():
            cluster = LocalCluster(
                n_workers=workers or os.cpu_count() or 1,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            )
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


def end_workers(client: Any) -> None:
    """End the worker processes of this machine's cluster now, with the tasks they run (a
    closing cluster would wait for them). Never used on another's scheduler."""
    import signal

    with contextlib.suppress(Exception):  # a worker gone already is what was asked
        for pid in client.run(os.getpid, wait=True).values():
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)


def wind_down(client: Any, pending: set, on_done: Callable[[Any], None], wait_s: float) -> set:
    """Once a batch's stop flag is set: every pending future that ends within ``wait_s``
    goes to ``on_done``; the rest are cancelled and, on this machine's cluster, the workers
    running them ended (:func:`end_workers`). Returns the futures cut off."""
    pending = set(pending)
    deadline = time.monotonic() + wait_s
    while pending and time.monotonic() < deadline:
        for future in [f for f in pending if f.done()]:
            pending.discard(future)
            on_done(future)
        time.sleep(0.05)
    client.cancel(list(pending))
    if pending and client.cluster is not None:
        end_workers(client)
    return pending


def new_stop_name() -> str:
    """A fresh name for the Dask Event of one batch of runs."""
    return f"smokyslam-stop-{uuid.uuid4().hex}"


class StopFlag:
    """``flag()``: whether the batch's Dask Event ``name`` is set. Asked from inside a task;
    asks the scheduler at most every ``STOP_POLL_S``, and once set stays set."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._event: Any = None
        self._next_s = 0.0
        self._set = False

    def __call__(self) -> bool:
        now = time.monotonic()
        if self._set or now < self._next_s:
            return self._set
        self._next_s = now + STOP_POLL_S
        from dask.distributed import Event

        with contextlib.suppress(ValueError):  # no client here: nobody can stop this run
            self._event = self._event or Event(self.name)
            self._set = bool(self._event.is_set())
        return self._set
