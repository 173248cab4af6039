"""``localization.png``: the particles and the trajectory over the saved map."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smokyslam.geometry import GridSpec
from smokyslam.mapping.render import map_picture
from smokyslam.types import GroundTruthTrajectory


def plot_localization(
    path: Path | str,
    cells: np.ndarray,
    spec: GridSpec,
    poses_map_base: np.ndarray,
    first_particles: np.ndarray | None,
    last_particles: np.ndarray,
    truth: GroundTruthTrajectory | None,
    title: str,
) -> Path:
    """The map (black walls, white free, grey unknown), the particles after the first scan and
    at the end, the true path (grey) and the filter's mean path (red), its start and end
    marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    image, canvas = map_picture(cells, spec)
    x0, x1, y0, y1 = canvas.extent_m
    width = 7.0
    fig, ax = plt.subplots(figsize=(width, max(3.0, width * (y1 - y0) / max(x1 - x0, 1e-6))))
    ax.imshow(image, origin="lower", extent=canvas.extent_m, interpolation="nearest")
    if first_particles is not None and len(first_particles):
        first_xy = first_particles[:, :2].T
        ax.scatter(*first_xy, s=1, color="#f0a000", alpha=0.3, label="particles, first scan")
    ax.scatter(*last_particles[:, :2].T, s=2, color="#00a0a0", alpha=0.6, label="particles, end")
    if truth is not None:
        ax.plot(*truth.poses_world_base[:, :2].T, color="0.45", lw=1.2, label="ground truth")
    poses = np.asarray(poses_map_base, dtype=float).reshape(-1, 3)
    if len(poses):
        ax.plot(*poses[:, :2].T, color="tab:red", lw=1.0, label="localized (mean)")
        ax.plot(*poses[0, :2], "o", color="tab:red", ms=4)
        ax.plot(*poses[-1, :2], "s", color="tab:red", ms=4)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="best", fontsize=7, markerscale=4)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
