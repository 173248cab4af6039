"""The Dask cluster a sweep runs on: a LocalCluster sized to this machine, or an existing
scheduler (``dask scheduler`` / ``dask worker`` on other machines)."""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from typing import Any

from smokyslam.errors import ConfigError
from smokyslam.pipelines.worker_process import sigint_ignored

logger = logging.getLogger(__name__)

CONNECT_TIMEOUT_S = 10


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
    # Runs start no processes of their own on a sweep's workers (the camera tracks inline),
    # so the workers need not be daemons; quiet logs keep the progress readable.
    # Workers start with Ctrl-C ignored (inherited): the terminal's Ctrl-C reaches the whole
    # process group, and only this process handles it, by closing the cluster.
    settings = {"distributed.worker.daemon": False, "distributed.admin.tick.limit": "10s"}
    with dask.config.set(settings), sigint_ignored():
        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.ERROR,
        )
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()
