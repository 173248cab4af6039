"""``smokyslam map --poses ground-truth``: the radar map built on ground-truth poses.

This isolates the mapping half of the method from odometry: the same scans, the same stitching,
perfect poses. Smoke emulation applies as in every run.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.map_metrics import evaluate_map
from smokyslam.frontends.readers.registry import open_log
from smokyslam.geometry import GridSpec
from smokyslam.mapping.build import build_radar_map
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.outputs import OutputFolder
from smokyslam.smoke import SmokedLog
from smokyslam.types import GroundTruthMap

logger = logging.getLogger(__name__)

MAP_METRIC_KEYS = (
    "error_index",
    "occupied_precision",
    "occupied_recall",
    "occupied_f1",
    "occupied_iou",
)


@dataclass
class TruthMappingResult:
    grid: OccupancyGrid
    metrics: dict
    wall_s: float
    out_dir: Path


def map_metrics(cells: np.ndarray, spec: GridSpec, truth: GroundTruthMap) -> dict[str, float]:
    """The contract's five map metrics of trinary cells against a GroundTruthMap."""
    scores = evaluate_map(cells, spec, truth.cells, truth.spec)
    return {key: scores[key] for key in MAP_METRIC_KEYS}


def run_truth_mapping(
    log_path: Path | str, config: SmokySlamConfig, out_dir: Path | str
) -> TruthMappingResult:
    """Build ``maps/radar_sparse`` from the log's radar on its ground-truth poses; score it."""
    started = time.perf_counter()
    with OutputFolder(out_dir) as out:
        out.write_config(config)
        log = open_log(log_path, config, require=("radar", "ground_truth_pose"))
        reader = SmokedLog(log, config.smoke)
        grid = build_radar_map(reader.frames(), reader.extrinsics(), config.mapping)
        cells = grid.to_cells()
        truth = reader.ground_truth_map()
        out.write_map("radar_sparse", cells, grid.spec, truth)
        metrics = {}
        if truth is not None:
            metrics = {"maps": {"radar_sparse": map_metrics(cells, grid.spec, truth)}}
        else:
            logger.warning("%s has no ground-truth map: no map metrics", log_path)
        wall_s = time.perf_counter() - started
        out.update_metrics({**metrics, "wall_s": wall_s})
        return TruthMappingResult(grid, metrics, wall_s, out.root)
