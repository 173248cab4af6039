"""``smokyslam fuse``: a saved radar map and a saved visual map fused by the trust index.

The table of contents of :func:`fuse_map_files`: read both maps and the trust (forced, or the
one measured by the run that made the visual map: ``VISUAL.trust.npz`` beside it); place the
visual map on the radar map's grid (registration by homography, or, with ``register=False``,
by world coordinates when both maps share a frame); fuse; write ``maps/fused.*`` (and with
registration ``homography.json``), metrics, and scores against a truth when one is given.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import FusionError
from smokyslam.fusion.fuse import FUSED_MAP, FusedMap
from smokyslam.fusion.fuser import MapFuser
from smokyslam.fusion.placement import place_visual_map
from smokyslam.fusion.trust import load_trust, trust_beside
from smokyslam.mapio import UNKNOWN, MapImage, load_map
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.register_maps import HOMOGRAPHY_FILE, homography_record, scale_prior

logger = logging.getLogger(__name__)


@dataclass
class FuseResult:
    fused: FusedMap
    metrics: dict[str, Any]
    out_dir: Path


def measured_trust(visual_yaml: Path, visual: MapImage) -> tuple[Any, float]:
    """The trust the run measured for ``visual_yaml`` (``VISUAL.trust.npz`` beside it)."""
    path = trust_beside(visual_yaml)
    if not path.is_file():
        raise FusionError(
            f"--trust auto: no measured trust beside {visual_yaml} ({path.name}, written by "
            "runs with a camera): give --trust T"
        )
    return load_trust(path, visual.cells.shape)


def fuse_map_files(
    radar_yaml: Path | str,
    visual_yaml: Path | str,
    out_dir: Path | str,
    config: SmokySlamConfig,
    register: bool = True,
    truth_path: Path | str | None = None,
    overwrite: bool = False,
) -> FuseResult:
    """Fuse the maps at ``radar_yaml`` and ``visual_yaml`` into ``out_dir/maps/fused.*``."""
    from smokyslam.evaluation.map_metrics import map_scores
    from smokyslam.pipelines.evaluate_map import load_truth

    radar_yaml, visual_yaml = Path(radar_yaml), Path(visual_yaml)
    radar, visual = load_map(radar_yaml), load_map(visual_yaml)
    for path, image in ((radar_yaml, radar), (visual_yaml, visual)):
        if not (image.cells != UNKNOWN).any():
            raise FusionError(f"{path}: the map has no known cell (all unknown): nothing to fuse")
    trust, t_run = None, None
    if config.fusion.trust == "auto":
        trust, t_run = measured_trust(visual_yaml, visual)
    truths = load_truth(truth_path, config, radar) if truth_path is not None else None
    fuser = MapFuser(config.fusion)
    metrics: dict[str, Any] = {}
    with OutputFolder(out_dir, overwrite=overwrite) as out:
        out.write_config(config)
        if register:
            settings = config.fusion.registration
            prior = scale_prior(visual, radar, settings.max_resolution_ratio)
            placed = place_visual_map(
                visual.cells, radar.cells, settings, trust, t_run or 1.0, prior, str(visual_yaml)
            )
            record = homography_record(placed.registration)
            out.path(HOMOGRAPHY_FILE).write_text(json.dumps(record, indent=2) + "\n")
            metrics["registration"] = record
            visual = MapImage(placed.cells, radar.spec)
            trust = placed.trust
        fused = fuser.fuse(radar.cells, radar.spec, visual.cells, visual.spec, trust, t_run)
        out.write_map(FUSED_MAP, fused.to_cells(), fused.spec)
        metrics["fusion"] = {**fused.summary(), "trust": config.fusion.trust, "inputs": {
            "radar": str(radar_yaml), "visual": str(visual_yaml)}}  # fmt: skip
        if truths is not None:
            metrics["maps"] = {
                "radar": map_scores(radar.cells, radar.spec, *truths),
                "visual": map_scores(visual.cells, visual.spec, *truths),
                FUSED_MAP: map_scores(fused.to_cells(), fused.spec, *truths),
            }
        out.update_metrics(metrics)
        logger.info("fused %s and %s: %s", radar_yaml, visual_yaml, metrics["fusion"])
        return FuseResult(fused, metrics, out.root)
