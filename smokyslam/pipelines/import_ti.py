"""``smokyslam import-ti``: a raw TI UART capture (what the mmWave Demo Visualizer saves) as a
log whose radar scans any command replays.

Every valid frame becomes exactly one scan (an empty one for a frame without detections), on
the configured radar topic, stamped by the sensor's frame counter times the ``.cfg``'s frame
period (a capture has no clock of its own; where the counter does not increase, one period
after the previous scan). Corrupt and truncated frames are dropped and counted. The sensor's
mounting is the config's rig (``rig:``), written as ``/tf_static``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError
from smokyslam.frontends.sensors.ti_config import load_ti_config
from smokyslam.frontends.sensors.ti_frames import ParseStats, TiFrameParser
from smokyslam.rig import rig_extrinsics
from smokyslam.sim.recorder import LogWriter

logger = logging.getLogger(__name__)

CHUNK_BYTES = 1 << 16


@dataclass
class ImportResult:
    log_path: Path
    scans: int
    duration_s: float
    stats: ParseStats


class ScanClock:
    """Stamps of a frame stream: the frame counter times the period while it increases."""

    def __init__(self, period_s: float) -> None:
        self._period_s = period_s
        self._first: int | None = None
        self._last: tuple[int, float] | None = None

    def stamp_s(self, frame_number: int) -> float:
        if self._first is None:
            self._first = frame_number
        if self._last is None or frame_number > self._last[0]:
            stamp = (frame_number - self._first) * self._period_s
            if self._last is not None and stamp <= self._last[1]:
                stamp = self._last[1] + self._period_s
        else:
            stamp = self._last[1] + self._period_s
        self._last = (frame_number, stamp)
        return stamp


def import_ti(
    capture: Path | str,
    radar_cfg: Path | str,
    out_log: Path | str,
    config: SmokySlamConfig,
    overwrite: bool = False,
    sdk: int | None = None,
) -> ImportResult:
    """Convert ``capture`` (raw UART bytes) configured by ``radar_cfg`` into ``out_log``.
    LogError when the capture holds no valid frame (no log is left then)."""
    capture = Path(capture)
    if not capture.is_file():
        raise LogError(f"capture not found: {capture}")
    radar = load_ti_config(radar_cfg)
    parser = TiFrameParser(radar.doppler_resolution_mps, sdk)
    clock = ScanClock(radar.frame_period_s)
    scans, last_stamp = 0, 0.0
    with LogWriter(out_log, config.topics, overwrite=overwrite) as writer:
        writer.write_tf_static(rig_extrinsics(config.rig), 0.0)
        with capture.open("rb") as stream:
            while chunk := stream.read(CHUNK_BYTES):
                for frame in parser.feed(chunk):
                    last_stamp = clock.stamp_s(frame.frame_number)
                    writer.write_radar(frame.scan(last_stamp))
                    scans += 1
        parser.finish()
        if scans == 0:
            raise LogError(
                f"{capture}: no TI mmWave frame found ({parser.stats.bytes_skipped} bytes "
                f"skipped, {parser.stats.dropped} damaged frames): is it a raw UART capture?"
            )
    stats = parser.stats
    logger.info(
        "%s: %d frames, %d dropped %s, %d bytes skipped",
        capture,
        stats.frames,
        stats.dropped,
        stats.reasons,
        stats.bytes_skipped,
    )
    return ImportResult(Path(out_log), scans, last_stamp, stats)
