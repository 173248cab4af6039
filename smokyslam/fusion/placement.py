"""A visual map placed in the radar map's grid by registration (the paper's automatic scale).

The camera's map comes at the camera's own scale and in its own frame; registering it onto
the metric radar map (``registration.py``) recovers scale, rotation and shift, and the visual
map and its measured trust grid are warped onto the radar map's grid, ready to fuse. A
registration below the confidence threshold is never applied: :func:`place_visual_map` raises.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.config.fusion import RegistrationConfig
from smokyslam.errors import FusionError
from smokyslam.fusion.registration import (
    Registration,
    register_maps,
    warp_cells,
    warp_values,
)


@dataclass
class PlacedVisualMap:
    """``cells`` (rows, cols) int8 and ``trust`` (rows, cols) t (None: none measured) on the
    radar map's grid, and the registration that placed them."""

    cells: np.ndarray
    trust: np.ndarray | None
    registration: Registration


def place_visual_map(
    visual_cells: np.ndarray,
    radar_cells: np.ndarray,
    config: RegistrationConfig,
    trust: np.ndarray | None = None,
    default_trust: float = 1.0,
    scale_prior: float = 1.0,
    name: str = "the visual map",
) -> PlacedVisualMap:
    """Register ``visual_cells`` onto ``radar_cells`` and warp it (and its ``trust`` grid,
    ``default_trust`` where it has none) onto the radar map's grid. FusionError when the
    registration is not confident."""
    registration = register_maps(visual_cells, radar_cells, config, scale_prior)
    if not registration.confident:
        raise FusionError(
            f"{name} could not be registered onto the radar map with confidence "
            f"({registration.confidence:.2f} < {config.confidence_threshold:g}, overlap "
            f"{registration.overlap:.2f}): the maps may not show the same place"
        )
    shape = np.shape(radar_cells)
    cells = warp_cells(visual_cells, registration.H, shape)
    warped_trust = None
    if trust is not None:
        warped_trust = warp_values(trust, registration.H, shape, default_trust)
    return PlacedVisualMap(cells, warped_trust, registration)
