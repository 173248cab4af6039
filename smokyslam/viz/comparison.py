"""Several finished runs in one Rerun recording, side by side (``compare --rerun``).

Read from what the runs wrote: each run's ``trajectory.tum`` (the truth frame, the log's
clock) becomes ``world/trajectory/<run>`` (the whole path, in the source's colour) and
``world/position/<run>`` (where it is at each ``sensor_time``); with ground truth,
``error/<run>`` is its distance from the true path over time. The true map and path lie
under ``world/ground_truth``; named maps, as pictures, under ``maps/``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.geometry import GridSpec
from smokyslam.types import GroundTruthMap
from smokyslam.viz.colors import map_rgba, source_color, truth_rgba
from smokyslam.viz.layout import compare_blueprint
from smokyslam.viz.rerun_stream import grid_map, open_stream, path_3d


@dataclass(frozen=True)
class RecordedRun:
    """One run's path: ``stamps_s`` (N,) on the log's clock, ``poses`` (N, 3) truth frame."""

    name: str
    source: str
    stamps_s: np.ndarray
    poses: np.ndarray


def record_runs(
    path: Path | None,
    runs: Sequence[RecordedRun],
    truth: RecordedRun | None,
    gt_map: GroundTruthMap | None,
    spawn: bool = False,
    maps: Mapping[str, tuple[np.ndarray, GridSpec]] | None = None,
) -> Path | None:
    """Write (and/or stream) one recording of every run's path over the truth; ``maps``:
    named trinary maps shown as pictures (``maps/<name>``, e.g. Table I's twelve)."""
    import rerun as rr

    maps = maps or {}
    rec = open_stream(path, spawn, compare_blueprint(list(maps)))
    for name, (cells, _) in maps.items():
        rec.log(f"maps/{name}", rr.Image(np.flipud(map_rgba(cells))), static=True)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    if gt_map is not None:
        rec.log(
            "world/ground_truth/map",
            grid_map(rr, truth_rgba(gt_map.cells), gt_map.spec, -0.01),
            static=True,
        )
    if truth is not None and len(truth.stamps_s):
        rec.log(
            "world/ground_truth/path",
            rr.LineStrips3D([path_3d(truth.poses)], colors=[source_color("ground_truth")]),
            static=True,
        )
    for index, run in enumerate(runs):
        if not len(run.stamps_s):
            continue
        color = source_color(run.name, index)
        rec.log(
            f"world/trajectory/{run.name}",
            rr.LineStrips3D([path_3d(run.poses)], colors=[color], radii=0.02),
            static=True,
        )
        times = [rr.TimeColumn("sensor_time", timestamp=run.stamps_s)]
        rec.send_columns(
            f"world/position/{run.name}",
            indexes=times,
            columns=rr.Points3D.columns(positions=path_3d(run.poses)),
        )
        rec.log(
            f"world/position/{run.name}",
            rr.Points3D.from_fields(colors=[color], radii=0.12),
            static=True,
        )
        if truth is not None and len(truth.stamps_s):
            error_m = _error_m(run, truth)
            rec.send_columns(
                f"error/{run.name}", indexes=times, columns=rr.Scalars.columns(scalars=error_m)
            )
            rec.log(
                f"error/{run.name}", rr.SeriesLines(colors=[color], names=run.name), static=True
            )
    rec.flush()
    if path is not None:
        rec.disconnect()
    return path


def _error_m(run: RecordedRun, truth: RecordedRun) -> np.ndarray:
    """(N,) metres from the true position at each of the run's stamps (NaN outside it)."""
    x = np.interp(run.stamps_s, truth.stamps_s, truth.poses[:, 0], left=np.nan, right=np.nan)
    y = np.interp(run.stamps_s, truth.stamps_s, truth.poses[:, 1], left=np.nan, right=np.nan)
    return np.hypot(run.poses[:, 0] - x, run.poses[:, 1] - y)
