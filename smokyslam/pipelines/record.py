"""``smokyslam record``: a live TI radar (and a camera) into a log, with host timestamps.

Configure the radar from its ``.cfg`` (the first refused line stops here, with the sensor's
words); then write one radar scan per frame and, with a camera (OpenCV VideoCapture, its
intrinsics from a camera YAML), every image it grabs, each stamped with the host's clock on
arrival, until ``duration_s``, Ctrl-C or the radar going away. Either way the log is closed
properly and holds everything recorded so far.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.camera import load_camera_intrinsics
from smokyslam.frontends.sensors.live import LiveTiReader
from smokyslam.frontends.sensors.ti_config import load_ti_config
from smokyslam.frontends.sensors.ti_frames import ParseStats
from smokyslam.frontends.sensors.ti_radar import TiRadar

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
    intrinsics of ``camera_cfg``) into ``out_log`` (see the module docstring): the live
    reader of ``run --live``, read to the end."""
    radar_config = load_ti_config(radar_cfg)
    live_camera = None
    if camera is not None:
        if camera_cfg is None:
            raise ConfigError("--camera needs --camera-cfg (its intrinsics)")
        live_camera = (camera, load_camera_intrinsics(camera_cfg))
    radar = TiRadar(cli_port, data_port)
    try:
        radar.configure(radar_config)
    except BaseException:
        radar.close()
        raise
    reader = LiveTiReader(
        radar, radar_config, config, Path(out_log), duration_s, live_camera, overwrite
    )
    ended_by, last_status = None, 0.0
    try:
        for _ in reader.frames():
            if on_status is not None and reader.elapsed_s - last_status >= STATUS_PERIOD_S:
                last_status = reader.elapsed_s
                on_status(_status(reader))
    except KeyboardInterrupt:
        ended_by = "interrupted"  # the reader has closed the log with what it holds
    ended_by = ended_by or reader.ended_by
    logger.info(
        "recorded %d scans, %d images in %.1f s (%s)",
        reader.scans,
        reader.images,
        reader.elapsed_s,
        ended_by,
    )
    return RecordResult(
        Path(out_log), reader.scans, reader.elapsed_s, reader.stats, ended_by, reader.images
    )


def _status(reader: LiveTiReader) -> str:
    elapsed_s, stats = max(reader.elapsed_s, 1e-9), reader.stats
    text = (
        f"radar {reader.scans} frames ({reader.scans / elapsed_s:.1f} Hz), {stats.dropped} "
        f"dropped, {stats.bytes_skipped} bytes skipped"
    )
    if reader.images:
        text += f"; camera {reader.images} images ({reader.images / elapsed_s:.1f} Hz)"
    return text
