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
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.loop import RunEstimate
from smokyslam.types import GroundTruthMap, GroundTruthTrajectory
from smokyslam.viz.rerun_recorder import Recorder

logger = logging.getLogger(__name__)


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
) -> None:
    """Every online map drawn in the output frame as ``maps/NAME.*``; scored (``maps`` in
    ``metrics.json``, and ``maps.NAME.observed`` against the ``observed`` truth) when the log
    has a true map and the run could be aligned to it."""
    path_xy = evaluation.to_truth.apply(estimate.poses_world_base)[:, :2]
    scored = gt_map is not None and evaluation.trajectory is not None
    for name, grid in estimate.maps.render(evaluation.pose_truth_map).items():
        cells = grid.to_cells()
        if out.write_map(name, cells, grid.spec, gt_map, path_xy) is not None and scored:
            scores = map_scores(cells, grid.spec, gt_map, observed)
            out.update_metrics({"maps": {name: scores}})


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
