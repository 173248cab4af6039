"""``smokyslam record``: a live TI radar (and a camera) into a log, with host timestamps.

Configure the radar from its ``.cfg`` (the first refused line stops here, with the sensor's
words); then write one radar scan per frame and, with a camera (OpenCV VideoCapture, its
intrinsics from a camera YAML), every image it grabs, each stamped with the host's clock on
arrival, until ``duration_s``, Ctrl-C or the radar going away. Either way the log is closed
properly and holds everything recorded so far.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.camera import CameraGrabber, load_camera_intrinsics
from smokyslam.frontends.sensors.ti_config import load_ti_config
from smokyslam.frontends.sensors.ti_frames import ParseStats, TiFrameParser
from smokyslam.frontends.sensors.ti_radar import TiRadar
from smokyslam.pipelines.import_ti import scan_of
from smokyslam.rig import rig_extrinsics
from smokyslam.sim.recorder import LogWriter

logger = logging.getLogger(__name__)

STATUS_PERIOD_S = 1.0


@dataclass
class RecordResult:
    log_path: Path
    scans: int
    duration_s: float
    stats: ParseStats
    ended_by: str
    """``duration``, ``interrupted`` (Ctrl-C) or ``disconnected`` (the sensor went away)."""
    images: int = 0


def record(
    cli_port: str,
    data_port: str,
    radar_cfg: Path | str,
    out_log: Path | str,
    config: SmokySlamConfig,
    duration_s: float | None = None,
    on_status: Callable[[str], None] | None = None,
    overwrite: bool = False,
    camera: str | None = None,
    camera_cfg: Path | str | None = None,
) -> RecordResult:
    """Record the radar (and ``camera``, a device index, URL or video file, with the
    intrinsics of ``camera_cfg``) into ``out_log`` (see the module docstring)."""
    radar_config = load_ti_config(radar_cfg)
    intrinsics = None
    if camera is not None:
        if camera_cfg is None:
            raise ConfigError("--camera needs --camera-cfg (its intrinsics)")
        intrinsics = load_camera_intrinsics(camera_cfg)
    radar = TiRadar(cli_port, data_port)
    grabber = None
    parser = TiFrameParser(radar_config.doppler_resolution_mps)
    scans, stamp_s, ended_by = 0, 0.0, "disconnected"
    try:
        radar.configure(radar_config)
        with LogWriter(out_log, config.topics, overwrite=overwrite) as writer:
            writer.write_tf_static(rig_extrinsics(config.rig), 0.0)
            started = time.monotonic()
            last_status = 0.0
            if camera is not None:
                grabber = CameraGrabber(camera, intrinsics, lambda: time.monotonic() - started)
            try:
                for frame in radar.frames(parser):
                    stamp_s = time.monotonic() - started
                    writer.write_radar(scan_of(frame, stamp_s))
                    scans += 1
                    for image in grabber.ready() if grabber is not None else ():
                        writer.write_camera(image, depth_scale=1)
                    if on_status is not None and stamp_s - last_status >= STATUS_PERIOD_S:
                        last_status = stamp_s
                        on_status(_status(scans, stamp_s, parser.stats, grabber))
                    if duration_s is not None and stamp_s >= duration_s:
                        ended_by = "duration"
                        radar.stop()
            except KeyboardInterrupt:
                ended_by = "interrupted"  # the log is closed below with what it holds
            finally:
                for image in grabber.close() if grabber is not None else ():
                    writer.write_camera(image, depth_scale=1)
    finally:
        radar.close()
    images = grabber.frames if grabber is not None else 0
    logger.info("recorded %d scans, %d images in %.1f s (%s)", scans, images, stamp_s, ended_by)
    return RecordResult(Path(out_log), scans, stamp_s, parser.stats, ended_by, images)


def _status(scans: int, elapsed_s: float, stats: ParseStats, grabber) -> str:
    rate = scans / elapsed_s if elapsed_s > 0 else 0.0
    text = (
        f"radar {scans} frames ({rate:.1f} Hz), {stats.dropped} dropped, "
        f"{stats.bytes_skipped} bytes skipped"
    )
    if grabber is not None:
        text += f"; camera {grabber.frames} images ({grabber.frames / max(elapsed_s, 1e-9):.1f} Hz)"
    return text
