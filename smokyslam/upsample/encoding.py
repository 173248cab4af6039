"""Maps to network tensors and back.

The network reads trinary cells (what a saved PGM holds), so a map up-samples the same from
a file as online: channel 0 = +1 occupied / -1 free / 0 unknown, channel 1 = 1 where known.
It writes a value per cell on the error index's scale (1 occupied, 0 free, 0.5 unknown),
made trinary with map_server's thresholds.
"""

from __future__ import annotations

import numpy as np

from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, trinary_from_probability

OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196
"""map_server's thresholds, applied to the dense value (as the saved maps use)."""


def encode_cells(cells: np.ndarray) -> np.ndarray:
    """(2, rows, cols) float32 network input of (rows, cols) trinary cells."""
    cells = np.asarray(cells)
    occupancy = np.select([cells == OCCUPIED, cells == FREE], [1.0, -1.0], 0.0)
    return np.stack([occupancy, (cells != UNKNOWN).astype(float)]).astype(np.float32)


def target_values(cells: np.ndarray) -> np.ndarray:
    """(rows, cols) float32 training target of trinary truth cells: 1 / 0 / 0.5."""
    cells = np.asarray(cells)
    return np.select([cells == OCCUPIED, cells == FREE], [1.0, 0.0], 0.5).astype(np.float32)


def cells_from_values(values: np.ndarray) -> np.ndarray:
    """(rows, cols) int8 trinary cells of dense values (map_server thresholds)."""
    return trinary_from_probability(np.asarray(values, dtype=float), OCCUPIED_THRESH, FREE_THRESH)
