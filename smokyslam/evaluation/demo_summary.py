"""The demo's closing page, ``summary.md``: what a newcomer reads first."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from smokyslam.evaluation.compare_table import CompareRow, markdown_table


def write_summary(
    path: Path,
    title: str,
    rows: Sequence[CompareRow],
    truth_map_metrics: dict[str, Any],
    recording: Path | None,
) -> Path:
    """``summary.md``: every source's numbers (as ``compare.md``), the radar map built on the
    true poses (the best a radar map of this walk can do), how much the camera counted in the
    fused run, where the pictures are, and how to open the recording."""
    root = path.parent
    lines = [f"# {title}", "", "## Every source", "", markdown_table(rows)]
    lines += ["Every path over the true map: [trajectories.png](trajectories.png).", ""]
    lines += ["## The radar map on ground-truth poses", ""]
    for name, scores in truth_map_metrics.get("maps", {}).items():
        line = (
            f"- `{name}`: error index {scores['error_index']:.3f}, F1 {scores['occupied_f1']:.3f}"
        )
        if "observed" in scores:
            line += (
                f" (against what a lidar saw on the walk: {scores['observed']['error_index']:.3f})"
            )
        lines.append(line)
    fused = next((row for row in rows if row.source == "fused" and row.ok), None)
    if fused is not None:
        factors = fused.metrics.get("factors", {})
        pairs = fused.metrics.get("camera_pairs", {})
        lines += ["", "## How much the camera counted", ""]
        lines.append(
            f"The fused run used {factors.get('camera', 0)} camera factors "
            f"({', '.join(f'{k} {v}' for k, v in pairs.items()) or 'no camera pairs'}), "
            f"{factors.get('radar', 0)} radar factors and {factors.get('loop_closure', 0)} "
            "loop closures."
        )
    lines += ["", "## Pictures", ""]
    for row in rows:
        if row.ok:
            folder = row.run_dir.relative_to(root)
            lines.append(
                f"- {row.source}: [path]({folder}/trajectory.png), [error]({folder}/error.png), "
                f"[health]({folder}/health.png), maps in `{folder}/maps/`"
            )
    if recording is not None:
        lines += ["", "## The recording", ""]
        lines.append(
            f"`{recording.relative_to(root)}` holds the fused run as it went (radar points, "
            "camera images, paths, keyframes, growing maps, health). Open it with "
            f"`smokyslam view {recording}` (or `rerun {recording}`)."
        )
    path.write_text("\n".join(lines) + "\n")
    return path
