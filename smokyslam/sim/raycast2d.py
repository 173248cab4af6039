"""Vectorized 2D ray casting against a World's occupied grid (shared by radar and camera).

All rays march together through the grid cells they cross (Amanatides-Woo stepping): one
Python iteration per cell step, numpy over the rays still travelling. A ray stops at the first
occupied cell, when it leaves the grid, or past ``max_range_m``.

A hit lies on a cell face. ``face_axis`` says which: 0 for a face of constant x (normal along
±x), 1 for a face of constant y. ``normal_xy`` is the face's outward unit normal, pointing back
towards the ray origin, so ``-dir · normal`` is the cosine of the incidence angle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.sim.world import World

NO_FACE = -1
"""``face_axis`` of a ray that hit nothing, or that started inside an occupied cell."""


@dataclass
class RayHits:
    """Result of casting N rays; every array is indexed by ray.

    hit: (N,) bool, True where an occupied cell was reached within range.
    distance_m: (N,) float64, metres from the origin along the ray; inf where no hit.
    points_xy_m: (N, 2) float64, world hit points; NaN where no hit.
    face_axis: (N,) int8, 0 = face of constant x, 1 = face of constant y, NO_FACE otherwise.
    normal_xy: (N, 2) float64, unit normal of the hit face (towards the origin); 0 where no face.
    cells_ixy: (N, 2) int64, grid cell [ix, iy] that was hit; -1 where no hit.
    """

    hit: np.ndarray
    distance_m: np.ndarray
    points_xy_m: np.ndarray
    face_axis: np.ndarray
    normal_xy: np.ndarray
    cells_ixy: np.ndarray

    def cos_incidence(self, directions_xy: np.ndarray) -> np.ndarray:
        """(N,) cosine of the angle between each ray and its hit face's normal; 0 where no face."""
        return np.abs(np.sum(np.asarray(directions_xy) * self.normal_xy, axis=-1))


def directions_from_angles(angles_rad: np.ndarray) -> np.ndarray:
    """(N, 2) unit vectors of world angles (counter-clockwise from +x)."""
    angles_rad = np.asarray(angles_rad, dtype=float)
    return np.stack([np.cos(angles_rad), np.sin(angles_rad)], axis=-1)


class RayCaster:
    """Casts rays through one World's occupied grid (the grid is read once, at construction)."""

    _FREE, _OCCUPIED, _OUTSIDE = 0, 1, 2

    def __init__(self, world: World) -> None:
        self.spec = world.spec
        # A one-cell border marks "outside", so stepping needs no bounds checks.
        grid = np.pad(world.occupied.astype(np.uint8), 1, constant_values=self._OUTSIDE)
        self._stride = grid.shape[1]
        self._grid = grid.ravel()

    def cast(
        self, origins_xy_m: np.ndarray, directions_xy: np.ndarray, max_range_m: float
    ) -> RayHits:
        """Cast N rays; see :func:`cast_rays`."""
        res = self.spec.resolution_m
        directions = np.asarray(directions_xy, dtype=float).reshape(-1, 2)
        n = len(directions)
        origins = np.broadcast_to(np.asarray(origins_xy_m, dtype=float), (n, 2))
        rows, cols = self.spec.shape

        # Everything below is in grid units (1 = one cell); distances convert back with * res.
        o = (origins - np.asarray(self.spec.origin_xy_m)) / res
        cell = np.floor(o).astype(np.int64)
        step = np.sign(directions).astype(np.int64)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.where(directions != 0.0, 1.0 / directions, np.inf)
            t_delta = np.abs(inv)
            t_next = np.where(step > 0, (cell + 1 - o) * inv, (cell - o) * inv)
        t_next[step == 0] = np.inf

        distance = np.full(n, np.inf)
        face = np.full(n, NO_FACE, dtype=np.int8)
        flat_hit = np.full(n, -1, dtype=np.int64)

        inside = (cell[:, 0] >= 0) & (cell[:, 1] >= 0) & (cell[:, 0] < cols) & (cell[:, 1] < rows)
        flat_start = (cell[:, 1] + 1) * self._stride + cell[:, 0] + 1
        start_occ = inside & (self._grid[np.where(inside, flat_start, 0)] == self._OCCUPIED)
        distance[start_occ] = 0.0
        flat_hit[start_occ] = flat_start[start_occ]

        max_t = max_range_m / res
        active = np.flatnonzero(inside & ~start_occ)
        flat = flat_start[active]
        tnx, tny = t_next[active, 0].copy(), t_next[active, 1].copy()
        sx, sy = step[active, 0], step[active, 1] * self._stride
        dx, dy = t_delta[active, 0], t_delta[active, 1]
        # A ray crosses at most |dx| + |dy| <= sqrt(2) * range cells before it runs out of range.
        for _ in range(int(np.ceil(np.sqrt(2.0) * max_t)) + 2):
            if active.size == 0:
                break
            along_x = tnx < tny
            t = np.minimum(tnx, tny)
            flat += np.where(along_x, sx, sy)
            np.add(tnx, dx, out=tnx, where=along_x)
            np.add(tny, dy, out=tny, where=~along_x)
            value = self._grid[flat]
            stop = (value != self._FREE) | (t > max_t)
            if not stop.any():
                continue
            hit_now = stop & (value == self._OCCUPIED) & (t <= max_t)
            done = active[hit_now]
            distance[done] = t[hit_now] * res
            face[done] = np.where(along_x[hit_now], 0, 1)
            flat_hit[done] = flat[hit_now]
            keep = ~stop
            active, flat, tnx, tny = active[keep], flat[keep], tnx[keep], tny[keep]
            sx, sy, dx, dy = sx[keep], sy[keep], dx[keep], dy[keep]

        hit = flat_hit >= 0
        points = np.full((n, 2), np.nan)
        points[hit] = origins[hit] + distance[hit, None] * directions[hit]
        normal = np.zeros((n, 2))
        on_x = face == 0
        on_y = face == 1
        normal[on_x, 0] = -step[on_x, 0]
        normal[on_y, 1] = -step[on_y, 1]
        cells = np.full((n, 2), -1, dtype=np.int64)
        cells[hit, 0] = flat_hit[hit] % self._stride - 1
        cells[hit, 1] = flat_hit[hit] // self._stride - 1
        return RayHits(hit, distance, points, face, normal, cells)


def cast_rays(
    world: World, origins_xy_m: np.ndarray, directions_xy: np.ndarray, max_range_m: float
) -> RayHits:
    """Cast rays through ``world.occupied`` (a one-off :class:`RayCaster`).

    origins_xy_m: (2,) or (N, 2) world ray origins, metres (broadcast to the N directions).
        Rays starting outside the grid report misses.
    directions_xy: (N, 2) unit directions in the world frame.
    max_range_m: hits further than this are reported as misses.
    """
    return RayCaster(world).cast(origins_xy_m, directions_xy, max_range_m)
