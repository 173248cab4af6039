"""The table of a comparison: one row per (source, smoke level) run, as CSV and markdown.

The ``map`` columns score the run's main map: ``visual`` for camera runs, else ``fused`` when
the run wrote one, else ``radar_sparse`` (the first of those present in its
``metrics.json``). ``ate_rmse_m`` is after the run's rigid SE(2) alignment (camera-only runs
are metric through the camera's height); ``ate_sim2_rmse_m`` is after a Sim(2) alignment,
given for camera-only runs.
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from smokyslam.smoke import SmokeLevel

COLUMNS = (
    "source",
    "radar_loss",
    "camera_noise",
    "haze",
    "ate_rmse_m",
    "ate_alignment",
    "drift_pct",
    "lost_frames",
    "realtime_factor",
    "map",
    "map_error_index",
    "map_f1",
    "ate_sim2_rmse_m",
    "status",
    "error",
)
MAIN_MAPS = {"camera": ("visual", "fused", "radar_sparse")}
DEFAULT_MAIN_MAPS = ("fused", "radar_sparse", "visual")


class RunStatus(StrEnum):
    """How a run ended, as written in the table's ``status`` column."""

    OK = "ok"
    FAILED = "failed"
    INTERRUPTED = "interrupted"


@dataclass
class CompareRow:
    """One finished (or failed) run: ``metrics`` as in its ``metrics.json``, empty on failure."""

    source: str
    level: SmokeLevel
    run_dir: Path
    status: RunStatus
    error: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is RunStatus.OK

    def main_map(self) -> str | None:
        """The map this row scores (see the module docstring), or None without one."""
        maps = self.metrics.get("maps", {})
        return next((m for m in MAIN_MAPS.get(self.source, DEFAULT_MAIN_MAPS) if m in maps), None)

    def values(self) -> dict[str, Any]:
        """The row under :data:`COLUMNS`; None where there is no value."""
        trajectory = self.metrics.get("trajectory", {})
        name = self.main_map()
        scores = self.metrics["maps"][name] if name else {}
        return {
            "source": self.source,
            "radar_loss": self.level.radar_loss_text,
            "camera_noise": self.level.camera_noise_text,
            "haze": self.level.haze_text or "0",
            "ate_rmse_m": trajectory.get("ate_rmse_m"),
            "ate_alignment": trajectory.get("ate_alignment"),
            "drift_pct": trajectory.get("drift_pct"),
            "lost_frames": trajectory.get("lost_frames"),
            "realtime_factor": self.metrics.get("realtime_factor"),
            "map": name,
            "map_error_index": scores.get("error_index"),
            "map_f1": scores.get("occupied_f1"),
            "ate_sim2_rmse_m": trajectory.get("ate_sim2_rmse_m"),
            "status": self.status.value,
            "error": self.error,
        }


def _csv_value(value: Any) -> str:
    return "" if value is None else repr(value) if isinstance(value, float) else str(value)


def _markdown_value(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 100 else f"{value:.1f}"
    return str(value).replace("|", "\\|").replace("\n", " ")


def write_tables(rows: Sequence[CompareRow], out_dir: Path) -> tuple[Path, Path]:
    """``compare.csv`` (full precision, empty where missing) and ``compare.md`` (3 decimals)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, markdown_path = out_dir / "compare.csv", out_dir / "compare.md"
    values = [row.values() for row in rows]
    with csv_path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(COLUMNS)
        writer.writerows([_csv_value(v[c]) for c in COLUMNS] for v in values)
    markdown_path.write_text(markdown_table(rows))
    return csv_path, markdown_path


def markdown_table(rows: Sequence[CompareRow]) -> str:
    """The rows as a markdown table (3 decimals), as in ``compare.md``."""
    values = [row.values() for row in rows]
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_markdown_value(v[c]) for c in COLUMNS) + " |" for v in values]
    return "\n".join(lines) + "\n"
