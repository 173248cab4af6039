"""PNG pictures of maps: grey map cells, ground-truth walls in red, the trajectory in blue."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from smokyslam.errors import MapFileError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap

# BGR colours.
_GREY = {OCCUPIED: (0, 0, 0), FREE: (254, 254, 254), UNKNOWN: (205, 205, 205)}
_RED = np.array([0, 0, 255], dtype=float)
_BLUE = (200, 80, 0)
_MAX_SIDE_PX = 4000


def _union_spec(spec: GridSpec, other: GridSpec | None) -> GridSpec:
    """A grid at ``spec``'s resolution covering both grids."""
    if other is None:
        return spec
    x0, x1, y0, y1 = spec.extent_m
    u0, u1, v0, v1 = other.extent_m
    left, bottom = min(x0, u0), min(y0, v0)
    cols = math.ceil((max(x1, u1) - left) / spec.resolution_m - 1e-9)
    rows = math.ceil((max(y1, v1) - bottom) / spec.resolution_m - 1e-9)
    return GridSpec((left, bottom), spec.resolution_m, (rows, cols))


def render_map_png(
    path: Path | str,
    cells: np.ndarray,
    spec: GridSpec,
    truth: GroundTruthMap | None = None,
    trajectory_xy_m: np.ndarray | None = None,
    min_side_px: int = 600,
) -> Path:
    """Write a picture of a trinary map (north up) and return its path.

    cells: (rows, cols) int8 100 / 0 / -1 over ``spec``. Map cells are black (occupied),
    white (free) or grey (unknown); ground-truth occupied cells are tinted red (dark red where
    the map agrees); ``trajectory_xy_m`` (N, 2) world positions are drawn as a blue line.
    Cells are enlarged to whole pixels so the shorter side reaches ``min_side_px`` (the
    longer side stays within 4000 pixels).
    """
    path = Path(path)
    canvas = _union_spec(spec, truth.spec if truth is not None else None)
    if min(canvas.shape) == 0:
        raise MapFileError(f"cannot render an empty map to {path}")
    map_cells = resample_nearest(np.asarray(cells, dtype=np.int8), spec, canvas, UNKNOWN)
    image = np.zeros((*canvas.shape, 3), dtype=float)
    for value, colour in _GREY.items():
        image[map_cells == value] = colour
    if truth is not None:
        walls = resample_nearest(truth.cells, truth.spec, canvas, UNKNOWN) == OCCUPIED
        image[walls] = 0.5 * image[walls] + 0.5 * _RED
    scale = max(
        1, min(math.ceil(min_side_px / min(canvas.shape)), _MAX_SIDE_PX // max(canvas.shape))
    )
    image = np.repeat(np.repeat(image, scale, axis=0), scale, axis=1)
    image = np.ascontiguousarray(np.flipud(image).astype(np.uint8))
    if trajectory_xy_m is not None and len(trajectory_xy_m) > 1:
        xy = (np.asarray(trajectory_xy_m, dtype=float) - canvas.origin_xy_m) / canvas.resolution_m
        pixels = np.stack([xy[:, 0] * scale, image.shape[0] - xy[:, 1] * scale], axis=1)
        cv2.polylines(image, [np.round(pixels).astype(np.int32)], False, _BLUE, 2, cv2.LINE_AA)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image):
        raise MapFileError(f"could not write map picture {path}")
    return path
