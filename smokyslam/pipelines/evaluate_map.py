"""``smokyslam evaluate``: score a saved map against a log's ground truth, a map or a cloud.

Against a log, the map is scored against its full ground truth and, when the log has it
(simulated logs), against the observed truth a lidar recorded along the walk, under
``observed``. Against a map YAML or a lidar cloud (``.ply`` / ``.pcd``, flattened from a
z-band onto the map's grid) there is one truth.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError, MapFileError
from smokyslam.evaluation.cloud_truth import CLOUD_SUFFIXES, cloud_truth
from smokyslam.evaluation.map_metrics import map_scores
from smokyslam.frontends.readers.registry import open_log
from smokyslam.geometry import GridSpec
from smokyslam.mapio import UNKNOWN, MapImage, load_map, with_implicit_walls
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap


def load_truth(
    truth_path: Path | str,
    config: SmokySlamConfig,
    estimate: MapImage | None = None,
    z_band: tuple[float, float] | None = None,
) -> tuple[GroundTruthMap, GroundTruthMap | None]:
    """(truth, observed truth or None) from a map YAML, a log's ground-truth map topics, or
    a point cloud flattened onto the grid of ``estimate`` (required for a cloud). A floor
    plan's implicit walls are truth, as in the simulator's ``/ground_truth/map``."""
    truth_path = Path(truth_path)
    suffix = truth_path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        truth = load_map(truth_path)
        cells = with_implicit_walls(truth.cells) if truth.unknown == "solid" else truth.cells
        return GroundTruthMap(stamp_s=0.0, cells=cells, spec=truth.spec), None
    if suffix in CLOUD_SUFFIXES:
        if estimate is None:
            raise MapFileError(f"{truth_path}: a cloud is flattened onto a map's grid")
        return cloud_truth(truth_path, estimate.cells, estimate.spec, z_band), None
    if z_band is not None:
        raise MapFileError("--z-band applies only to a point-cloud truth (.ply or .pcd)")
    reader = open_log(truth_path, config, require=("ground_truth_map",))
    truth = reader.ground_truth_map()
    if truth is None:
        raise LogError(f"{truth_path}: the log has no ground-truth map")
    return truth, reader.observed_ground_truth_map()


def evaluate_map_file(
    map_yaml: Path | str,
    truth_path: Path | str,
    config: SmokySlamConfig,
    z_band: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """The five map metrics of ``map_yaml`` against the truth at ``truth_path`` (and under
    ``observed`` against a log's observed truth).

    A map that knows none of the cells the truth knows (another place, a broken resolution)
    is not a map of that truth: MapFileError.
    """
    estimate = load_map(map_yaml)
    truth, observed = load_truth(truth_path, config, estimate, z_band)
    known = resample_nearest(estimate.cells, estimate.spec, truth.spec, UNKNOWN) != UNKNOWN
    if not (known & (truth.cells != UNKNOWN)).any():
        raise MapFileError(
            f"{map_yaml}: the map does not overlap the ground truth of {truth_path} "
            f"(map {_extent(estimate.spec)}, truth {_extent(truth.spec)})"
        )
    return map_scores(estimate.cells, estimate.spec, truth, observed)


def _extent(spec: GridSpec) -> str:
    x0, x1, y0, y1 = spec.extent_m
    return f"x {x0:.4g}..{x1:.4g} m, y {y0:.4g}..{y1:.4g} m"
