"""``smokyslam run --live``: the run loop fed by a TI radar instead of a log.

The radar is configured from its ``.cfg`` once the output folder is claimed; the run records
the stream into ``DIR/live.mcap`` as it goes and writes the usual outputs when the stream ends
(``--duration``, Ctrl-C or a disconnect). A camera (OpenCV source and intrinsics YAML) is
optional; without one, camera-only runs are refused and fused runs on the radar alone.
"""

from __future__ import annotations

from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.camera import load_camera_intrinsics
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
    camera: str | None = None,
    camera_cfg: Path | str | None = None,
) -> RunResult:
    """Run ``source`` on the live radar and ``camera`` (see the module docstring)."""
    live_camera = None
    if camera is not None:
        if camera_cfg is None:
            raise ConfigError("--camera needs --camera-cfg (its intrinsics)")
        live_camera = (camera, load_camera_intrinsics(camera_cfg))
    if get_source(source).camera_only and live_camera is None:
        raise ConfigError("--odometry camera needs --camera and --camera-cfg in a live run")
    radar_config = load_ti_config(radar_cfg)

    def open_reader() -> LiveTiReader:
        radar = TiRadar(cli_port, data_port)
        try:
            radar.configure(radar_config)
        except BaseException:
            radar.close()
            raise
        record_path = Path(out_dir) / LIVE_LOG
        return LiveTiReader(radar, radar_config, config, record_path, duration_s, live_camera)

    return run_reader(
        open_reader, source, config, out_dir, on_progress, rerun_path, overwrite, rerun_spawn
    )
