"""PNGs of a ``smokyslam compare``: every source's trajectory per smoke level, and ATE per level.

Both read only what the runs wrote (``trajectory.tum``, ``ground_truth.tum``, ``metrics.json``
as carried by the rows), so they can be redrawn from a finished comparison.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from smokyslam.errors import SmokySlamError
from smokyslam.evaluation.compare_table import CompareRow
from smokyslam.evaluation.trajectory_io import read_tum
from smokyslam.types import GroundTruthMap

SOURCE_COLOURS = {
    "camera": "tab:blue",
    "radar": "tab:red",
    "dead-reckoning": "tab:orange",
    "fused": "tab:green",
}
_OTHER_COLOURS = ("tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
_HAZE_STYLES = (("-", "o"), ("--", "s"), (":", "^"), ("-.", "D"))
_MARGIN_M = 1.5
_PANEL_W = 5.0  # inches
_LEGEND_H = 0.4


def _colour(source: str, sources: list[str]) -> str:
    others = [s for s in sources if s not in SOURCE_COLOURS]
    if source in SOURCE_COLOURS:
        return SOURCE_COLOURS[source]
    return _OTHER_COLOURS[others.index(source) % len(_OTHER_COLOURS)]


def _unique(values: list[str]) -> list[str]:
    return list(dict.fromkeys(values))


def run_paths(row: CompareRow) -> tuple[np.ndarray, np.ndarray | None]:
    """The run's (N, 3) path as written (in the ground-truth frame when the log has ground
    truth, see ``evaluation/run_evaluation.py``) and the (M, 3) ground truth, or None."""
    _, poses = read_tum(row.run_dir / "trajectory.tum")
    gt_path = row.run_dir / "ground_truth.tum"
    return poses, read_tum(gt_path)[1] if gt_path.is_file() else None


def plot_trajectories(
    path: Path | str, rows: list[CompareRow], gt_map: GroundTruthMap | None = None
) -> Path:
    """One panel per smoke level (a row of panels per haze value): the ground-truth map and
    path, and every successful run's base_link path, coloured by source. All panels
    share the view: the paths' bounding box plus a margin, the map drawn underneath."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    sources = _unique([row.source for row in rows])
    smoke_labels = _unique([row.level.smoke_label for row in rows])
    hazes = _unique([row.level.haze_text for row in rows])
    paths = [_load(row) for row in rows]
    drawn = [xy for p in paths if not isinstance(p, str) for xy in p if xy is not None]
    low, high = np.zeros(2), np.ones(2)
    if drawn:
        xy = np.concatenate([poses[:, :2] for poses in drawn])
        low, high = xy.min(axis=0) - _MARGIN_M, xy.max(axis=0) + _MARGIN_M
    panel_h = float(np.clip(_PANEL_W * (high[1] - low[1]) / (high[0] - low[0]), 2.0, 7.0))
    nrows, ncols = max(1, len(hazes)), max(1, len(smoke_labels))
    fig, axes = plt.subplots(
        nrows, ncols, figsize=(_PANEL_W * ncols, (panel_h + 1.0) * nrows + _LEGEND_H), squeeze=False
    )
    for ax in axes.flat:
        ax.set_axis_off()
    for h, haze in enumerate(hazes):
        for s, smoke in enumerate(smoke_labels):
            panel = [
                (row, loaded)
                for row, loaded in zip(rows, paths, strict=True)
                if (row.level.haze_text, row.level.smoke_label) == (haze, smoke)
            ]
            if panel:
                _draw_panel(axes[h, s], panel, gt_map, sources)
                axes[h, s].set_xlim(low[0], high[0])
                axes[h, s].set_ylim(low[1], high[1])
    # One legend for the figure: every panel draws the same sources in the same colours.
    handles: dict[str, object] = {}
    for ax in axes.flat:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=len(handles), fontsize=8)
    fig.tight_layout(rect=(0, _LEGEND_H / fig.get_figheight(), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def _load(row: CompareRow) -> tuple[np.ndarray, np.ndarray | None] | str:
    """The row's path and ground truth, or why there is none."""
    if not row.ok:
        return "failed"
    try:
        return run_paths(row)
    except SmokySlamError as exc:
        return str(exc)


def _draw_panel(
    ax,
    panel: list[tuple[CompareRow, tuple[np.ndarray, np.ndarray | None] | str]],
    gt_map: GroundTruthMap | None,
    sources: list[str],
) -> None:
    """One smoke level: the true map and path, then each run (failed ones named only)."""
    ax.set_axis_on()
    if gt_map is not None:
        shade = np.where(gt_map.cells == 100, 1.0, np.where(gt_map.cells == 0, 0.0, 0.3))
        ax.imshow(shade, cmap="Greys", origin="lower", extent=gt_map.spec.extent_m, alpha=0.6)
    truth_drawn = False
    scores = []
    for row, loaded in panel:
        colour = _colour(row.source, sources)
        if isinstance(loaded, str):
            scores.append(f"{row.source} {loaded}")
            continue
        poses, gt_poses = loaded
        if gt_poses is not None and not truth_drawn:
            ax.plot(gt_poses[:, 0], gt_poses[:, 1], color="0.2", lw=1.2, label="ground truth")
            truth_drawn = True
        ax.plot(poses[:, 0], poses[:, 1], color=colour, lw=1.0, label=row.source)
        ate = row.metrics.get("trajectory", {}).get("ate_rmse_m")
        scores.append(f"{row.source} {ate:.2f} m" if ate is not None else row.source)
    ax.set_aspect("equal")
    ax.set_title(f"{panel[0][0].level.label}\nATE: " + ", ".join(scores), fontsize=8)
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.tick_params(labelsize=7)


def plot_ate_vs_smoke(path: Path | str, rows: list[CompareRow]) -> Path:
    """ATE (m) and lost frames (%) against the smoke level, one line per source (dashed and
    dotted for each haze value); failed runs and runs without ground truth leave gaps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    sources = _unique([row.source for row in rows])
    smoke_labels = _unique([row.level.smoke_label for row in rows])
    hazes = _unique([row.level.haze_text for row in rows])
    ticks = _unique([f"{r.level.radar_loss_text}:{r.level.camera_noise_text}" for r in rows])
    fig, (ate_ax, lost_ax) = plt.subplots(
        2, 1, figsize=(max(6.0, 1.6 * len(smoke_labels) + 3), 7), dpi=100, sharex=True
    )
    x = np.arange(len(smoke_labels))
    for source in sources:
        for h, haze in enumerate(hazes):
            ate, lost = np.full(len(x), np.nan), np.full(len(x), np.nan)
            for row in rows:
                if row.source != source or row.level.haze_text != haze:
                    continue
                trajectory = row.metrics.get("trajectory") or {}
                i = smoke_labels.index(row.level.smoke_label)
                ate[i] = _number(trajectory.get("ate_rmse_m"))
                frames = _number(trajectory.get("frames"))
                lost[i] = (
                    100.0 * _number(trajectory.get("lost_frames")) / frames if frames else np.nan
                )
            linestyle, marker = _HAZE_STYLES[h % len(_HAZE_STYLES)]
            style = dict(
                color=_colour(source, sources),
                linestyle=linestyle,
                marker=marker,
                label=source + (f", haze {haze}" if haze else ""),
            )
            ate_ax.plot(x, ate, **style)
            lost_ax.plot(x, lost, **style)
    ate_ax.set_ylabel("ATE RMSE [m]")
    ate_ax.set_title("trajectory error and tracking against smoke", fontsize=10)
    lost_ax.set_ylabel("lost frames [%]")
    lost_ax.set_xticks(x, ticks)
    lost_ax.set_xlabel("smoke level, radar loss : camera noise")
    ate_ax.set_ylim(bottom=0)
    lost_ax.set_ylim(-2, 102)
    for ax in (ate_ax, lost_ax):
        ax.grid(True, alpha=0.3)
    ate_ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def _number(value: object) -> float:
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else np.nan
