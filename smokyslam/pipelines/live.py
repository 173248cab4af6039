"""``smokyslam run --live`` and ``localize --live``: the run loop fed by a TI radar instead of a
log.

The radar is configured from its ``.cfg`` once the output folder is claimed; the run records
the stream into ``DIR/live.mcap`` as it goes and writes the usual outputs when the stream ends
(``--duration``, Ctrl-C or a disconnect). A camera (OpenCV source and intrinsics YAML) is
optional; without one, camera-only runs are refused, fused runs go on the radar alone, and
the localizer moves with radar odometry alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.camera import load_camera_intrinsics
from smokyslam.frontends.sensors.live import LiveTiReader
from smokyslam.frontends.sensors.ti_config import load_ti_config
from smokyslam.frontends.sensors.ti_radar import TiRadar
from smokyslam.pipelines.localize import LocalizeResult, StartRequest, localize_reader
from smokyslam.pipelines.run import ProgressCallback, RunResult, run_reader
from smokyslam.pipelines.sources import get_source

LIVE_LOG = "live.mcap"


@dataclass(frozen=True)
class LiveSensors:
    """A TI radar on its CLI and data ports, configured by ``radar_cfg``; optionally a
    ``camera`` (OpenCV device index, URL or video) with its intrinsics YAML ``camera_cfg``;
    ``duration_s``: how long to run (None: until Ctrl-C or a disconnect)."""

    cli_port: str
    data_port: str
    radar_cfg: Path | str
    duration_s: float | None = None
    camera: str | None = None
    camera_cfg: Path | str | None = None

    def opener(self, config: SmokySlamConfig, out_dir: Path | str) -> Callable[[], LiveTiReader]:
        """What opens the reader once the output folder is claimed: configures the radar
        and records the stream into ``out_dir/live.mcap``. Bad options fail here, first."""
        live_camera = None
        if self.camera is not None:
            if self.camera_cfg is None:
                raise ConfigError("--camera needs --camera-cfg (its intrinsics)")
            live_camera = (self.camera, load_camera_intrinsics(self.camera_cfg))
        radar_config = load_ti_config(self.radar_cfg)

        def open_reader() -> LiveTiReader:
            radar = TiRadar(self.cli_port, self.data_port)
            try:
                radar.configure(radar_config)
            except BaseException:
                radar.close()
                raise
            record_path = Path(out_dir) / LIVE_LOG
            return LiveTiReader(
                radar, radar_config, config, record_path, self.duration_s, live_camera
            )

        return open_reader


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
    sensors = LiveSensors(cli_port, data_port, radar_cfg, duration_s, camera, camera_cfg)
    open_reader = sensors.opener(config, out_dir)
    if get_source(source).camera_only and camera is None:
        raise ConfigError("--odometry camera needs --camera and --camera-cfg in a live run")
    return run_reader(
        open_reader, source, config, out_dir, on_progress, rerun_path, overwrite, rerun_spawn
    )


def localize_live(
    map_yaml: Path | str,
    sensors: LiveSensors,
    config: SmokySlamConfig,
    out_dir: Path | str,
    request: StartRequest,
    on_progress: ProgressCallback | None = None,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
    overwrite: bool = False,
) -> LocalizeResult:
    """Localize the live radar (and camera) in the map at ``map_yaml``, as ``localize`` does
    along a log; a live stream has no ground truth, so the start is a pose or global."""
    if request.init_offset is not None:
        raise ConfigError("--init-offset needs a log with ground truth, not a live sensor")
    open_reader = sensors.opener(config, out_dir)
    return localize_reader(
        map_yaml,
        open_reader,
        config,
        out_dir,
        request,
        on_progress,
        rerun_path,
        rerun_spawn,
        overwrite,
    )
