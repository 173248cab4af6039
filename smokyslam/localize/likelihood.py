"""The measurement model of the localizer: a likelihood field over a saved map.

The distance from every cell to the nearest wall surface (an occupied cell bordering free
space, see below for tracking; a Euclidean distance transform)
gives each radar point a likelihood ``z_hit N(d; 0, sigma) + z_rand / max_range``. A point in
unknown space gets at least the ``p_unknown`` a map that never saw that space can honestly
give, and more where it lies near a wall: a radar map sees a wall from one side only, and a
point just behind it is as near it as one just in front (scoring unknown space flat pushed
the filter about 0.25 m off on sparse radar maps). A point off the map gets ``p_unknown``.
The caller may pass its own ``p_unknown`` (the filter scores unknown space higher while it
tracks than while it searches, ``MonteCarloLocalizer.p_unknown``); a table per value is kept.

Scored above the search's ``p_unknown`` (while tracking), unknown space also lends its score
to the free cells at its edge, fading as a Gaussian of ``hit_sigma_m`` with their distance
to it. The edge of what a map saw free is where its rays ended, often on a wall the map never
marked: a stitched radar map's walls are scattered returns, and an up-sampled map drops some.
A point there scored as open free space (``z_rand / max_range``, 0.02), 1/15 of unknown
space's 0.3, so the few points on such a wall outweighed the rest of the scan. In the fused
map of office 20017, the far wall of a room beside the start was free up to it and unknown
beyond, and the filter tracked a place 3.5 m along the corridor whose walls the map knew,
for 9.6 s. A search keeps the edge out: there a wrong place near the map's border would gain
from it (global localization in fused maps of 20 offices: 18 instead of 20 converged).

While tracking, the surfaces are also the occupied cells that border unknown space, not only
free space. An up-sampled or fused map often leaves a cell of unknown space between a room's
free space and its wall, and a wall a SLAM run drew twice is two or three cells thick; a return
on such a wall scored as open space. In the fused map a `run` made of warehouse 20025, the
wall beside the start is such a wall, and the true place fitted worse than the same place 4 m
over, on the neighbouring aisle, for the first 10 s of scans; now for the first 5 s. A search
keeps to the walls that border free space: with the wider surfaces there too, global
localization in 20 offices converged within 20 s in 19 instead of 20, in fused maps and in
true-pose dense maps alike.

A likelihood field scores a point by its distance to the nearest wall, whichever side of it
the point lies on, but a radar return is the first surface on its ray. Its ray cannot have
gone through a wall just before it. Without that the field is lopsided: seen from inside a
room, the space beyond its walls is full of other walls, and the room itself is open. A pose
too far forward puts the points just beyond the walls ahead, near those surfaces, and costs
little. A pose too far back puts them in open space, and costs much. Measured on simulated
offices, the filter then sat 0.06-0.07 m ahead of the truth along the heading. So each point
also looks back along its ray, from the radar (:meth:`seen_from`), at ``ray_check_m``. Every
place there that the map has occupied multiplies the point's likelihood by ``ray_blocked``.
The places must be at least :data:`MIN_CHECK_RANGE_M` from the radar.

Evaluated for P particles x N points at once (numpy, no loop over particles).
"""

from __future__ import annotations

import copy

import numpy as np
from scipy.ndimage import binary_dilation, distance_transform_edt

from smokyslam.config import LocalizeConfig
from smokyslam.errors import MapError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN

MIN_CHECK_RANGE_M = 0.3
"""Places looked at along a ray lie at least this far from the radar (its least range)."""


class LikelihoodField:
    """``log_likelihood(particles, points)``: how well each pose explains the points."""

    def __init__(self, cells: np.ndarray, spec: GridSpec, config: LocalizeConfig) -> None:
        """``cells``: (rows, cols) trinary grid over ``spec`` (a map_server map)."""
        cells = np.asarray(cells)
        occupied = cells == OCCUPIED
        if not occupied.any():
            raise MapError("the map has no occupied cell: there is nothing to localize against")
        self.spec = spec
        self._settings = config
        # A radar sees surfaces: distances are to occupied cells bordering free space (a
        # solid block's inside would otherwise reward points that went through its walls).
        self._likelihood = self._hit_field(occupied, cells == FREE)
        self._occupied = occupied
        self._unknown = cells == UNKNOWN
        self._occupied_flat = np.pad(occupied, 1).astype(np.int8).ravel()
        self._ray_check_m = np.asarray(config.ray_check_m, dtype=float)
        self._log_blocked = float(np.log(config.ray_blocked))
        self.sensor_xy_m = np.zeros(2)
        """Where the rays start, in the frame of the points (base_link): the radar."""
        self._tables: dict[float, np.ndarray] = {}
        self.p_unknown = config.p_unknown
        """The ``p_unknown`` used when :meth:`log_likelihood` is given none."""
        iy, ix = np.nonzero(cells == 0)
        self.free_xy = spec.centres_of(np.column_stack([ix, iy]))
        """(M, 2) centres of the free cells: where a global search spreads its particles."""

    def seen_from(self, sensor_xy_m: np.ndarray) -> LikelihoodField:
        """This field, for points whose rays start at (2,) ``sensor_xy_m`` in their frame (the
        radar's position on base_link). The tables are shared."""
        field = copy.copy(self)
        field.sensor_xy_m = np.asarray(sensor_xy_m, dtype=float).reshape(2)
        return field

    def _table(self, p_unknown: float) -> np.ndarray:
        """The flat log-likelihood of a point in each cell of the map padded by one cell
        (the padding: off the map, ``log(p_unknown)``), unknown cells at least ``p_unknown``.
        Above the search's ``p_unknown`` the free cells at their edge get at least that,
        faded by their distance to them, and the surfaces are the occupied cells bordering
        any cell not occupied, unknown ones too (one table per value, made once)."""
        if p_unknown not in self._tables:
            if p_unknown > self.p_unknown:
                hits = self._hit_field(self._occupied, ~self._occupied)
                likelihood = np.maximum(hits, p_unknown * self._unknown_edge())
            else:
                likelihood = np.maximum(self._likelihood, np.where(self._unknown, p_unknown, 0.0))
            padded = np.pad(likelihood, 1, constant_values=p_unknown)
            self._tables[p_unknown] = np.log(padded).astype(np.float32).ravel()
        return self._tables[p_unknown]

    def _hit_field(self, occupied: np.ndarray, open_space: np.ndarray) -> np.ndarray:
        """``z_hit N(d; 0, sigma) + z_rand / max_range`` of each cell's distance ``d`` to the
        nearest surface: an ``occupied`` cell bordering ``open_space`` (any occupied cell
        where none does)."""
        s = self._settings
        surface = occupied & binary_dilation(open_space, np.ones((3, 3), dtype=bool))
        if not surface.any():
            surface = occupied
        distance_m = distance_transform_edt(~surface) * self.spec.resolution_m
        sigma_m = s.hit_sigma_m
        p_hit = np.exp(-0.5 * (distance_m / sigma_m) ** 2) / (np.sqrt(2 * np.pi) * sigma_m)
        return s.z_hit * p_hit + s.z_rand / s.max_range_m

    def _unknown_edge(self) -> np.ndarray:
        """1 in unknown space, fading as a Gaussian of ``hit_sigma_m`` with the distance to it
        (0 everywhere in a map without unknown space); made for a tracking table only."""
        if not self._unknown.any():
            return np.zeros(self._unknown.shape)
        to_unknown_m = distance_transform_edt(~self._unknown) * self.spec.resolution_m
        return np.exp(-0.5 * (to_unknown_m / self._settings.hit_sigma_m) ** 2)

    def log_likelihood(
        self, particles: np.ndarray, points_xy: np.ndarray, p_unknown: float | None = None
    ) -> np.ndarray:
        """(P,) summed log-likelihood of (N, 2) base-frame points seen from (P, 3) poses, a
        point in unknown space or off the map scoring at least ``p_unknown`` (default: the
        config's), and ``log(ray_blocked)`` for each place before a point that its ray went
        through a wall at."""
        particles = np.asarray(particles, dtype=float).reshape(-1, 3)
        points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        if len(points) == 0:
            return np.zeros(len(particles))
        p_unknown = self.p_unknown if p_unknown is None else float(p_unknown)
        table = self._table(p_unknown)
        behind = self._places_before(points)
        cells = self._cells_of(particles, np.vstack([points, behind]))
        n = len(points)
        score = np.take(table, cells[:, :n]).sum(axis=1, dtype=float)
        if len(behind):
            score += self._log_blocked * np.take(self._occupied_flat, cells[:, n:]).sum(axis=1)
        return score

    def _places_before(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) the places ``ray_check_m`` before each point on its ray from the sensor,
        those at least :data:`MIN_CHECK_RANGE_M` from it."""
        ray = points - self.sensor_xy_m
        reach = np.linalg.norm(ray, axis=1)
        unit = ray / np.maximum(reach, 1e-9)[:, None]
        places = [np.zeros((0, 2))]
        for back in self._ray_check_m:
            far_enough = reach - back >= MIN_CHECK_RANGE_M
            places.append(points[far_enough] - back * unit[far_enough])
        return np.vstack(places)

    def _cells_of(self, particles: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(P, N) flat index, in the padded tables, of the cell of every point seen from
        every pose (points off the map: a padding cell)."""
        rows, cols = self._likelihood.shape
        inverse = 1.0 / self.spec.resolution_m
        # in cells of the padded grid (cell 0 is the padding), single precision (a map of
        # 10^4 cells a side stays within 10^-3 of a cell): clipping keeps every point off
        # the map in a padding cell, and truncation floors what stays non-negative
        c = np.cos(particles[:, 2:3]).astype(np.float32)
        s = np.sin(particles[:, 2:3]).astype(np.float32)
        px = (points[:, 0] * inverse).astype(np.float32)
        py = (points[:, 1] * inverse).astype(np.float32)
        origin = (particles[:, :2] - self.spec.origin_xy_m) * inverse + 1.0
        col = c * px
        col -= s * py
        col += origin[:, 0:1].astype(np.float32)
        row = s * px
        row += c * py
        row += origin[:, 1:2].astype(np.float32)
        np.clip(col, 0.0, cols + 1.0, out=col)
        np.clip(row, 0.0, rows + 1.0, out=row)
        index = row.astype(np.int32)
        index *= cols + 2
        index += col.astype(np.int32)
        return index
