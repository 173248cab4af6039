"""``smokyslam run --live``: the run loop fed by a TI radar instead of a log.

The radar is configured from its ``.cfg`` once the output folder is claimed; the run records
the stream into ``DIR/live.mcap`` as it goes and writes the usual outputs when the stream ends
(``--duration``, Ctrl-C or a disconnect). There is no camera in a live run yet.
"""

from __future__ import annotations

from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.live import LiveTiReader
from smokyslam.frontends.sensors.ti_config import load_ti_config
from smokyslam.frontends.sensors.ti_radar import TiRadar
from smokyslam.pipelines.run import ProgressCallback, RunResult, run_reader
from smokyslam.pipelines.sources import get_source

LIVE_LOG = "live.mcap"


def run_live(
    cli_port: str,
    data_port: str,
    radar_cfg: Path | str,
    source: str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    duration_s: float | None = None,
    on_progress: ProgressCallback | None = None,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
    overwrite: bool = False,
) -> RunResult:
    """Run ``source`` on the live radar (see the module docstring)."""
    if get_source(source).camera_only:
        raise ConfigError(
            "a live run has no camera yet: use --odometry radar, fused or dead-reckoning"
        )
    radar_config = load_ti_config(radar_cfg)

    def open_reader() -> LiveTiReader:
        radar = TiRadar(cli_port, data_port)
        try:
            radar.configure(radar_config)
        except BaseException:
            radar.close()
            raise
        return LiveTiReader(radar, radar_config, config, Path(out_dir) / LIVE_LOG, duration_s)

    return run_reader(
        open_reader, source, config, out_dir, on_progress, rerun_path, overwrite, rerun_spawn
    )
