"""Camera images paired with their depth images, while every frame keeps the log's order.

When a log has a depth topic, each image waits (up to ``DEPTH_WAIT_S`` of log time) for the
depth image with the same header stamp (within ``DEPTH_MATCH_S``); frames behind a waiting
image are held back so the output stays in time order.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from typing import Any

from smokyslam.frontends.readers.checks import StreamChecks
from smokyslam.rosmsg import header_stamp_ns
from smokyslam.rosmsg_decode import depth_from_msg, image_from_msg
from smokyslam.types import CameraFrame, CameraIntrinsics, Frame

DEPTH_WAIT_S = 0.1
"""Log time an image waits for its depth image before it is released without depth."""
DEPTH_MATCH_S = 0.001
"""Largest header-stamp difference between an image and the depth image paired with it."""


class FrameAssembler:
    """Keeps frames in log order while camera images wait for their depth images."""

    def __init__(self, intrinsics: CameraIntrinsics | None, has_depth: bool) -> None:
        self.intrinsics = intrinsics
        self.has_depth = has_depth
        self._queue: deque[Frame] = deque()
        # id(frame) -> (frame, header stamp ns, release time s) of images waiting for depth
        self._waiting: dict[int, tuple[CameraFrame, int, float]] = {}
        self._early_depths: list[tuple[int, float, Any]] = []

    def push(self, frame: Frame) -> None:
        self._queue.append(frame)

    def push_image(self, msg: Any, stamp_s: float, checks: StreamChecks) -> None:
        image = CameraFrame(stamp_s=stamp_s, image=image_from_msg(msg), intrinsics=self.intrinsics)
        frame = checks.image(image)
        if frame is None:
            return
        key = header_stamp_ns(msg) or round(stamp_s * 1e9)
        self._queue.append(frame)
        for i, (depth_key, _, depth_msg) in enumerate(self._early_depths):
            if abs(depth_key - key) <= DEPTH_MATCH_S * 1e9:
                frame.depth_m = depth_from_msg(depth_msg, frame.image.shape)
                del self._early_depths[i]
                return
        if self.has_depth:
            self._waiting[id(frame)] = (frame, key, stamp_s + DEPTH_WAIT_S)

    def push_depth(self, msg: Any, stamp_s: float) -> None:
        key = header_stamp_ns(msg) or round(stamp_s * 1e9)
        for frame_id, (frame, image_key, _) in self._waiting.items():
            if abs(image_key - key) <= DEPTH_MATCH_S * 1e9:
                frame.depth_m = depth_from_msg(msg, frame.image.shape)
                del self._waiting[frame_id]
                return
        self._early_depths.append((key, stamp_s, msg))

    def release(self, now_s: float) -> Iterator[Frame]:
        """Frames that no longer wait for anything, in order, as of log time ``now_s``."""
        for frame_id, (_, _, deadline_s) in list(self._waiting.items()):
            if deadline_s < now_s:
                del self._waiting[frame_id]
        self._early_depths = [d for d in self._early_depths if d[1] + DEPTH_WAIT_S >= now_s]
        while self._queue and id(self._queue[0]) not in self._waiting:
            yield self._queue.popleft()
