"""The measurement model of the localizer: a likelihood field over a saved map.

The distance from every cell to the nearest wall surface (an occupied cell bordering free
space; a Euclidean distance transform)
gives each radar point a likelihood ``z_hit N(d; 0, sigma) + z_rand / max_range``. A point in
unknown space gets at least the ``p_unknown`` a map that never saw that space can honestly
give, and more where it lies near a wall: a radar map sees a wall from one side only, and a
point just behind it is as near it as one just in front (scoring unknown space flat pushed
the filter about 0.25 m off on sparse radar maps). A point off the map gets ``p_unknown``.
The caller may pass its own ``p_unknown`` (the filter scores unknown space higher while it
tracks than while it searches, ``MonteCarloLocalizer.p_unknown``); a table per value is kept.
Evaluated for P particles x N points at once (numpy, no loop over particles).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation, distance_transform_edt

from smokyslam.config import LocalizeConfig
from smokyslam.errors import MapError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN


class LikelihoodField:
    """``log_likelihood(particles, points)``: how well each pose explains the points."""

    def __init__(self, cells: np.ndarray, spec: GridSpec, config: LocalizeConfig) -> None:
        """``cells``: (rows, cols) trinary grid over ``spec`` (a map_server map)."""
        sigma_m, z_hit, z_rand = config.hit_sigma_m, config.z_hit, config.z_rand
        max_range_m, p_unknown = config.max_range_m, config.p_unknown
        cells = np.asarray(cells)
        occupied = cells == OCCUPIED
        if not occupied.any():
            raise MapError("the map has no occupied cell: there is nothing to localize against")
        # A radar sees surfaces: distances are to occupied cells bordering free space (a
        # solid block's inside would otherwise reward points that went through its walls).
        surface = occupied & binary_dilation(cells == FREE, np.ones((3, 3), dtype=bool))
        if not surface.any():
            surface = occupied
        distance_m = distance_transform_edt(~surface) * spec.resolution_m
        p_hit = np.exp(-0.5 * (distance_m / sigma_m) ** 2) / (np.sqrt(2 * np.pi) * sigma_m)
        self._likelihood = z_hit * p_hit + z_rand / max_range_m
        self._unknown = cells == UNKNOWN
        self._tables: dict[float, np.ndarray] = {}
        self.p_unknown = p_unknown
        """The ``p_unknown`` used when :meth:`log_likelihood` is given none."""
        self.spec = spec
        iy, ix = np.nonzero(cells == 0)
        self.free_xy = spec.centres_of(np.column_stack([ix, iy]))
        """(M, 2) centres of the free cells: where a global search spreads its particles."""

    def _table(self, p_unknown: float) -> np.ndarray:
        """The (rows, cols) log-likelihood of a point in each cell, unknown cells at least
        ``p_unknown`` (one table per value, made once)."""
        if p_unknown not in self._tables:
            likelihood = self._likelihood.copy()
            likelihood[self._unknown] = np.maximum(likelihood[self._unknown], p_unknown)
            self._tables[p_unknown] = np.log(likelihood).astype(np.float32)
        return self._tables[p_unknown]

    def log_likelihood(
        self, particles: np.ndarray, points_xy: np.ndarray, p_unknown: float | None = None
    ) -> np.ndarray:
        """(P,) summed log-likelihood of (N, 2) base-frame points seen from (P, 3) poses, a
        point in unknown space or off the map scoring at least ``p_unknown`` (default: the
        config's)."""
        particles = np.asarray(particles, dtype=float).reshape(-1, 3)
        points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        if len(points) == 0:
            return np.zeros(len(particles))
        c, s = np.cos(particles[:, 2])[:, None], np.sin(particles[:, 2])[:, None]
        x = particles[:, 0:1] + c * points[None, :, 0] - s * points[None, :, 1]
        y = particles[:, 1:2] + s * points[None, :, 0] + c * points[None, :, 1]
        ix = np.floor((x - self.spec.origin_xy_m[0]) / self.spec.resolution_m).astype(np.int64)
        iy = np.floor((y - self.spec.origin_xy_m[1]) / self.spec.resolution_m).astype(np.int64)
        p_unknown = self.p_unknown if p_unknown is None else float(p_unknown)
        table = self._table(p_unknown)
        rows, cols = table.shape
        inside = (ix >= 0) & (ix < cols) & (iy >= 0) & (iy < rows)
        values = np.full(ix.shape, np.log(p_unknown), dtype=float)
        values[inside] = table[iy[inside], ix[inside]]
        return values.sum(axis=1)
