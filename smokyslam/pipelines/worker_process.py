"""What every worker process of a run does first: leave Ctrl-C to its parent, die with it.

A terminal's Ctrl-C reaches the whole process group; the main process handles it (keeps what
was computed, stops its workers), so a worker ignores it rather than print a traceback. A
worker whose parent is gone (killed, crashed) exits within ``WATCH_S`` instead of waiting
forever on a pipe nobody writes to.
"""

from __future__ import annotations

import os
import signal
import threading
import time

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
