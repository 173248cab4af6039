"""``smokyslam evaluate``: score a saved map against a log's ground truth or another map."""

from __future__ import annotations

from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError, MapFileError
from smokyslam.evaluation.map_metrics import map_scores
from smokyslam.frontends.readers.registry import open_log
from smokyslam.geometry import GridSpec
from smokyslam.mapio import UNKNOWN, load_map
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap


def load_truth(truth_path: Path | str, config: SmokySlamConfig) -> GroundTruthMap:
    """Ground truth from a map YAML, or from the ground-truth map topic of a log."""
    truth_path = Path(truth_path)
    if truth_path.suffix in (".yaml", ".yml"):
        truth = load_map(truth_path)
        return GroundTruthMap(stamp_s=0.0, cells=truth.cells, spec=truth.spec)
    truth = open_log(truth_path, config, require=("ground_truth_map",)).ground_truth_map()
    if truth is None:
        raise LogError(f"{truth_path}: the log has no ground-truth map")
    return truth


def evaluate_map_file(
    map_yaml: Path | str, truth_path: Path | str, config: SmokySlamConfig
) -> dict[str, float]:
    """The five map metrics of ``map_yaml`` against the truth at ``truth_path``.

    A map that knows none of the cells the truth knows (another place, a broken resolution)
    is not a map of that truth: MapFileError.
    """
    estimate = load_map(map_yaml)
    truth = load_truth(truth_path, config)
    known = resample_nearest(estimate.cells, estimate.spec, truth.spec, UNKNOWN) != UNKNOWN
    if not (known & (truth.cells != UNKNOWN)).any():
        raise MapFileError(
            f"{map_yaml}: the map does not overlap the ground truth of {truth_path} "
            f"(map {_extent(estimate.spec)}, truth {_extent(truth.spec)})"
        )
    return map_scores(estimate.cells, estimate.spec, truth)


def _extent(spec: GridSpec) -> str:
    x0, x1, y0, y1 = spec.extent_m
    return f"x {x0:.4g}..{x1:.4g} m, y {y0:.4g}..{y1:.4g} m"
