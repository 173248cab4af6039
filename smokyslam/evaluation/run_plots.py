"""A run's plots over time: its error against the truth (``error.png``) and the health of its
odometry and camera (``health.png``), matplotlib, headless."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from smokyslam.evaluation.trajectory_metrics import associate
from smokyslam.types import GroundTruthTrajectory

if TYPE_CHECKING:
    from smokyslam.pipelines.health import RunHealth


def position_errors_m(
    stamps_s: np.ndarray, poses_truth_frame: np.ndarray, truth: GroundTruthTrajectory
) -> tuple[np.ndarray, np.ndarray]:
    """((M,) stamps inside the truth's span, (M,) metres from the true position there) of
    (N, 3) poses already in the truth frame."""
    inside, gt = associate(stamps_s, truth.stamps_s, truth.poses_world_base)
    poses = np.asarray(poses_truth_frame, dtype=float).reshape(-1, 3)[inside]
    return np.asarray(stamps_s, dtype=float)[inside], np.hypot(*(poses[:, :2] - gt[:, :2]).T)


def _figure(rows: int):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        rows, 1, figsize=(7.0, 1.2 + 1.8 * rows), dpi=110, sharex=True, layout="constrained"
    )
    return plt, fig, np.atleast_1d(axes)


def plot_error(
    path: Path | str,
    source: str,
    stamps_s: np.ndarray,
    poses_truth_frame: np.ndarray,
    lost: np.ndarray,
    truth: GroundTruthTrajectory,
) -> Path:
    """Position error over time (seconds from the log start), lost frames marked."""
    path = Path(path)
    t_s, error_m = position_errors_m(stamps_s, poses_truth_frame, truth)
    plt, fig, (ax,) = _figure(1)
    ax.plot(t_s, error_m, color="tab:red", lw=1.0, label=f"{source} position error")
    lost = np.asarray(lost, dtype=bool)
    if lost.any():
        lost_s = np.asarray(stamps_s, dtype=float)[lost]
        ax.plot(lost_s, np.zeros(len(lost_s)), "|", color="tab:orange", label="lost frames")
    rmse = float(np.sqrt(np.mean(error_m**2))) if len(error_m) else float("nan")
    ax.set_title(f"{source}: error against ground truth over time (RMSE {rmse:.3f} m)", fontsize=9)
    ax.set_xlabel("time since log start [s]")
    ax.set_ylabel("position error [m]")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_health(path: Path | str, source: str, health: RunHealth) -> Path:
    """The odometry's inliers and loop closures; the camera's tracked features, its measured
    smoke and the trust index t, when the run used a camera."""
    path = Path(path)
    camera = len(health.camera_stamps_s) > 0
    plt, fig, axes = _figure(3 if camera else 1)
    t_s = health.array("stamps_s")
    ax = axes[0]
    ax.plot(t_s, health.array("inliers"), color="tab:blue", lw=0.8, label="odometry inliers")
    lost = health.array("lost") > 0
    if lost.any():
        ax.plot(t_s[lost], np.zeros(lost.sum()), "|", color="tab:orange", label="lost")
    loops = health.array("loop_closures")
    if len(loops) and loops[-1] > 0:
        twin = ax.twinx()
        twin.step(t_s, loops, color="tab:purple", lw=1.0, where="post")
        twin.set_ylabel("loop closures", color="tab:purple")
    ax.set_ylabel("inliers")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"{source}: health over time", fontsize=9)
    if camera:
        c_s = health.array("camera_stamps_s")
        axes[1].plot(c_s, health.array("camera_tracked"), color="tab:green", lw=0.8)
        axes[1].set_ylabel("camera features\ntracked")
        axes[2].plot(c_s, health.array("trust_index"), color="tab:red", lw=1.0, label="trust t")
        axes[2].plot(
            c_s, health.array("impulse_fraction"), color="0.4", lw=0.8, label="salt & pepper"
        )
        axes[2].plot(c_s, health.array("rms_contrast"), color="tab:cyan", lw=0.8, label="contrast")
        axes[2].set_ylim(-0.02, 1.02)
        axes[2].set_ylabel("smoke, trust")
        axes[2].legend(loc="upper left", fontsize=8, ncols=3)
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time since log start [s]")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
