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
from smokyslam.evaluation.map_metrics import map_scores, score_text
from smokyslam.frontends.readers.registry import open_log
from smokyslam.mapping.build import build_radar_map
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.outputs import OutputFolder
from smokyslam.smoke import SmokeEmulator
from smokyslam.upsample.infer import DENSE_MAP, get_upsampler, upsample


def _method(config: SmokySlamConfig) -> str:
    """``map --upsample`` up-samples even when the config turns it off for runs."""
    return "gan" if config.upsample.method == "none" else config.upsample.method


logger = logging.getLogger(__name__)


@dataclass
class TruthMappingResult:
    grid: OccupancyGrid
    metrics: dict
    wall_s: float
    out_dir: Path


def run_truth_mapping(
    log_path: Path | str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    overwrite: bool = False,
    upsample_map: bool = False,
) -> TruthMappingResult:
    """Build ``maps/radar_sparse`` from the log's (smoked) radar on its ground-truth poses
    (and with ``upsample_map`` its up-sampling, ``maps/radar_dense``); score them against the
    log's true map (and the observed truth, where the log has it)."""
    started = time.perf_counter()
    upsampler = None
    if upsample_map:
        upsampler = get_upsampler(config.upsample, _method(config))  # bad weights: now
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
        maps = {"radar_sparse": grid}
        if upsampler is not None and min(grid.spec.shape) > 0:
            maps[DENSE_MAP] = upsample(upsampler, grid.to_cells(), grid.spec)
        gt_map, observed = reader.ground_truth_map(), reader.observed_ground_truth_map()
        if gt_map is None:
            logger.warning("%s has no ground-truth map: no map metrics", log_path)
        metrics: dict = {}
        for name, drawn in maps.items():
            cells = drawn.to_cells()
            path_xy = truth.poses_world_base[:, :2]
            scores = None
            if gt_map is not None and cells.size:
                scores = map_scores(cells, drawn.spec, gt_map, observed)
            caption = "on ground-truth poses" + (score_text(scores) if scores else "")
            written = out.write_map(name, cells, drawn.spec, gt_map, path_xy, caption)
            if scores is not None and written is not None:
                metrics.setdefault("maps", {})[name] = scores
        wall_s = time.perf_counter() - started
        out.update_metrics({**metrics, "wall_s": wall_s})
        return TruthMappingResult(grid, metrics, wall_s, out.root)
