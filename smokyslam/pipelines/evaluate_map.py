"""``smokyslam evaluate``: score a saved map against a log's ground truth or another map."""

from __future__ import annotations

from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError
from smokyslam.evaluation.map_metrics import map_scores
from smokyslam.frontends.readers.registry import open_log
from smokyslam.mapio import load_map
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
    """The five map metrics of ``map_yaml`` against the truth at ``truth_path``."""
    estimate = load_map(map_yaml)
    return map_scores(estimate.cells, estimate.spec, load_truth(truth_path, config))
