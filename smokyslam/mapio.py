"""Occupancy maps on disk in ROS map_server format: a PGM image plus a YAML description.

The YAML holds ``image``, ``resolution``, ``origin`` ([x, y, yaw] of the lower-left pixel),
``negate``, ``occupied_thresh``, ``free_thresh`` and ``mode: trinary``. Image row 0 is the top
of the map, so rows are flipped against smokyslam's ``[iy, ix]`` arrays (iy grows northwards).

What an unknown cell means differs between maps, and map_server does not say. In the maps
smokyslam writes, unknown is space no sensor observed; they carry ``unknown: unobserved``. In a
floor plan that draws no walls it is solid: the wall is where free space meets unknown
(:func:`with_implicit_walls`), as the simulator takes it; ``unknown: solid`` says so. A map
without the key is read by what it draws (:data:`PLAN_WALL_SHARE`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.ndimage import binary_dilation

from smokyslam.errors import MapFileError
from smokyslam.geometry import GridSpec

OCCUPIED, FREE, UNKNOWN = 100, 0, -1
UNKNOWN_MEANINGS = ("unobserved", "solid")
PLAN_WALL_SHARE = 0.15
"""A map without an ``unknown`` key whose occupied cells number fewer than this share of the
unknown cells touching its free space draws (almost) no walls: a floor plan whose walls are
that edge, so its unknown is solid. Measured: a robot-built plan without drawn walls 0.07; a
plan with drawn walls 4.6; stitched radar maps of ten offices 0.20-0.26 (sparse) and
0.53-0.59 (up-sampled); a map stitched from the Intel lab's laser scans 1.36. In those sensor
maps the edge of free space is unobserved: read as walls, tracking along the Intel log lost
29 % of its frames instead of 3.5 %, and in the office maps 1-2 of 10 runs more missed."""
_PIXEL_OCCUPIED, _PIXEL_FREE, _PIXEL_UNKNOWN = 0, 254, 205


@dataclass
class MapImage:
    """A trinary map: cells[iy, ix] int8 with 100 occupied, 0 free, -1 unknown."""

    cells: np.ndarray
    spec: GridSpec
    unknown: str = "unobserved"
    """What an unknown cell is: ``unobserved`` (smokyslam's maps) or ``solid`` (a floor plan
    that draws no walls)."""

    def as_probability(self) -> np.ndarray:
        """(rows, cols) float: occupied 1.0, free 0.0, unknown 0.5 (the error index's values)."""
        prob = np.full(self.cells.shape, 0.5)
        prob[self.cells == OCCUPIED] = 1.0
        prob[self.cells == FREE] = 0.0
        return prob


def trinary_from_probability(
    prob: np.ndarray, occupied_thresh: float = 0.65, free_thresh: float = 0.196
) -> np.ndarray:
    """Cells int8 (100/0/-1) from occupancy probabilities; NaN counts as unknown."""
    cells = np.full(prob.shape, UNKNOWN, dtype=np.int8)
    cells[prob > occupied_thresh] = OCCUPIED
    cells[prob < free_thresh] = FREE
    return cells


def save_map(
    yaml_path: Path | str,
    cells: np.ndarray,
    spec: GridSpec,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    preview_png: bool = True,
    unknown: str | None = None,
) -> Path:
    """Write ``NAME.pgm`` + ``NAME.yaml`` (and ``NAME.png`` when asked); returns the YAML path.
    ``unknown``: written as the YAML's ``unknown`` key when given (see the module docstring)."""
    yaml_path = Path(yaml_path)
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    cells = np.asarray(cells)
    pixels = np.full(cells.shape, _PIXEL_UNKNOWN, dtype=np.uint8)
    pixels[cells == OCCUPIED] = _PIXEL_OCCUPIED
    pixels[cells == FREE] = _PIXEL_FREE
    pixels = np.flipud(pixels)
    pgm_path = yaml_path.with_suffix(".pgm")
    if not cv2.imwrite(str(pgm_path), pixels):
        raise MapFileError(f"could not write map image {pgm_path}")
    if preview_png:
        cv2.imwrite(str(yaml_path.with_suffix(".png")), pixels)
    description = {
        "image": pgm_path.name,
        "resolution": float(spec.resolution_m),
        "origin": [float(spec.origin_xy_m[0]), float(spec.origin_xy_m[1]), 0.0],
        "negate": 0,
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
        "mode": "trinary",
    }
    if unknown is not None:
        description["unknown"] = unknown
    yaml_path.write_text(yaml.safe_dump(description, sort_keys=False))
    return yaml_path


def _read_description(yaml_path: Path) -> dict:
    if not yaml_path.is_file():
        raise MapFileError(f"map file not found: {yaml_path}")
    try:
        description = yaml.safe_load(yaml_path.read_text())
    except UnicodeDecodeError:
        raise MapFileError(f"{yaml_path}: not a text (UTF-8) map description") from None
    except OSError as exc:
        raise MapFileError(f"{yaml_path}: cannot read it ({exc.strerror or exc})") from None
    except yaml.YAMLError as exc:
        raise MapFileError(f"{yaml_path}: not valid YAML ({exc.__class__.__name__})") from exc
    if not isinstance(description, dict):
        raise MapFileError(f"{yaml_path}: not a map_server map description")
    for key in ("image", "resolution", "origin"):
        if key not in description:
            raise MapFileError(f"{yaml_path}: missing key '{key}'")
    resolution = description["resolution"]
    if not isinstance(resolution, int | float) or not 0 < resolution < math.inf:
        raise MapFileError(f"{yaml_path}: resolution must be a positive number, got {resolution!r}")
    origin = description["origin"]
    if not isinstance(origin, list) or len(origin) < 2:
        raise MapFileError(f"{yaml_path}: origin must be [x, y, yaw], got {origin!r}")
    if not all(isinstance(v, int | float) and math.isfinite(v) for v in origin):
        raise MapFileError(f"{yaml_path}: origin must be finite numbers, got {origin!r}")
    if len(origin) > 2 and origin[2] not in (0, 0.0):
        raise MapFileError(f"{yaml_path}: rotated map origins (yaw != 0) are not supported")
    if not isinstance(description["image"], str):
        raise MapFileError(f"{yaml_path}: image must be a file name, got {description['image']!r}")
    for key in ("negate", "occupied_thresh", "free_thresh"):
        value = description.get(key, 0)
        if not isinstance(value, int | float) or not math.isfinite(value):
            raise MapFileError(f"{yaml_path}: {key} must be a number, got {value!r}")
    if description.get("unknown", UNKNOWN_MEANINGS[0]) not in UNKNOWN_MEANINGS:
        raise MapFileError(
            f"{yaml_path}: unknown must be one of {', '.join(UNKNOWN_MEANINGS)}, "
            f"got {description['unknown']!r}"
        )
    return description


def load_map(yaml_path: Path | str) -> MapImage:
    """Read a map_server map (PGM or PNG image) as trinary cells.

    Pixels are interpreted as map_server does: p = (255 - v) / 255 (or v / 255 when negated);
    p > occupied_thresh is occupied, p < free_thresh is free, the rest unknown.
    """
    yaml_path = Path(yaml_path)
    description = _read_description(yaml_path)
    image_path = yaml_path.parent / str(description["image"])
    if not image_path.is_file():
        raise MapFileError(f"{yaml_path}: map image not found: {image_path}")
    pixels = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise MapFileError(f"{image_path}: not a readable PGM/PNG image")
    if pixels.ndim == 3:
        alpha = pixels[..., 3] if pixels.shape[2] == 4 else None
        pixels = pixels[..., :3].mean(axis=2)
        if alpha is not None:
            pixels = np.where(alpha == 0, _PIXEL_UNKNOWN, pixels)
    scale = 65535.0 if pixels.dtype == np.uint16 else 255.0
    value = pixels.astype(float) / scale
    prob = value if int(description.get("negate", 0)) else 1.0 - value
    cells = trinary_from_probability(
        np.flipud(prob),
        float(description.get("occupied_thresh", 0.65)),
        float(description.get("free_thresh", 0.196)),
    )
    origin = description["origin"]
    spec = GridSpec(
        origin_xy_m=(float(origin[0]), float(origin[1])),
        resolution_m=float(description["resolution"]),
        shape=cells.shape,
    )
    unknown = description.get("unknown") or _unknown_by_what_it_draws(cells)
    return MapImage(cells=cells, spec=spec, unknown=unknown)


def _unknown_by_what_it_draws(cells: np.ndarray) -> str:
    implied = np.count_nonzero(with_implicit_walls(cells) != cells)
    drawn = np.count_nonzero(cells == OCCUPIED)
    return "solid" if drawn < PLAN_WALL_SHARE * implied else "unobserved"


def with_implicit_walls(cells: np.ndarray) -> np.ndarray:
    """``cells`` with every unknown cell that borders free space (8 neighbours) occupied: the
    walls of a floor plan that draws none, by the rule of the simulator's ground truth."""
    cells = np.array(cells, copy=True)
    free = cells == FREE
    cells[(cells == UNKNOWN) & binary_dilation(free, np.ones((3, 3), dtype=bool))] = OCCUPIED
    return cells
