"""A PNG of an estimated trajectory over the ground truth (path, and map when known)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smokyslam.evaluation.trajectory_metrics import TrajectoryMetrics
from smokyslam.types import GroundTruthMap, GroundTruthTrajectory


def plot_trajectory(
    path: Path | str,
    source: str,
    poses_world_base: np.ndarray,
    lost: np.ndarray,
    truth: GroundTruthTrajectory | None = None,
    metrics: TrajectoryMetrics | None = None,
    gt_map: GroundTruthMap | None = None,
) -> Path:
    """Draw (N, 3) base_link poses (already in the ground-truth frame when there is one) over
    the true path and, when given, the true occupancy grid; (N,) ``lost`` frames are marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    estimate = np.asarray(poses_world_base, dtype=float).reshape(-1, 3)
    fig, ax = plt.subplots(figsize=(7, 7), dpi=110)
    if gt_map is not None:
        occupied = np.where(gt_map.cells == 100, 1.0, np.where(gt_map.cells == 0, 0.0, 0.5))
        ax.imshow(occupied, cmap="Greys", origin="lower", extent=gt_map.spec.extent_m, alpha=0.6)
    title = f"{source} odometry, {len(estimate)} frames"
    if truth is not None:
        gt = truth.poses_world_base
        ax.plot(gt[:, 0], gt[:, 1], color="0.3", lw=1.0, label="ground truth")
    if metrics is not None:
        title += (
            f"\nATE {metrics.ate_rmse_m:.2f} m ({metrics.drift_pct:.2f}% of"
            f" {metrics.path_length_m:.0f} m), {metrics.ate_alignment}-aligned"
        )
    ax.plot(estimate[:, 0], estimate[:, 1], color="tab:red", lw=1.0, label=source)
    lost = np.asarray(lost, dtype=bool)
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
