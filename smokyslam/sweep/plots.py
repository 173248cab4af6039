"""A sweep's plots: ATE distributions per source and smoke level (``ate_by_source.png``), and
each world's fused / best-single-source ratio (``fused_vs_best.png``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from smokyslam.sweep.results import SweepRow, ratios
from smokyslam.viz.colors import source_color


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_ate_by_source(rows: Sequence[SweepRow], path: Path) -> Path:
    """One box per source in a panel per smoke level (log scale: runs span decades)."""
    plt = _pyplot()
    levels = list(dict.fromkeys(row.row.level.label for row in rows))
    sources = list(dict.fromkeys(row.row.source for row in rows))
    fig, axes = plt.subplots(
        1,
        len(levels),
        figsize=(3.2 * len(levels) + 1.0, 4.0),
        dpi=110,
        squeeze=False,
        sharey=True,
        layout="constrained",
    )
    for ax, level in zip(axes[0], levels, strict=True):
        data = [
            [
                r.ate_m
                for r in rows
                if r.row.level.label == level and r.row.source == s and r.ate_m is not None
            ]
            for s in sources
        ]
        shown = [(s, d) for s, d in zip(sources, data, strict=True) if d]
        if shown:
            boxes = ax.boxplot([d for _, d in shown], patch_artist=True)
            ax.set_xticks(range(1, len(shown) + 1), [s for s, _ in shown], rotation=30)
            for patch, (source, _) in zip(boxes["boxes"], shown, strict=True):
                patch.set_facecolor(np.array(source_color(source)) / 255)
        ax.set_yscale("log")
        ax.set_title(f"smoke {level}", fontsize=9)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("ATE [m] (camera: Sim(2))")
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_fused_vs_best(rows: Sequence[SweepRow], path: Path) -> Path:
    """Per world, the fused run's ATE over the best single source's, one marker per level
    and config; below 1, fusion helped."""
    plt = _pyplot()
    by_row = ratios(rows)
    worlds = list(dict.fromkeys(row.world.name for row in rows))
    fig, ax = plt.subplots(
        figsize=(max(5.0, 0.5 * len(worlds) + 2.0), 4.0), dpi=110, layout="constrained"
    )
    levels = list(dict.fromkeys(row.row.level.label for row in rows))
    for k, level in enumerate(levels):
        xs, ys = [], []
        for i, row in enumerate(rows):
            if (
                row.row.source == "fused"
                and row.row.level.label == level
                and "vs_best" in by_row.get(i, {})
            ):
                xs.append(worlds.index(row.world.name) + 0.1 * (k - len(levels) / 2))
                ys.append(by_row[i]["vs_best"])
        ax.plot(xs, ys, "o", label=f"smoke {level}")
    ax.axhline(1.0, color="0.4", lw=0.8)
    ax.set_xticks(range(len(worlds)), worlds, rotation=45, ha="right", fontsize=7)
    ax.set_ylabel("fused ATE / best single source")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.savefig(path)
    plt.close(fig)
    return path
