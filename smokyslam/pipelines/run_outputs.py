"""What a run writes: trajectory files, maps, metrics and the end of its recording.

Everything is expressed through the run's one alignment (``RunEvaluation.to_truth``): in the
ground-truth frame when the log has ground truth, in the estimate's own frame otherwise.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from smokyslam.evaluation.gyro_bias import gyro_bias_metrics
from smokyslam.evaluation.map_metrics import map_scores, score_text
from smokyslam.evaluation.run_evaluation import RunEvaluation
from smokyslam.evaluation.run_plots import plot_error, plot_health
from smokyslam.evaluation.trajectory_io import write_kitti, write_tum
from smokyslam.evaluation.trajectory_plot import plot_trajectory
from smokyslam.frontends.readers.base import LogReader
from smokyslam.fusion.fuse import FUSED_MAP
from smokyslam.fusion.trust import TRUST_SUFFIX, save_trust
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.stages import RunEstimate
from smokyslam.types import GroundTruthMap, GroundTruthTrajectory
from smokyslam.viz.recorder import Recorder

logger = logging.getLogger(__name__)

UNALIGNED_VISUAL = "visual_unaligned"
"""A camera-only run's visual map in its own frame (``maps/visual_unaligned.*``)."""


def write_trajectory(
    out: OutputFolder,
    source: str,
    estimate: RunEstimate,
    evaluation: RunEvaluation,
    truth: GroundTruthTrajectory | None,
    reader: LogReader,
) -> dict[str, Any]:
    """``trajectory.tum``, ``trajectory_kitti.txt``, ``ground_truth.tum`` and the
    ``odometry``, ``trajectory`` and ``alignment`` parts of ``metrics.json``. TUM files are
    stamped on the log's own clock (``reader.log_time_s``), as evo expects."""
    poses = evaluation.to_truth.apply(estimate.poses_world_base)
    write_tum(out.path("trajectory.tum"), reader.log_time_s(estimate.stamps_s), poses)
    write_kitti(out.path("trajectory_kitti.txt"), poses)
    if truth is not None:
        write_tum(
            out.path("ground_truth.tum"), reader.log_time_s(truth.stamps_s), truth.poses_world_base
        )
    metrics: dict[str, Any] = {
        "odometry": {
            "source": source,
            "frames_per_s": estimate.frames_per_s,
            "lost_frames": int(estimate.lost.sum()),
            **estimate.extra,
        },
        **evaluation.metrics(),
        **estimate.graph,
    }
    if estimate.gyro is not None:
        bias = gyro_bias_metrics(
            estimate.gyro,
            truth,
            estimate.extra.get("gyro_bias_degps"),
            estimate.extra.get("graph_gyro_bias_degps"),
        )
        if bias is not None:
            metrics["gyro_bias"] = bias
    return out.update_metrics(metrics)


def write_figures(
    out: OutputFolder,
    source: str,
    estimate: RunEstimate,
    evaluation: RunEvaluation,
    truth: GroundTruthTrajectory | None,
    gt_map: GroundTruthMap | None,
) -> None:
    """``trajectory.png``, ``error.png`` (with ground truth) and ``health.png``. Written after
    every number and map (a run stopped while it draws has lost nothing it computed)."""
    poses = evaluation.to_truth.apply(estimate.poses_world_base)
    plot_trajectory(
        out.path("trajectory.png"),
        source,
        poses,
        estimate.lost,
        truth,
        evaluation.trajectory,
        gt_map,
    )
    if truth is not None and evaluation.trajectory is not None:
        plot_error(out.path("error.png"), source, estimate.stamps_s, poses, estimate.lost, truth)
    plot_health(out.path("health.png"), source, estimate.health)


def write_maps(
    out: OutputFolder,
    source: str,
    estimate: RunEstimate,
    evaluation: RunEvaluation,
    gt_map: GroundTruthMap | None,
    observed: GroundTruthMap | None = None,
    keep_unaligned: bool = False,
) -> None:
    """Every online map drawn in the output frame as ``maps/NAME.*``; scored (``maps`` in
    ``metrics.json``, and ``maps.NAME.observed`` against the ``observed`` truth) when the log
    has a true map and the run could be aligned to it. The visual map's measured trust lies
    beside it (``maps/visual.trust.npz``). ``keep_unaligned``: also the visual map in the
    estimate's own frame, as the camera placed it (``maps/visual_unaligned.*``), for
    registration onto a radar map (``fuse``, ``paper-table``)."""
    path_xy = evaluation.to_truth.apply(estimate.poses_world_base)[:, :2]
    scored = gt_map is not None and evaluation.trajectory is not None
    rendered = {}
    for name, grid in estimate.maps.render_each(evaluation.pose_truth_map):
        rendered[name] = grid
        cells = grid.to_cells()
        scores = map_scores(cells, grid.spec, gt_map, observed) if scored and cells.size else None
        caption = f"{source} run" + (score_text(scores) if scores else "")
        written = out.write_map(name, cells, grid.spec, gt_map, path_xy, caption)
        if written is not None and scores is not None:
            out.update_metrics({"maps": {name: scores}})
    if "visual" in rendered and estimate.maps.fuser is not None:
        _write_trust(out, estimate, "visual", rendered["visual"].spec, evaluation.pose_truth_map)
        if keep_unaligned:
            own = estimate.maps.render(np.zeros(3))["visual"]
            out.write_map(
                UNALIGNED_VISUAL,
                own.to_cells(),
                own.spec,
                trajectory_xy_m=estimate.poses_world_base[:, :2],
                caption=f"{source} run, in its own frame (before registration)",
            )
            _write_trust(out, estimate, UNALIGNED_VISUAL, own.spec, np.zeros(3))
    if FUSED_MAP in rendered:
        out.update_metrics({"fusion": rendered[FUSED_MAP].summary()})


def _write_trust(
    out: OutputFolder, estimate: RunEstimate, name: str, spec, T_target_map: np.ndarray
) -> None:
    trust, t_run = estimate.maps.visual_trust(T_target_map, spec)
    save_trust(out.path("maps", f"{name}{TRUST_SUFFIX}"), trust, t_run)
    out.update_metrics({"fusion": {"trust_run": t_run}})


def record_results(recorder: Recorder, estimate: RunEstimate, evaluation: RunEvaluation) -> None:
    """The end of the run's recording: where its map frame lies in the world, and the final
    path (nothing, with the null recorder)."""
    recorder.log_result(evaluation.pose_truth_map, estimate.stamps_s, estimate.poses_world_base)
    recorder.close()
