"""A picture of a registration: the destination map and the warped source map, one colour each."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from smokyslam.errors import MapFileError
from smokyslam.mapio import FREE, OCCUPIED

# BGR colours.
_UNKNOWN_GREY = (205, 205, 205)
_FREE_WHITE = (250, 250, 250)
_DESTINATION_BLUE = (200, 110, 0)
_SOURCE_RED = (0, 0, 220)
_BOTH_PURPLE = (120, 0, 110)


def overlay_image(destination_cells: np.ndarray, warped_cells: np.ndarray) -> np.ndarray:
    """(rows, cols, 3) uint8 BGR, north up (as the PGM is stored): walls of the destination in
    blue, of the warped source in red, of both in purple; free in either white, the rest grey.
    Both inputs are trinary (rows, cols) ``[iy, ix]`` cells on the destination's grid."""
    dst_wall = destination_cells == OCCUPIED
    src_wall = warped_cells == OCCUPIED
    image = np.empty((*destination_cells.shape, 3), dtype=np.uint8)
    image[:] = _UNKNOWN_GREY
    image[(destination_cells == FREE) | (warped_cells == FREE)] = _FREE_WHITE
    image[dst_wall] = _DESTINATION_BLUE
    image[src_wall] = _SOURCE_RED
    image[dst_wall & src_wall] = _BOTH_PURPLE
    return np.ascontiguousarray(np.flipud(image))


def write_overlay_png(
    path: Path | str,
    destination_cells: np.ndarray,
    warped_cells: np.ndarray,
    min_side_px: int = 600,
) -> Path:
    """Write :func:`overlay_image`, cells enlarged to whole pixels so the shorter side reaches
    ``min_side_px`` (the longer within 4000 pixels); returns the path."""
    path = Path(path)
    image = overlay_image(destination_cells, warped_cells)
    rows, cols = image.shape[:2]
    scale = max(1, min(math.ceil(min_side_px / min(rows, cols)), 4000 // max(rows, cols)))
    image = np.repeat(np.repeat(image, scale, axis=0), scale, axis=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image):
        raise MapFileError(f"could not write the overlay picture {path}")
    return path
