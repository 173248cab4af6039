"""How the run's worker processes start: leave Ctrl-C to their parent, die with it.

A terminal's Ctrl-C reaches the whole process group; the main process handles it (keeps what
was computed, stops its workers), so a worker ignores it rather than print a traceback. Every
worker forks from one fork server started with Ctrl-C ignored (:func:`worker_context`): it
ignores Ctrl-C from its first instruction, while the main process never ignores it, even
while workers start (ignoring it there lost a Ctrl-C pressed in that moment; now it is held
and raised once they have started: :func:`interrupt_held`). A fork from the server is clean
too: none of the threads torch, gtsam or OpenCV keep in the main process. A worker whose
parent is gone (killed, crashed) exits within ``WATCH_S`` instead of waiting forever on a
pipe nobody writes to.
"""

from __future__ import annotations

import contextlib
import importlib
import multiprocessing
import multiprocessing.forkserver
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any

WATCH_S = 0.5


def start_worker_process(parent_pid: int) -> None:
    """Call first in a worker's initializer, with the pid of the process that started it
    (given by that process: by the time a worker has started, its parent may be gone; a
    fork server's worker is not its parent's child, so the pid is watched, not getppid)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while _alive(parent_pid):
            time.sleep(WATCH_S)
        os._exit(0)  # the parent is gone: nothing is waiting for this worker's results

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process holds the pid now: the parent is gone
        return False
    return True


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """SIGINT ignored in this block (a process started in it inherits that). Only the main
    thread can change signal handlers; elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def interrupt_held() -> Iterator[None]:
    """A Ctrl-C during this block (workers starting) is held and raised as KeyboardInterrupt
    when it ends, not in the middle of a half-started pool or cluster. Main thread only;
    elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pressed: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pressed.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if pressed:
        raise KeyboardInterrupt


class DeferredCtrlC:
    """While installed (``with``), a first Ctrl-C is only noted, for the code to act on where
    it is safe (:meth:`take`: the run loop asks between frames); a second one is raised at
    once, to force a stop; one noted and not taken is raised when the block ends. A
    KeyboardInterrupt raised at an arbitrary point can land in a wait on a worker's result
    and leave that future's lock held: the executor's thread then waits for the lock forever
    and the process never exits (seen once in ten Ctrl-C'd fused runs). Only on the main
    thread of a process that heeds Ctrl-C; elsewhere (a worker that leaves Ctrl-C to its
    parent, a thread) nothing changes."""

    def __init__(self) -> None:
        self._pressed = False
        self._installed = False
        self._previous: Any = None

    def take(self) -> bool:
        """Whether a Ctrl-C came since the last call (it is the caller's to act on now)."""
        pressed, self._pressed = self._pressed, False
        return pressed

    def __enter__(self) -> DeferredCtrlC:
        heeded = signal.getsignal(signal.SIGINT) is not signal.SIG_IGN
        if heeded and threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_sigint)
            self._installed = True
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc_info: object) -> None:
        if self._installed:  # the previous handler may be None (one not set from Python)
            signal.signal(signal.SIGINT, self._previous or signal.SIG_DFL)
            self._installed = False
        if self.take() and exc_type is None:
            raise KeyboardInterrupt

    def _on_sigint(self, signum: int, frame: object) -> None:
        if self._pressed:
            self._pressed = False  # acted on here
            raise KeyboardInterrupt
        self._pressed = True


def worker_context() -> multiprocessing.context.BaseContext:
    """The start method of every worker process: forks of a fork server that was started
    with Ctrl-C ignored, so each of its forks ignores it from its first instruction (the
    server is started once, in a few milliseconds; see the module docstring)."""
    with sigint_ignored():
        multiprocessing.forkserver.ensure_running()
    return multiprocessing.get_context("forkserver")


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
    """One worker process (:func:`worker_context`), started now with ``niceness`` added to its
    priority; ``initializer(*initargs)`` runs in it first and should call
    :func:`start_worker_process`. Give plain ``initargs`` for a niced worker: they are
    unpickled before it is niced. A Ctrl-C while it starts is raised once it has started (and
    the worker is shut down)."""
    pool = ProcessPoolExecutor(
        1,
        mp_context=worker_context(),
        initializer=_niced_start,
        initargs=(niceness, initializer.__module__, initializer.__name__, initargs),
    )
    try:
        with interrupt_held():
            pool.submit(_ready)  # starts the worker inside the block
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    return pool
