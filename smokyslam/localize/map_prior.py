"""The map the localizer weighs radar points against: a sparse radar map is densified first.

A stitched radar map (``maps/radar_sparse.*``) holds its walls as scattered returns: a quarter
to almost half of its occupied cells have no occupied neighbour (measured 0.24-0.46 on 34
sparse maps of offices, warehouses, corridors and floor plans), where the up-sampled, fused,
ground-truth and floor-plan maps have at most 0.08. In such a map the likelihood field's
walls are broken lines, and where a wall has no return the filter slides along it (on ten
unseen offices, tracking held its bound in 6 of 10 runs in sparse maps, 10 of 10 in their
up-sampled copies). So, by default, a map that sparse is first up-sampled by the shipped
generator (the package's learned prior of what a radar map's walls and free space look
like; ``smokyslam upsample`` gives the same map), and the filter weighs against that.

``localize.densify``: ``auto`` (up-sample when the share of isolated occupied cells is at
least ``densify_isolated``), ``always``, ``never``.

A floor plan that draws no walls (a map whose unknown is solid, see :mod:`smokyslam.mapio`)
first gets the walls it implies: where free space simply ends at unknown, the plan has nothing
else for the radar points to fit (measured: tracking from 1 m off never converged in
such a plan; see ``tests/test_localize_cli.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import convolve

from smokyslam.config import SmokySlamConfig
from smokyslam.geometry import GridSpec
from smokyslam.mapio import OCCUPIED, UNKNOWN, with_implicit_walls
from smokyslam.mapping.grid import resample_nearest


@dataclass(frozen=True)
class LocalizationMap:
    """The trinary ``cells`` the filter uses, on the given map's grid; ``densified`` says
    whether they are the up-sampled copy of the map given; ``isolated_share`` is the given
    map's."""

    cells: np.ndarray
    densified: bool
    isolated_share: float
    implicit_walls: int = 0
    """Cells made walls because the map is a floor plan whose free space ends at unknown."""


def isolated_share(cells: np.ndarray) -> float:
    """The share of occupied cells with no occupied cell among their 8 neighbours (0 for a
    map without occupied cells)."""
    occupied = np.asarray(cells) == OCCUPIED
    if not occupied.any():
        return 0.0
    neighbours = convolve(occupied.astype(np.uint8), np.ones((3, 3), np.uint8), mode="constant")
    return float(np.count_nonzero(occupied & (neighbours == 1)) / np.count_nonzero(occupied))


def localization_map(
    cells: np.ndarray, spec: GridSpec, config: SmokySlamConfig, unknown: str = "unobserved"
) -> LocalizationMap:
    """The map to localize in: ``cells`` themselves (with their implicit walls when
    ``unknown`` is ``solid``, a floor plan), or their up-sampled copy when
    ``config.localize.densify`` asks for it (``auto``: a map as sparse as a stitched radar
    map)."""
    walls = 0
    if unknown == "solid":
        walled = with_implicit_walls(cells)
        walls = int(np.count_nonzero(walled != cells))
        cells = walled if walls else cells
    share = isolated_share(cells)
    policy = config.localize.densify
    if policy == "never" or (policy == "auto" and share < config.localize.densify_isolated):
        return LocalizationMap(cells, False, share, walls)
    from smokyslam.upsample.infer import get_upsampler, upsample  # torch: only when used

    dense = upsample(get_upsampler(config.upsample, "gan"), cells, spec)
    cells = resample_nearest(dense.cells, dense.spec, spec, UNKNOWN)
    return LocalizationMap(cells, True, share, walls)
