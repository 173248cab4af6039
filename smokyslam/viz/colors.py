"""Colours of the recording, in numpy: Doppler, grid maps, and one colour per source."""

from __future__ import annotations

import numpy as np

from smokyslam.mapio import FREE, OCCUPIED

SOURCE_COLORS = {
    "fused": (214, 39, 40),
    "radar": (31, 119, 180),
    "dead-reckoning": (148, 103, 189),
    "camera": (44, 160, 44),
    "ground_truth": (90, 90, 90),
}
"""A source's colour, the same in every recording and plot."""

_OTHER = ((255, 127, 14), (140, 86, 75), (227, 119, 194), (188, 189, 34), (23, 190, 207))

MAP_RGBA = {
    "unknown": (128, 128, 128, 60),
    "free": (255, 255, 255, 150),
    "occupied": (0, 0, 0, 255),
}
"""A trinary map cell's colour: unknown faint grey, free white, occupied black."""

TRUTH_WALL_RGBA = (220, 40, 40, 255)
"""True walls are red; the rest of the true map is left transparent."""


def source_color(name: str, index: int = 0) -> tuple[int, int, int]:
    """The colour of ``name`` (a source, or a run named after one: ``fused-r0.1-c0.2``)."""
    for source, color in SOURCE_COLORS.items():
        if name == source or name.startswith(source + "-"):
            return color
    return _OTHER[index % len(_OTHER)]


def doppler_colors(doppler_mps: np.ndarray, full_scale_mps: float = 2.0) -> np.ndarray:
    """(N, 3) uint8: approaching (negative Doppler) blue, receding red, still grey-white."""
    v = np.clip(np.asarray(doppler_mps, dtype=float) / full_scale_mps, -1.0, 1.0)
    red = 230 - 180 * np.clip(-v, 0.0, 1.0)
    blue = 230 - 180 * np.clip(v, 0.0, 1.0)
    green = 230 - 180 * np.abs(v)
    return np.column_stack([red, green, blue]).astype(np.uint8)


def map_rgba(cells: np.ndarray) -> np.ndarray:
    """(rows, cols, 4) uint8 of a trinary grid (row 0 the lowest y, as stored)."""
    cells = np.asarray(cells)
    rgba = np.empty((*cells.shape, 4), dtype=np.uint8)
    rgba[:] = MAP_RGBA["unknown"]
    rgba[cells == FREE] = MAP_RGBA["free"]
    rgba[cells == OCCUPIED] = MAP_RGBA["occupied"]
    return rgba


def truth_rgba(cells: np.ndarray) -> np.ndarray:
    """(rows, cols, 4) uint8: the true walls in red, everything else transparent."""
    rgba = np.zeros((*np.asarray(cells).shape, 4), dtype=np.uint8)
    rgba[np.asarray(cells) == OCCUPIED] = TRUTH_WALL_RGBA
    return rgba
