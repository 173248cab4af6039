"""``smokyslam paper-table``: the paper's Table I, end to end, on any log with ground truth.

The table of contents of :func:`paper_table`: run the fused and the camera-only sources at the
paper's three smoke levels (radar loss, camera noise) = (0, 0), (0.1, 0.2), (0.2, 0.4) as one
comparison (``DIR/runs/``, in parallel); per level take the sparse and the up-sampled radar
maps of the fused run (in the ground-truth frame), register the camera-only run's visual map
(its own frame and scale: ``maps/visual_unaligned``) by homography onto the fused run's maps
(sparse, up-sampled, and its own visual map: the most confident placement), fuse it with the
up-sampled map by the trust the camera measured; score all twelve maps against the observed
truth where the log has one (the paper's lidar-made truth), else the full truth; write the
table, the maps and one figure.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import FusionError, SmokySlamError
from smokyslam.evaluation.map_metrics import evaluate_map
from smokyslam.evaluation.paper_table_io import TableRow, plot_table_maps, write_table
from smokyslam.frontends.readers.registry import open_log
from smokyslam.fusion.fuser import MapFuser
from smokyslam.fusion.placement import place_visual_map
from smokyslam.fusion.trust import load_trust, trust_beside
from smokyslam.mapio import UNKNOWN, MapImage, load_map, save_map
from smokyslam.mapping.grid import resample_nearest
from smokyslam.outputs import claim_folder
from smokyslam.pipelines.compare import compare, record_rows
from smokyslam.pipelines.run_outputs import UNALIGNED_VISUAL
from smokyslam.smoke import SmokeLevel

logger = logging.getLogger(__name__)

LEVELS = (
    SmokeLevel.from_values(0.0, 0.0, 0.0),
    SmokeLevel.from_values(0.1, 0.2, 0.0),
    SmokeLevel.from_values(0.2, 0.4, 0.0),
)
PAPER_ERROR_INDEX = (0.476, 0.497, 0.543, 0.188, 0.189, 0.207, 0.339, 0.364, 0.419, 0.105, 0.151)
PAPER_ERROR_INDEX += (0.171,)
PAPER_TABLE_OUTPUTS = (
    "table.csv",
    "table.md",
    "maps.png",
    "maps",
    "runs",
    "config.yaml",
    "compare.csv",
    "compare.md",
    "trajectories.png",
    "ate_vs_smoke.png",
)
"""What paper-table leaves in its folder (the comparison of its runs included)."""

ProgressCallback = Callable[..., None]


@dataclass
class PaperTableResult:
    rows: list[TableRow]
    truth_name: str
    out_dir: Path
    wall_s: float


def paper_table(
    log_path: Path | str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    workers: int | None = None,
    on_progress: ProgressCallback | None = None,
    overwrite: bool = False,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
) -> PaperTableResult:
    """Table I of the log at ``log_path`` into ``out_dir`` (see the module docstring).
    ``rerun_path`` / ``rerun_spawn``: the six runs' paths and the twelve maps in one Rerun
    recording."""
    started = time.perf_counter()
    log_path, out_dir = Path(log_path), Path(out_dir)
    truth, truth_name = _truth(log_path, config)
    claim_folder(out_dir, overwrite, PAPER_TABLE_OUTPUTS, markers=PAPER_TABLE_OUTPUTS[:2])
    runs = compare(
        log_path, ("fused", "camera"), LEVELS, config, out_dir, workers, on_progress, True
    )
    if runs.failed:
        failed = runs.failed[0]
        raise SmokySlamError(f"paper-table: the {failed.source} run failed: {failed.error}")
    by_run = {(row.source, row.level.label): row.run_dir for row in runs.rows}
    maps: dict[int, MapImage | None] = {}
    trust_used: dict[int, float | None] = {}
    fuser = MapFuser(config.fusion)
    for i, level in enumerate(LEVELS):
        fused_dir, camera_dir = by_run["fused", level.label], by_run["camera", level.label]
        maps[1 + i] = sparse = _read(fused_dir / "maps/radar_sparse.yaml")
        maps[4 + i] = dense = _read(fused_dir / "maps/radar_dense.yaml")
        maps[7 + i], maps[10 + i], trust_used[10 + i] = None, None, None
        visual_yaml = camera_dir / f"maps/{UNALIGNED_VISUAL}.yaml"
        if dense is None or sparse is None or not visual_yaml.is_file():
            continue
        own_visual = _read(fused_dir / "maps/visual.yaml")
        try:
            visual, fused, t_mean = _register_and_fuse(
                visual_yaml, (sparse, dense, own_visual), config, fuser
            )
        except FusionError as exc:
            logger.warning("level %s: %s", level.label, exc)
            continue
        maps[7 + i], maps[10 + i], trust_used[10 + i] = visual, fused, t_mean
    rows = []
    for index in range(1, 13):
        image = maps[index]
        scores = evaluate_map(image.cells, image.spec, truth.cells, truth.spec) if image else {}
        if image is not None:
            save_map(
                out_dir / f"maps/map_{index}.yaml", image.cells, image.spec, unknown="unobserved"
            )
        rows.append(
            TableRow(
                index,
                _name(index),
                scores.get("error_index"),
                scores.get("occupied_f1"),
                PAPER_ERROR_INDEX[index - 1],
                trust_used.get(index),
            )
        )
    write_table(out_dir, rows, truth_name, log_path)
    plot_table_maps(out_dir / "maps.png", rows, maps, truth)
    if rerun_path is not None or rerun_spawn:
        pictures = {
            f"map_{i:02d}": (image.cells, image.spec)
            for i, image in maps.items()
            if image is not None
        }
        path = None if rerun_path is None else Path(rerun_path)
        record_rows(runs.rows, truth, path, rerun_spawn, pictures)
    return PaperTableResult(rows, truth_name, out_dir, time.perf_counter() - started)


def _register_and_fuse(
    visual_yaml: Path,
    targets: tuple[MapImage, MapImage, MapImage | None],
    config: SmokySlamConfig,
    fuser: MapFuser,
) -> tuple[MapImage, MapImage, float]:
    """(the visual map placed on the radar maps' grid, its fusion with the dense map, the mean
    trust used). ``targets``: the fused run's sparse and dense radar maps and its own visual
    map (None when it has none), each taken onto the dense map's grid. The camera-only
    visual map is registered onto each, and the most confident placement is kept;
    FusionError when none is confident.

    The fused run's visual map is the same camera's landmarks placed on the fused run's
    metric poses, in the radar maps' frame: far more alike to the camera-only map than radar
    walls are (on 48 runs of 16 unseen worlds, 27 agreeing placements instead of 12)."""
    sparse, dense, own_visual = targets
    visual = load_map(visual_yaml)
    trust, t_run = load_trust(trust_beside(visual_yaml), visual.cells.shape)
    scale = visual.spec.resolution_m / dense.spec.resolution_m
    destinations = [resample_nearest(sparse.cells, sparse.spec, dense.spec, UNKNOWN), dense.cells]
    if own_visual is not None:
        destinations.append(
            resample_nearest(own_visual.cells, own_visual.spec, dense.spec, UNKNOWN)
        )
    placements, errors = [], []
    for destination in destinations:
        try:
            placements.append(
                place_visual_map(
                    visual.cells,
                    destination,
                    config.fusion.registration,
                    trust,
                    t_run,
                    scale,
                    str(visual_yaml),
                )
            )
        except FusionError as exc:
            errors.append(exc)
    if not placements:
        raise errors[0]
    placed = max(placements, key=lambda p: p.registration.confidence)
    logger.info("%s registered: confidence %.2f", visual_yaml, placed.registration.confidence)
    fused = fuser.fuse(dense.cells, dense.spec, placed.cells, dense.spec, placed.trust, t_run)
    placed_map = MapImage(placed.cells, dense.spec)
    return placed_map, MapImage(fused.to_cells(), fused.spec), fused.trust_mean


def _read(path: Path) -> MapImage | None:
    return load_map(path) if path.is_file() else None


def _truth(log_path: Path, config: SmokySlamConfig):
    """(the truth maps are scored against, its name): the observed one where there is one.
    A log without the radar or the camera the table's runs need is refused before any run."""
    reader = open_log(log_path, config, require=("radar", "camera_image"))
    observed = reader.observed_ground_truth_map()
    if observed is not None:
        return observed, "observed (what an ideal lidar recorded along the true walk)"
    truth = reader.ground_truth_map()
    if truth is None:
        raise SmokySlamError(f"{log_path}: no ground-truth map: paper-table needs one")
    return truth, "full (the whole floor plan; the log has no observed truth)"


def _name(index: int) -> str:
    level = LEVELS[(index - 1) % 3]
    smoke = f"radar loss {level.radar_loss:g}, camera noise {level.camera_noise:g}"
    kind = ("sparse radar", "up-sampled radar", "visual (registered)", "fused")[(index - 1) // 3]
    if index >= 10:
        return f"fused maps {index - 6} & {index - 3} ({smoke})"
    return f"{kind} ({smoke})"
