"""A PNG of an estimated trajectory over the ground truth (trajectory, and map when known)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.evaluation.trajectory_metrics import (
    Alignment,
    TrajectoryMetrics,
    associate,
    umeyama_2d,
)
from smokyslam.types import GroundTruthMap

if TYPE_CHECKING:
    from smokyslam.pipelines.odometry import OdometryRun


def plot_trajectory(
    path: Path | str,
    run: OdometryRun,
    aligned_metrics: TrajectoryMetrics | None = None,
    alignment: Alignment | str = Alignment.SE2,
    gt_map: GroundTruthMap | None = None,
) -> Path:
    """Draw the run's base_link path (aligned onto the ground truth when there is one) over
    the ground-truth path and, when given, the ground-truth occupancy grid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    estimate = run.poses_world_base
    fig, ax = plt.subplots(figsize=(7, 7), dpi=110)
    if gt_map is not None:
        occupied = np.where(gt_map.cells == 100, 1.0, np.where(gt_map.cells == 0, 0.0, 0.5))
        ax.imshow(occupied, cmap="Greys", origin="lower", extent=gt_map.spec.extent_m, alpha=0.6)
    title = f"{run.source} odometry, {len(estimate)} frames"
    if run.has_ground_truth and len(estimate) >= 2:
        inside, gt_at = associate(run.stamps_s, run.gt_stamps_s, run.gt_poses_world_base)
        similarity = umeyama_2d(
            estimate[inside, :2], gt_at[:, :2], with_scale=Alignment(alignment) is Alignment.SIM2
        )
        estimate = similarity.apply(estimate)
        gt = run.gt_poses_world_base
        ax.plot(gt[:, 0], gt[:, 1], color="0.3", lw=1.0, label="ground truth")
        if aligned_metrics is not None:
            title += (
                f"\nATE {aligned_metrics.ate_rmse_m:.2f} m ({aligned_metrics.drift_pct:.2f}% of"
                f" {aligned_metrics.path_length_m:.0f} m), {aligned_metrics.ate_alignment}-aligned"
            )
    ax.plot(estimate[:, 0], estimate[:, 1], color="tab:red", lw=1.0, label=run.source)
    lost = run.lost
    if lost.any():
        ax.plot(estimate[lost, 0], estimate[lost, 1], "x", color="tab:orange", label="lost")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
