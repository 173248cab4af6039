"""What the run loop keeps besides the stages: busy seconds per stage, and radar frames and
camera results in the log's order while the camera tracks in a worker."""

from __future__ import annotations

import contextlib
import time
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import Future

from smokyslam.frontends.radar.frontend import RadarFrame
from smokyslam.pipelines.camera_stage import Tracked


class StageClock:
    """Busy seconds per stage."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def add(self, stage: str, seconds: float) -> None:
        self.seconds[stage] = self.seconds.get(stage, 0.0) + seconds

    @contextlib.contextmanager
    def time(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(stage, time.perf_counter() - start)


class InOrder:
    """Radar frames and camera results (finished, or still tracking in the worker) in the
    log's order; :meth:`ready` hands out the front of the queue up to the first camera frame
    still tracking, waiting for it only while more than ``keep`` items are queued."""

    def __init__(self) -> None:
        self._queue: deque[RadarFrame | Future | Tracked] = deque()

    def __len__(self) -> int:
        return len(self._queue)

    def extend(self, items: Iterable[RadarFrame | Future | Tracked]) -> None:
        self._queue.extend(items)

    def ready(self, keep: int) -> Iterator[RadarFrame | Tracked]:
        while self._queue:
            item = self._queue[0]
            if isinstance(item, Future):
                if not item.done() and len(self._queue) <= keep:
                    return
                item = item.result()
            self._queue.popleft()
            yield item
