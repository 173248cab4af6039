"""The files of ``paper-table``: ``table.csv``, ``table.md`` and the figure of its 12 maps."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, MapImage
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap

CSV_COLUMNS = ("map_index", "name", "error_index", "occupied_f1", "paper_error_index")


@dataclass
class TableRow:
    """One map of Table I; ``error_index`` and ``occupied_f1`` are None when the map could not
    be made (e.g. the visual map could not be registered), ``trust`` only on fused rows."""

    map_index: int
    name: str
    error_index: float | None
    occupied_f1: float | None
    paper_error_index: float
    trust: float | None = None


def _number(value: float | None) -> str:
    return "" if value is None else f"{value:.3f}"


def fused_ratios(rows: list[TableRow]) -> dict[int, float | None]:
    """Per fused row (10-12): its error index over the better (lower) of its two inputs'."""
    by_index = {row.map_index: row for row in rows}
    ratios = {}
    for index in (10, 11, 12):
        inputs = [by_index[index - 6].error_index, by_index[index - 3].error_index]
        fused = by_index[index].error_index
        ok = fused is not None and None not in inputs and min(inputs) > 0
        ratios[index] = fused / min(inputs) if ok else None
    return ratios


def write_table(out_dir: Path, rows: list[TableRow], truth_name: str, log_path: Path) -> None:
    """``table.csv`` (the contract's columns) and ``table.md`` (with the trust used and the
    fused rows' ratios to their better input)."""
    with (out_dir / "table.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CSV_COLUMNS)
        for row in rows:
            writer.writerow(
                [
                    row.map_index,
                    row.name,
                    _number(row.error_index),
                    _number(row.occupied_f1),
                    f"{row.paper_error_index:.3f}",
                ]
            )
    ratios = fused_ratios(rows)
    lines = [
        f"# Table I on {log_path.name}",
        "",
        f"Scored against the {truth_name} ground truth; error index = mean((truth - map)^2).",
        "",
        "| map | name | error index | occupied F1 | paper's error index | trust t | fused / "
        "better input |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        ratio = ratios.get(row.map_index)
        lines.append(
            f"| {row.map_index} | {row.name} | {_number(row.error_index)} | "
            f"{_number(row.occupied_f1)} | {row.paper_error_index:.3f} | "
            f"{_number(row.trust)} | {_number(ratio)} |"
        )
    lines.append("")
    (out_dir / "table.md").write_text("\n".join(lines))


def plot_table_maps(
    path: Path, rows: list[TableRow], maps: dict[int, MapImage | None], truth: GroundTruthMap
) -> Path:
    """One figure of the 12 maps (rows: sparse, up-sampled, visual, fused; columns: the three
    smoke levels) on the truth's grid, true walls in red beneath."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec: GridSpec = truth.spec
    x0, x1, y0, y1 = spec.extent_m
    fig, axes = plt.subplots(4, 3, figsize=(12, 12 * spec.shape[0] / spec.shape[1] + 1.5))
    for row, ax in zip(rows, axes.ravel(), strict=True):
        image = np.full((*spec.shape, 3), 0.8)
        image[truth.cells == OCCUPIED] = (1.0, 0.75, 0.75)
        found = maps.get(row.map_index)
        if found is not None:
            cells = resample_nearest(found.cells, found.spec, spec, -1)
            image[cells == FREE] = 1.0
            image[cells == OCCUPIED] = 0.0
        ax.imshow(image, origin="lower", extent=(x0, x1, y0, y1))
        score = "no map" if row.error_index is None else f"E = {row.error_index:.3f}"
        ax.set_title(
            f"{row.map_index}: {row.name}\n{score} (paper {row.paper_error_index})", fontsize=7
        )
        ax.tick_params(labelsize=6)
    fig.suptitle("Table I maps: black occupied, white free, grey unknown, pink true walls")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
