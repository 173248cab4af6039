"""``smokyslam localize``: find the rig in a saved map, with the run loop's stages.

The table of contents of :func:`localize_reader`: claim the output folder and write the
effective config; load the map (up-sampled first when it is as sparse as a stitched radar
map, ``localize/map_prior.py``) and build its likelihood field; open the reader (a log, or
live sensors: ``pipelines/live.py``); resolve the start (a pose, a pose offset from the
truth, or none: global); run the one loop with radar odometry's stages (and the camera's,
for the motion steps) plus the localizer; write ``trajectory.tum`` (map frame, the log's
clock), ``metrics.json`` and ``localization.png``; finish the recording.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from smokyslam.backends.camera_factors import CameraFactorMaker, get_camera_factor_maker
from smokyslam.backends.scale import SharedScale
from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError, RunFailedError, RunInterruptedError, TopicError
from smokyslam.evaluation.trajectory_io import write_tum
from smokyslam.frontends.readers.base import LogReader
from smokyslam.frontends.readers.registry import config_for_log, open_log
from smokyslam.geometry import interpolate_se2, se2_compose
from smokyslam.localize.evaluation import localization_metrics
from smokyslam.localize.likelihood import LikelihoodField
from smokyslam.localize.map_prior import localization_map
from smokyslam.localize.mcl import MonteCarloLocalizer
from smokyslam.localize.plot import plot_localization
from smokyslam.localize.stage import LocalizationTrack, Localizer, LocalizeStart
from smokyslam.mapio import load_map
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.loop import RunLoop
from smokyslam.pipelines.sources import Source, build_stages
from smokyslam.pipelines.worker_process import DeferredCtrlC
from smokyslam.types import RadarScan
from smokyslam.viz.recorder import RecordingSetup, open_recorder

logger = logging.getLogger(__name__)

SOURCE = Source("scan-matching", "factors", False, ("radar",))
"""The run loop's stages the localizer rides on: radar odometry gives its motion steps, and
the camera, where the log has one and ``localize.camera_motion`` is on, joins them."""


@dataclass(frozen=True)
class StartRequest:
    """What the user asked for: ``init`` a map pose (x, y, yaw_rad), ``init_offset`` a pose
    offset from the ground-truth start (for evaluation), or neither (global)."""

    init: np.ndarray | None = None
    init_offset: np.ndarray | None = None


@dataclass
class LocalizeResult:
    out_dir: Path
    metrics: dict[str, Any]
    track: LocalizationTrack


def localize_log(
    map_yaml: Path | str,
    log_path: Path | str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    request: StartRequest,
    on_progress: Callable[[float, str], None] | None = None,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
    overwrite: bool = False,
) -> LocalizeResult:
    """Localize the log's radar frames in the map at ``map_yaml``; outputs in ``out_dir``."""
    config = config_for_log(log_path, config)
    return localize_reader(
        map_yaml,
        lambda: open_log(log_path, config, require=SOURCE.requires),
        config,
        out_dir,
        request,
        on_progress,
        rerun_path,
        rerun_spawn,
        overwrite,
    )


def localize_reader(
    map_yaml: Path | str,
    open_reader: Callable[[], LogReader],
    config: SmokySlamConfig,
    out_dir: Path | str,
    request: StartRequest,
    on_progress: Callable[[float, str], None] | None = None,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
    overwrite: bool = False,
) -> LocalizeResult:
    """:func:`localize_log` over the reader ``open_reader()`` returns (a log, or live
    sensors), opened once the map is loaded and the output folder claimed."""
    started = time.perf_counter()
    config = config.model_copy(deep=True)
    config.upsample.method = "none"  # the localizer needs no dense map of the new walk
    config.slam.camera_factors = config.localize.camera_motion  # the camera stage, for it
    config.slam.visual_map = False
    saved = load_map(map_yaml)
    used = localization_map(saved.cells, saved.spec, config, saved.unknown)
    if used.implicit_walls:
        logger.info(
            "%s: a floor plan that draws no walls (its unknown is solid): %d cells where its "
            "free space meets unknown are walls ('unknown: unobserved' in its YAML: none)",
            map_yaml,
            used.implicit_walls,
        )
    field = LikelihoodField(used.cells, saved.spec, config.localize)  # an empty map: now
    with OutputFolder(out_dir, overwrite=overwrite) as out, out.interrupt_kept():
        out.write_config(config)
        reader = open_reader()
        truth, gt_map = reader.ground_truth_trajectory(), reader.ground_truth_map()
        start = _resolve_start(request, reader, config)
        extrinsics = reader.extrinsics()
        recorder = open_recorder(rerun_path, config.recording, rerun_spawn)
        recorder.start(
            RecordingSetup("localize", extrinsics, None, reader.log_time_s, truth, gt_map)
        )
        stages = build_stages(SOURCE, reader, config, recorder)
        radar_on_base = stages.radar.pose_base_radar[:2]  # where the points' rays start
        mcl = MonteCarloLocalizer(field.seen_from(radar_on_base), config.localize)
        camera = None
        if stages.camera is not None:  # radar frames' steps, at the scale of SLAM's keyframes
            scale = SharedScale(stages.backend.camera_scale)
            # Whole metric steps, as localization was measured with (docs/localization.md);
            # SLAM's default yaw factors are not measured here yet.
            camera = get_camera_factor_maker(
                config.backend, config.slam, extrinsics.T_base_camera, scale, kind="pose"
            )
        stages.localizer = Localizer(mcl, stages.radar.pose_base_radar, start, camera)
        estimate = RunLoop(stages, on_progress).run(reader.frames(stages.streams))
        with DeferredCtrlC():  # written whole on a first Ctrl-C; a second one stops it
            stamps_s, poses, _, particles = stages.localizer.track.arrays()
            write_tum(out.path("trajectory.tum"), reader.log_time_s(stamps_s), poses)
            if truth is not None:
                write_tum(
                    out.path("ground_truth.tum"),
                    reader.log_time_s(truth.stamps_s),
                    truth.poses_world_base,
                )
            metrics = localization_metrics(stamps_s, poses, particles, truth, config.localize)
            plot_localization(
                out.path("localization.png"),
                used.cells,
                saved.spec,
                poses,
                stages.localizer.first_particles,
                mcl.particles,
                truth,
                _title(start, metrics),
            )
            recorder.log_result(np.zeros(3), stamps_s, poses)  # the map frame is the world's
            recorder.close()
            duration_s = reader.summary().duration_s
            wall_s = time.perf_counter() - started
            extra: dict[str, Any] = {"interrupted": True} if estimate.interrupted else {}
            if estimate.failure:
                extra["failed"] = estimate.failure
            if problems := reader.problems():
                extra["log"] = problems
            everything = out.update_metrics(
                {
                    "localization": {
                        "map": str(Path(map_yaml)),
                        "map_densified": used.densified,
                        "map_isolated_share": used.isolated_share,
                        "map_implicit_walls": used.implicit_walls,
                        "mode": start.mode,
                        "start": _pose_json(start.pose_map_base),
                        **metrics,
                    },
                    "odometry": {
                        "source": "radar" if camera is None else "radar+camera",
                        "lost_frames": int(estimate.lost.sum()),
                        **_camera_steps(camera),
                    },
                    "wall_s": wall_s,
                    "duration_s": duration_s,
                    "realtime_factor": duration_s / wall_s if wall_s > 0 else None,
                    **extra,
                }
            )
    logger.info("localized %d frames of %s in %.1f s", len(stamps_s), reader.path, wall_s)
    if estimate.interrupted:
        raise RunInterruptedError(out.root)
    if estimate.failure:
        raise RunFailedError(estimate.failure, out.root)
    return LocalizeResult(out.root, everything, stages.localizer.track)


def _resolve_start(
    request: StartRequest, reader: LogReader, config: SmokySlamConfig
) -> LocalizeStart:
    sigmas = np.array(
        [
            config.localize.init_sigma_m,
            config.localize.init_sigma_m,
            np.radians(config.localize.init_sigma_deg),
        ]
    )
    if request.init is not None:
        return LocalizeStart(np.asarray(request.init, dtype=float), sigmas)
    if request.init_offset is None:
        return LocalizeStart()
    truth = reader.ground_truth_trajectory()
    if truth is None or len(truth) == 0:
        raise ConfigError(f"{reader.path}: --init-offset needs a log with ground truth")
    # Evaluation only: the offset perturbs the true pose at the first radar frame.
    frames = reader.frames(("radar",))
    try:
        first_s = next((f.stamp_s for f in frames if isinstance(f, RadarScan)), None)
    finally:
        frames.close()
    if first_s is None:
        raise TopicError(f"{reader.path}: the log has no radar scan to localize")
    true_start = interpolate_se2(truth.stamps_s, truth.poses_world_base, first_s).reshape(3)
    offset = np.asarray(request.init_offset, dtype=float)
    start = true_start.copy()
    start[:2] += offset[:2]  # the offset in the map's axes, not the rig's
    start[2] = se2_compose(true_start, np.array([0.0, 0.0, offset[2]]))[2]
    return LocalizeStart(start, sigmas)


def _camera_steps(camera: CameraFactorMaker | None) -> dict[str, Any]:
    """``camera_steps``: the radar frames whose motion step the camera joined (``used``), and
    why the others went without it (as ``metrics.json`` ``camera_pairs`` of a fused run)."""
    if camera is None:
        return {}
    outcomes = ("used", "untracked", "gated", "no_scale", "inconsistent")
    return {"camera_steps": {key: camera.outcomes.get(key, 0) for key in outcomes}}


def _pose_json(pose: np.ndarray | None) -> dict[str, float] | None:
    if pose is None:
        return None
    return {"x_m": float(pose[0]), "y_m": float(pose[1]), "yaw_deg": float(np.degrees(pose[2]))}


def _title(start: LocalizeStart, metrics: dict[str, Any]) -> str:
    title = f"localization ({start.mode}), {metrics['frames']} frames"
    if metrics.get("converge_time_s") is not None:
        after = metrics["after_convergence"]
        title += (
            f"\nconverged after {metrics['converge_time_s']:.1f} s; then position RMSE "
            f"{after['position_rmse_m']:.2f} m, median yaw error {after['yaw_median_deg']:.1f} deg"
        )
    elif "all" in metrics:
        title += "\nnot converged"
    return title
