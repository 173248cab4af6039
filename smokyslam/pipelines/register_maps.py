"""``smokyslam register``: one saved map registered onto another by a homography.

The output folder holds ``homography.json`` (``H`` maps source pixel (col, row) to destination
pixel (col, row) of the two images as stored), the source warped onto the destination's grid
(``maps/warped.{pgm,yaml,png}``), ``overlay.png``, the effective config and a log.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import FusionError
from smokyslam.fusion.overlay import write_overlay_png
from smokyslam.fusion.registration import (
    Registration,
    check_registrable,
    register_maps,
    warp_cells,
)
from smokyslam.mapio import MapImage, load_map
from smokyslam.outputs import OutputFolder, claim_folder

logger = logging.getLogger(__name__)

WARPED_MAP = "warped"
HOMOGRAPHY_FILE = "homography.json"
OVERLAY_FILE = "overlay.png"
REGISTER_OUTPUTS = (HOMOGRAPHY_FILE, OVERLAY_FILE, "maps", "config.yaml", "run.log")
"""What ``register`` leaves in its folder; any of them there means the folder holds a result."""


@dataclass
class RegisterResult:
    registration: Registration
    out_dir: Path
    wall_s: float
    """Seconds spent registering (not reading or writing files)."""


def homography_record(registration: Registration) -> dict[str, Any]:
    """The contents of ``homography.json``."""
    return {
        "H": [[float(v) for v in row] for row in registration.H],
        "rms_residual": float(registration.rms_residual),
        "overlap": float(registration.overlap),
        "confidence": float(registration.confidence),
        "confident": bool(registration.confident),
    }


def scale_prior(source: MapImage, destination: MapImage, max_ratio: float) -> float:
    """The source-to-destination pixel scale the resolutions imply; FusionError when they are
    more than ``max_ratio`` apart (no scale registration searches could make them overlap)."""
    ratio = source.spec.resolution_m / destination.spec.resolution_m
    if max(ratio, 1.0 / ratio) > max_ratio:
        raise FusionError(
            f"the maps' resolutions ({source.spec.resolution_m:g} m and "
            f"{destination.spec.resolution_m:g} m) are {max(ratio, 1.0 / ratio):.1f}x apart, "
            f"more than the {max_ratio:g}x registration bridges "
            "(fusion.registration.max_resolution_ratio): resample one map first"
        )
    return ratio


def register_map_files(
    source_yaml: Path | str,
    destination_yaml: Path | str,
    out_dir: Path | str,
    config: SmokySlamConfig,
    overwrite: bool = False,
) -> RegisterResult:
    """Register the map at ``source_yaml`` onto the one at ``destination_yaml`` and write the
    result into ``out_dir``. A registration below the confidence threshold is written too (to
    be inspected) but flagged ``confident: false`` in ``homography.json`` and the log."""
    settings = config.fusion.registration
    source, destination = load_map(source_yaml), load_map(destination_yaml)
    check_registrable(source.cells, str(source_yaml))
    check_registrable(destination.cells, str(destination_yaml))
    prior = scale_prior(source, destination, settings.max_resolution_ratio)
    claim_folder(Path(out_dir), overwrite, REGISTER_OUTPUTS)
    with OutputFolder(out_dir) as out:
        out.write_config(config)
        started = time.perf_counter()
        registration = register_maps(source.cells, destination.cells, settings, prior)
        wall_s = time.perf_counter() - started
        if not registration.confident:
            logger.info(
                "registration of %s onto %s is not confident (%.2f < %.2f): do not apply it",
                source_yaml,
                destination_yaml,
                registration.confidence,
                settings.confidence_threshold,
            )
        warped = warp_cells(source.cells, registration.H, destination.cells.shape)
        out.write_map(WARPED_MAP, warped, destination.spec)
        write_overlay_png(out.path(OVERLAY_FILE), destination.cells, warped)
        record = homography_record(registration)
        out.path(HOMOGRAPHY_FILE).write_text(json.dumps(record, indent=2) + "\n")
        logger.info(
            "registered %s onto %s: %s (%.2f s)", source_yaml, destination_yaml, record, wall_s
        )
        return RegisterResult(registration, out.root, wall_s)
