"""What a run writes: trajectory files, maps, metrics and the end of its recording.

Everything is expressed through the run's one alignment (``RunEvaluation.to_truth``): in the
ground-truth frame when the log has ground truth, in the estimate's own frame otherwise.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from smokyslam.evaluation.map_metrics import map_scores
from smokyslam.evaluation.run_evaluation import RunEvaluation
from smokyslam.evaluation.trajectory_io import write_kitti, write_tum
from smokyslam.evaluation.trajectory_plot import plot_trajectory
from smokyslam.fusion.fuse import FUSED_MAP
from smokyslam.fusion.trust import TRUST_SUFFIX, save_trust
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.loop import RunEstimate
from smokyslam.types import GroundTruthMap, GroundTruthTrajectory
from smokyslam.viz.rerun_recorder import Recorder

logger = logging.getLogger(__name__)

UNALIGNED_VISUAL = "visual_unaligned"
"""A camera-only run's visual map in its own frame (``maps/visual_unaligned.*``)."""


def write_trajectory(
    out: OutputFolder,
    source: str,
    estimate: RunEstimate,
    evaluation: RunEvaluation,
    truth: GroundTruthTrajectory | None,
    gt_map: GroundTruthMap | None,
) -> dict[str, Any]:
    """``trajectory.tum``, ``trajectory_kitti.txt``, ``ground_truth.tum``, ``trajectory.png``
    and the ``odometry``, ``trajectory`` and ``alignment`` parts of ``metrics.json``."""
    poses = evaluation.to_truth.apply(estimate.poses_world_base)
    write_tum(out.path("trajectory.tum"), estimate.stamps_s, poses)
    write_kitti(out.path("trajectory_kitti.txt"), poses)
    if truth is not None:
        write_tum(out.path("ground_truth.tum"), truth.stamps_s, truth.poses_world_base)
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
    plot_trajectory(
        out.path("trajectory.png"),
        source,
        poses,
        estimate.lost,
        truth,
        evaluation.trajectory,
        gt_map,
    )
    return out.update_metrics(metrics)


def write_maps(
    out: OutputFolder,
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
    rendered = estimate.maps.render(evaluation.pose_truth_map)
    for name, grid in rendered.items():
        cells = grid.to_cells()
        if out.write_map(name, cells, grid.spec, gt_map, path_xy) is not None and scored:
            scores = map_scores(cells, grid.spec, gt_map, observed)
            out.update_metrics({"maps": {name: scores}})
    if "visual" in rendered and estimate.maps.fuser is not None:
        _write_trust(out, estimate, "visual", rendered["visual"].spec, evaluation.pose_truth_map)
        if keep_unaligned:
            own = estimate.maps.render(np.zeros(3))["visual"]
            out.write_map(UNALIGNED_VISUAL, own.to_cells(), own.spec)
            _write_trust(out, estimate, UNALIGNED_VISUAL, own.spec, np.zeros(3))
    if FUSED_MAP in rendered:
        out.update_metrics({"fusion": rendered[FUSED_MAP].summary()})


def _write_trust(
    out: OutputFolder, estimate: RunEstimate, name: str, spec, T_target_map: np.ndarray
) -> None:
    trust, t_run = estimate.maps.visual_trust(T_target_map, spec)
    save_trust(out.path("maps", f"{name}{TRUST_SUFFIX}"), trust, t_run)
    out.update_metrics({"fusion": {"trust_run": t_run}})


def record_results(
    recorder: Recorder,
    source: str,
    estimate: RunEstimate,
    evaluation: RunEvaluation,
    truth: GroundTruthTrajectory | None,
    gt_map: GroundTruthMap | None,
    out: OutputFolder,
) -> None:
    """The end of the run's recording: where its map frame lies, the final path, the maps and
    the ground truth (or nothing, with the null recorder)."""
    recorder.log_alignment(evaluation.pose_truth_map)
    recorder.log_trajectory(
        source, estimate.stamps_s, evaluation.to_truth.apply(estimate.poses_world_base)
    )
    if truth is not None or gt_map is not None:
        stamps = truth.stamps_s if truth is not None else np.zeros(0)
        poses = truth.poses_world_base if truth is not None else np.zeros((0, 3))
        recorder.log_ground_truth(gt_map, stamps, poses)
    for name, (cells, spec) in out.maps.items():
        recorder.log_map(name, cells, spec)
    recorder.close()
