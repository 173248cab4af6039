"""What every worker process of a run does first: leave Ctrl-C to its parent, die with it.

A terminal's Ctrl-C reaches the whole process group; the main process handles it (keeps what
was computed, stops its workers), so a worker ignores it rather than print a traceback. A
worker whose parent is gone (killed, crashed) exits within ``WATCH_S`` instead of waiting
forever on a pipe nobody writes to.
"""

from __future__ import annotations

import contextlib
import importlib
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor

WATCH_S = 0.5


def start_worker_process(parent_pid: int) -> None:
    """Call first in a worker's initializer, with the pid of the process that started it
    (given by that process: by the time a worker has started, its parent may be gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(WATCH_S)
        os._exit(0)  # the parent is gone: nothing is waiting for this worker's results

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while a worker is started: a child inherits an ignored signal, so a
    Ctrl-C in the terminal reaches the main process only (and no worker prints a traceback
    of it, even while it is still importing). Only the main thread can change signal
    handlers; elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _ready() -> bool:
    return True


def _niced_start(niceness: int, module: str, function: str, args: tuple) -> None:
    """A worker's first step: lower its priority, then import and run its initializer (so
    even the worker's imports yield the cores to the run)."""
    if niceness:
        with contextlib.suppress(OSError):
            os.nice(niceness)
    getattr(importlib.import_module(module), function)(*args)


def start_worker_pool(
    initializer: Callable[..., None], initargs: tuple, niceness: int = 0
) -> ProcessPoolExecutor:
    """One spawned worker process (torch, gtsam and OpenCV threads do not survive a fork),
    started now with SIGINT ignored and ``niceness`` added to its priority;
    ``initializer(*initargs)`` runs in it first and should call :func:`start_worker_process`.
    Give plain ``initargs`` for a niced worker: they are unpickled before it is niced."""
    with sigint_ignored():
        pool = ProcessPoolExecutor(
            1,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_niced_start,
            initargs=(niceness, initializer.__module__, initializer.__name__, initargs),
        )
        pool.submit(_ready)  # starts the worker inside the block
    return pool
