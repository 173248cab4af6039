"""Live sensors as a :class:`~smokyslam.frontends.readers.base.LogReader`: ``run --live``.

The run loop reads a live TI radar (and a camera) exactly as it reads a log. Each frame
becomes a radar scan stamped with the host's clock on arrival, and the camera's images
(grabbed on a thread, host-stamped) come before the scan they preceded. Everything is written
to the recording (``record_path``) as it goes. The stream ends at ``duration_s``, when the
radar goes away, or at Ctrl-C. Either way the recording is closed properly and keeps
everything received. There is no ground truth.
"""

from __future__ import annotations

import time
from collections.abc import Collection, Iterator
from pathlib import Path

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.frontends.readers.base import LogSummary, StreamSummary
from smokyslam.frontends.sensors.camera import CameraGrabber
from smokyslam.frontends.sensors.ti_config import TiRadarConfig
from smokyslam.frontends.sensors.ti_frames import ParseStats, TiFrameParser
from smokyslam.frontends.sensors.ti_radar import TiRadar
from smokyslam.rig import rig_extrinsics
from smokyslam.sim.recorder import LogWriter
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    Frame,
    GroundTruthMap,
    GroundTruthTrajectory,
)


class LiveTiReader:
    """A configured TI radar, read once (``frames``), recorded as it is read."""

    def __init__(
        self,
        radar: TiRadar,
        radar_config: TiRadarConfig,
        config: SmokySlamConfig,
        record_path: Path,
        duration_s: float | None = None,
        camera: tuple[str, CameraIntrinsics] | None = None,
        overwrite: bool = True,
    ) -> None:
        """``camera``: (OpenCV source, its intrinsics), or None for radar only.
        ``overwrite``: replace a recording already at ``record_path``."""
        self.path = Path(record_path)
        self._camera = camera
        self._radar = radar
        self._config = config
        self._duration_s = duration_s
        self._overwrite = overwrite
        self._parser = TiFrameParser(radar_config.doppler_resolution_mps)
        self._started_epoch_s = time.time()
        self.scans = 0
        self.images = 0
        self.elapsed_s = 0.0
        """Radar scans and camera images recorded so far, and the time of the latest scan."""
        self.ended_by = "disconnected"
        """``duration``, or ``disconnected`` (the radar went away)."""

    @property
    def stats(self) -> ParseStats:
        """What the frame parser has seen (frames, drops, bytes skipped)."""
        return self._parser.stats

    def frames(self, streams: Collection[str] | None = None) -> Iterator[Frame]:
        wants_images = streams is None or "camera_image" in streams
        started = time.monotonic()
        self._started_epoch_s = time.time()
        grabber = None
        try:
            if self._camera is not None:  # a refused camera stops before anything is recorded
                source, intrinsics = self._camera
                grabber = CameraGrabber(source, intrinsics, lambda: time.monotonic() - started)
            writer = LogWriter(self.path, self._config.topics, overwrite=self._overwrite)
            writer.__enter__()
        except BaseException:
            self._radar.close()
            if grabber is not None:
                grabber.close()
            raise
        writer.write_tf_static(self.extrinsics(), 0.0)
        try:
            for frame in self._radar.frames(self._parser):
                stamp_s = time.monotonic() - started
                for image in grabber.ready() if grabber is not None else ():
                    writer.write_camera(image, depth_scale=1)
                    self.images += 1
                    if wants_images:
                        yield image
                scan = frame.scan(stamp_s)
                writer.write_radar(scan)
                self.scans, self.elapsed_s = self.scans + 1, stamp_s
                yield scan
                if self._duration_s is not None and stamp_s >= self._duration_s:
                    self.ended_by = "duration"
                    self._radar.stop()
        finally:  # Ctrl-C, a disconnect or the end: the recording keeps what it received
            for image in grabber.close() if grabber is not None else ():
                writer.write_camera(image, depth_scale=1)
                self.images += 1
            writer.close()
            self._radar.close()

    def summary(self) -> LogSummary:
        rate = self.scans / self.elapsed_s if self.elapsed_s > 0 else 0.0
        streams = [StreamSummary("radar (live)", "TI mmWave UART", self.scans, rate)]
        return LogSummary(self.path, "live", self.elapsed_s, self._started_epoch_s, streams)

    def log_time_s(self, stamps_s: np.ndarray) -> np.ndarray:
        """Host clock: seconds since the epoch."""
        return np.asarray(stamps_s, dtype=float) + self._started_epoch_s

    def ground_truth_trajectory(self) -> GroundTruthTrajectory | None:
        return None

    def ground_truth_map(self) -> GroundTruthMap | None:
        return None

    def observed_ground_truth_map(self) -> GroundTruthMap | None:
        return None

    def extrinsics(self) -> Extrinsics:
        return rig_extrinsics(self._config.rig)

    def camera_intrinsics(self) -> CameraIntrinsics | None:
        return self._camera[1] if self._camera is not None else None

    def problems(self) -> dict[str, object]:
        stats = self.stats
        if not (stats.dropped or stats.bytes_skipped):
            return {}
        return {"dropped_frames": stats.dropped, "bytes_skipped": stats.bytes_skipped}
