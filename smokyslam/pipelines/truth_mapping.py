"""``smokyslam map --poses ground-truth``: the radar map built on ground-truth poses.

This isolates the mapping half of the method from odometry: the same scans, the same smoke,
the same keyframe gate and stitching, perfect poses.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

from smokyslam.backends.keyframes import get_keyframe_gate
from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError
from smokyslam.evaluation.map_metrics import map_scores
from smokyslam.frontends.readers.registry import open_log
from smokyslam.mapping.build import build_radar_map
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.outputs import OutputFolder
from smokyslam.smoke import SmokeEmulator

logger = logging.getLogger(__name__)


@dataclass
class TruthMappingResult:
    grid: OccupancyGrid
    metrics: dict
    wall_s: float
    out_dir: Path


def run_truth_mapping(
    log_path: Path | str, config: SmokySlamConfig, out_dir: Path | str, overwrite: bool = False
) -> TruthMappingResult:
    """Build ``maps/radar_sparse`` from the log's (smoked) radar on its ground-truth poses;
    score it against the log's true map."""
    started = time.perf_counter()
    with OutputFolder(out_dir, overwrite=overwrite) as out:
        out.write_config(config)
        reader = open_log(log_path, config, require=("radar", "ground_truth_pose"))
        truth = reader.ground_truth_trajectory()
        if truth is None or len(truth) < 2:
            raise LogError(f"{log_path}: fewer than two ground-truth poses to map on")
        smoke = SmokeEmulator(config.smoke)
        frames = (smoke.apply(frame) for frame in reader.frames())
        gate = get_keyframe_gate(config.keyframes)
        grid = build_radar_map(frames, truth, reader.extrinsics(), config.mapping, gate)
        cells = grid.to_cells()
        gt_map = reader.ground_truth_map()
        written = out.write_map(
            "radar_sparse", cells, grid.spec, gt_map, truth.poses_world_base[:, :2]
        )
        metrics = {}
        if gt_map is None:
            logger.warning("%s has no ground-truth map: no map metrics", log_path)
        elif written is not None:
            observed = reader.observed_ground_truth_map()
            metrics = {"maps": {"radar_sparse": map_scores(cells, grid.spec, gt_map, observed)}}
        wall_s = time.perf_counter() - started
        out.update_metrics({**metrics, "wall_s": wall_s})
        return TruthMappingResult(grid, metrics, wall_s, out.root)
