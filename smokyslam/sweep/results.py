"""A sweep's results: ``sweep.csv`` (one row per run), ``summary.md`` (per world kind, smoke
level and config: each source's ATE median, 90th percentile and worst case, and its ratios
against the best single source and against dead reckoning) and the plots.

The ATE a source is judged by is its rigid SE(2) one, except camera-only runs: their Sim(2)
one (a monocular camera's scale is its own). The best single source of a (world, level,
config) is the better of radar and camera there.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.evaluation.compare_table import COLUMNS, CompareRow, RunStatus
from smokyslam.sweep.spec import World

SWEEP_COLUMNS = (
    "world",
    "kind",
    "seed",
    "config",
    *(c for c in COLUMNS if c not in ("status", "error")),
    "status",
    "log",
    "run_dir",
)
SINGLE_SOURCES = ("radar", "camera")


@dataclass(frozen=True)
class SweepRow:
    """One run of a sweep: its world, its config's name and its compare row."""

    world: World
    config: str
    row: CompareRow

    @property
    def ate_m(self) -> float | None:
        """The ATE the source is judged by (camera-only: Sim(2)); None when it failed."""
        trajectory = self.row.metrics.get("trajectory", {})
        key = "ate_sim2_rmse_m" if self.row.source == "camera" else "ate_rmse_m"
        value = trajectory.get(key, trajectory.get("ate_rmse_m"))
        return float(value) if self.row.ok and value is not None else None

    @property
    def group(self) -> tuple[str, str, str]:
        """(world, smoke level, config): the runs that are compared with each other."""
        return (self.world.name, self.row.level.label, self.config)

    def values(self, out_dir: Path) -> dict[str, object]:
        values = self.row.values()
        status = self.row.status.value
        if self.row.status is RunStatus.FAILED:
            status += f": {self.row.error}"
        return {
            **values,
            "world": self.world.name,
            "kind": self.world.kind,
            "seed": "" if self.world.seed is None else self.world.seed,
            "config": self.config,
            "status": status,
            "log": _relative(self.world.log_path(out_dir), out_dir),
            "run_dir": _relative(self.row.run_dir, out_dir),
        }


def _relative(path: Path, out_dir: Path) -> str:
    """``path`` relative to the sweep's folder (``..`` for a log given from elsewhere)."""
    return os.path.relpath(Path(path).resolve(), out_dir.resolve())


def write_csv(rows: Sequence[SweepRow], out_dir: Path) -> Path:
    path = out_dir / "sweep.csv"
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(SWEEP_COLUMNS)
        for row in rows:
            values = row.values(out_dir)
            writer.writerow(["" if values[c] is None else values[c] for c in SWEEP_COLUMNS])
    return path


def ratios(rows: Sequence[SweepRow]) -> dict[int, dict[str, float]]:
    """Per row (by index): ``vs_best`` (its ATE over the best single source's in its group)
    and ``vs_dead_reckoning``, where those exist."""
    groups: dict[tuple[str, str, str], dict[str, float]] = {}
    for row in rows:
        if row.ate_m is not None:
            groups.setdefault(row.group, {})[row.row.source] = row.ate_m
    out: dict[int, dict[str, float]] = {}
    for i, row in enumerate(rows):
        if row.ate_m is None:
            continue
        group = groups[row.group]
        singles = [group[s] for s in SINGLE_SOURCES if s in group]
        entry = {}
        if singles and min(singles) > 0:
            entry["vs_best"] = row.ate_m / min(singles)
        if group.get("dead-reckoning", 0.0) > 0:
            entry["vs_dead_reckoning"] = row.ate_m / group["dead-reckoning"]
        out[i] = entry
    return out


def _stats(values: list[float]) -> str:
    if not values:
        return "– | – | –"
    array = np.asarray(values)
    return f"{np.median(array):.3f} | {np.percentile(array, 90):.3f} | {array.max():.3f}"


def write_summary(rows: Sequence[SweepRow], out_dir: Path, title: str) -> Path:
    """``summary.md``: a table per smoke level, a row per (world kind, config, source)."""
    by_row = ratios(rows)
    failed = [row for row in rows if not row.row.ok]
    lines = [f"# {title}", ""]
    lines.append(f"{len(rows)} runs, {len(failed)} failed. ATE in metres (camera: Sim(2)).")
    lines.append("Ratios: a run's ATE over its group's best single source (radar, camera)")
    lines.append("and over dead reckoning; median / 90th percentile / worst over the runs.")
    levels = list(dict.fromkeys(row.row.level.label for row in rows))
    for level in levels:
        lines += ["", f"## smoke {level}", ""]
        lines.append(
            "| kind | config | source | runs | ATE median | p90 | worst "
            "| vs best median | p90 | worst | vs dead reckoning median | p90 | worst |"
        )
        lines.append("|" + "---|" * 13)
        keys = dict.fromkeys(
            (row.world.kind, row.config, row.row.source)
            for row in rows
            if row.row.level.label == level
        )
        for kind in [*dict.fromkeys(k[0] for k in keys), "all"]:
            for config, source in dict.fromkeys((k[1], k[2]) for k in keys):
                chosen = [
                    i
                    for i, row in enumerate(rows)
                    if row.row.level.label == level
                    and row.config == config
                    and row.row.source == source
                    and kind in ("all", row.world.kind)
                ]
                if not chosen:
                    continue
                ate = [rows[i].ate_m for i in chosen if rows[i].ate_m is not None]
                best = [by_row[i]["vs_best"] for i in chosen if "vs_best" in by_row.get(i, {})]
                dr = [
                    by_row[i]["vs_dead_reckoning"]
                    for i in chosen
                    if "vs_dead_reckoning" in by_row.get(i, {})
                ]
                lines.append(
                    f"| {kind} | {config} | {source} | {len(chosen)} | {_stats(ate)} | "
                    f"{_stats(best)} | {_stats(dr)} |"
                )
    lines += _step_lines(rows)
    if failed:
        lines += ["", "## Failed runs", ""]
        lines += [f"- `{_relative(r.row.run_dir, out_dir)}`: {r.row.error}" for r in failed]
    path = out_dir / "summary.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _step_lines(rows: Sequence[SweepRow]) -> list[str]:
    """The fused runs' per-step precision of each source (``step_errors`` in their metrics)
    and the share of keyframe pairs the camera joined: medians per smoke level, kind, config."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for row in rows:
        metrics = row.row.metrics
        if row.row.source == "fused" and row.row.ok and "step_errors" in metrics:
            key = (row.row.level.label, row.world.kind, row.config)
            groups.setdefault(key, []).append(metrics)
    if not groups:
        return []
    lines = ["", "## Per-step precision of the fused runs' two sources", ""]
    lines.append("Every keyframe pair's radar and camera step against the true motion (the")
    lines.append("camera's before its consistency check), medians over the runs; joined: the")
    lines.append("share of keyframe pairs that got a camera factor.")
    lines.append("")
    lines.append(
        "| smoke | kind | config | runs | radar mm | camera mm | radar yaw deg "
        "| camera yaw deg | camera joined |"
    )
    lines.append("|" + "---|" * 9)
    for (level, kind, config), group in groups.items():
        steps = [m["step_errors"] for m in group]
        joined = [
            m["camera_pairs"].get("used", 0) / total
            for m in group
            if (total := sum(m.get("camera_pairs", {}).values()))
        ]
        lines.append(
            f"| {level} | {kind} | {config} | {len(group)} "
            f"| {_median(steps, 'radar', 'translation_rms_m', 1e3)} "
            f"| {_median(steps, 'camera', 'translation_rms_m', 1e3)} "
            f"| {_median(steps, 'radar', 'yaw_rms_deg')} "
            f"| {_median(steps, 'camera', 'yaw_rms_deg')} "
            f"| {f'{np.median(joined):.0%}' if joined else '–'} |"
        )
    return lines


def _median(steps: list[dict], source: str, key: str, scale: float = 1.0) -> str:
    """The median of ``step_errors[source][key]`` over runs, times ``scale``, as text."""
    return f"{scale * float(np.median([s[source][key] for s in steps])):.2f}"
