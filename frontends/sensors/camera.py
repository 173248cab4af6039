"""A live camera through OpenCV's VideoCapture (a device index, a stream URL or a video file),
grabbed on a thread of its own and stamped with the host's clock on arrival.

Intrinsics come from a small YAML file (``configs/cameras/webcam.yaml``): ``width``,
``height``, ``fx``, ``fy``, ``cx``, ``cy`` in pixels. A camera whose frames have another size
than its file says is refused at its first frame, before anything is recorded.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from smokyslam.errors import ConfigError, SensorError
from smokyslam.types import CameraFrame, CameraIntrinsics

INTRINSICS_KEYS = ("width", "height", "fx", "fy", "cx", "cy")


def load_camera_intrinsics(path: Path | str) -> CameraIntrinsics:
    """The pinhole of a camera YAML; ConfigError naming a missing or bad key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"camera config not found: {path}")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (yaml.YAMLError, UnicodeDecodeError, OSError) as exc:
        raise ConfigError(f"{path}: not a YAML camera config ({type(exc).__name__})") from None
    missing = [key for key in INTRINSICS_KEYS if key not in data]
    if missing:
        raise ConfigError(f"{path}: missing {', '.join(missing)} (pixels)")
    try:
        values = {key: float(data[key]) for key in INTRINSICS_KEYS}
    except (TypeError, ValueError):
        raise ConfigError(f"{path}: {', '.join(INTRINSICS_KEYS)} must be numbers") from None
    if min(values.values()) <= 0:
        raise ConfigError(f"{path}: {', '.join(INTRINSICS_KEYS)} must be positive")
    return CameraIntrinsics(
        int(values["width"]), int(values["height"]), *(values[k] for k in INTRINSICS_KEYS[2:])
    )


def _source(text: str) -> int | str:
    return int(text) if text.isdigit() else text


class CameraGrabber:
    """Grabs frames on a thread; :meth:`ready` hands over those grabbed so far."""

    def __init__(
        self, source: str, intrinsics: CameraIntrinsics, clock_s: Callable[[], float]
    ) -> None:
        import cv2

        self._cv2 = cv2
        self._capture = cv2.VideoCapture(_source(source))
        if not self._capture.isOpened():
            raise SensorError(f"camera '{source}' cannot be opened")
        self._intrinsics = intrinsics
        self._clock_s = clock_s
        self._queue: queue.Queue[CameraFrame] = queue.Queue()
        self._stop = threading.Event()
        self.frames = 0
        first = self._read()  # checked here, before anything is recorded
        if first is None:
            self._capture.release()
            raise SensorError(f"camera '{source}' gives no image")
        if first.shape != (intrinsics.height, intrinsics.width):
            self._capture.release()
            raise SensorError(
                f"camera '{source}' gives {first.shape[1]}x{first.shape[0]} images, its config "
                f"says {intrinsics.width}x{intrinsics.height}"
            )
        self._put(first)
        self._thread = threading.Thread(target=self._grab, name="camera", daemon=True)
        self._thread.start()

    def _read(self) -> np.ndarray | None:
        ok, image = self._capture.read()
        if not ok:
            return None
        if image.ndim == 3:
            image = self._cv2.cvtColor(image, self._cv2.COLOR_BGR2GRAY)
        return np.ascontiguousarray(image)

    def _put(self, image: np.ndarray) -> None:
        self._queue.put(CameraFrame(self._clock_s(), image, self._intrinsics))
        self.frames += 1

    def _grab(self) -> None:
        size = (self._intrinsics.height, self._intrinsics.width)
        while not self._stop.is_set():
            image = self._read()
            if image is None or image.shape != size:
                break  # the camera or the file ended
            self._put(image)

    def ready(self) -> list[CameraFrame]:
        """Every frame grabbed since the last call."""
        frames = []
        while not self._queue.empty():
            frames.append(self._queue.get_nowait())
        return frames

    def close(self) -> list[CameraFrame]:
        """Stop grabbing; the frames still waiting."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._capture.release()
        frames = []
        while not self._queue.empty():
            frames.append(self._queue.get_nowait())
        return frames
