"""The occupancy grid every map uses (radar, visual, fused): log-odds cells that grow on demand.

Cells are aligned with the world origin: world cell ``[ix, iy]`` covers
``[ix * r, (ix + 1) * r) x [iy * r, (iy + 1) * r)`` for resolution ``r``. Storage is a dense
float32 log-odds array indexed ``[iy, ix]`` over a window of world cells that grows by a
margin when an update falls outside it, so growth is amortized over many updates.

One ``update`` is one observation. Each cell changes at most once per update, however many
rays cross it or returns fall in it; a cell that is both passed through and hit in the same
update counts as hit (occupied wins: the return is direct evidence, while the pass may be a
neighbouring ray grazing the surface).
"""

from __future__ import annotations

import itertools

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.errors import MapError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import trinary_from_probability
from smokyslam.mapping.raycast import ray_lengths, raycast

_MAX_CELLS = 200_000_000  # 0.8 GB of log-odds; beyond it the poses are broken, not the building
_RAY_CELLS_PER_PIECE = 2_000_000


class OccupancyGrid:
    """Log-odds occupancy grid with clamping and bounds that grow.

    resolution_m: cell side. log_odds_hit / log_odds_miss: added per update to hit / passed
    cells. log_odds_min / log_odds_max: clamp. occupied_thresh / free_thresh: probabilities
    used by :meth:`to_cells`. grow_margin_cells: the least extra border added when growing.
    With the config's defaults one hit makes a cell occupied (p = 0.70) and two passes make it
    free (p = 0.18): sparse radar rarely crosses a cell more often than that.
    """

    def __init__(
        self,
        resolution_m: float,
        log_odds_hit: float,
        log_odds_miss: float,
        log_odds_min: float,
        log_odds_max: float,
        occupied_thresh: float,
        free_thresh: float,
        grow_margin_cells: int = 64,
    ) -> None:
        self.resolution_m = float(resolution_m)
        self.log_odds_hit = float(log_odds_hit)
        self.log_odds_miss = float(log_odds_miss)
        self.log_odds_min = float(log_odds_min)
        self.log_odds_max = float(log_odds_max)
        self.occupied_thresh = float(occupied_thresh)
        self.free_thresh = float(free_thresh)
        self.grow_margin_cells = int(grow_margin_cells)
        self._log_odds = np.zeros((0, 0), dtype=np.float32)
        self._offset_ixy = np.zeros(2, dtype=np.int64)  # world cell of array element [0, 0]

    def copy(self) -> OccupancyGrid:
        """An independent copy (same parameters and cells): a snapshot that later updates of
        this grid leave alone."""
        twin = self.empty_like()
        twin._log_odds, twin._offset_ixy = self._log_odds.copy(), self._offset_ixy.copy()
        return twin

    def empty_like(self) -> OccupancyGrid:
        """A new, empty grid with the same parameters."""
        return OccupancyGrid(
            self.resolution_m,
            self.log_odds_hit,
            self.log_odds_miss,
            self.log_odds_min,
            self.log_odds_max,
            self.occupied_thresh,
            self.free_thresh,
            self.grow_margin_cells,
        )

    # ------------------------------------------------------------ geometry

    @property
    def spec(self) -> GridSpec:
        """Geometry of the stored window (origin = lower-left corner of array cell [0, 0])."""
        origin = self._offset_ixy * self.resolution_m
        shape = self._log_odds.shape
        return GridSpec((float(origin[0]), float(origin[1])), self.resolution_m, shape)

    def cells_of(self, points_xy_m: np.ndarray) -> np.ndarray:
        """(N, 2) int64 world cells ``[ix, iy]`` of (N, 2) world points, metres."""
        points = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
        return np.floor(points / self.resolution_m).astype(np.int64)

    def _ensure_contains(self, low_ixy: np.ndarray, high_ixy: np.ndarray) -> None:
        """Grow the window so world cells ``low .. high`` (inclusive) lie inside it."""
        rows, cols = self._log_odds.shape
        begin, end = self._offset_ixy, self._offset_ixy + np.array([cols, rows])
        if rows and np.all(low_ixy >= begin) and np.all(high_ixy < end):
            return
        # Grow each outgrown side by at least half the current size: amortized O(1) growth.
        margin = np.maximum(self.grow_margin_cells, np.array([cols, rows]) // 2)
        if rows:
            new_begin = np.where(low_ixy < begin, low_ixy - margin, begin)
            new_end = np.where(high_ixy >= end, high_ixy + 1 + margin, end)
        else:
            new_begin, new_end = low_ixy - margin, high_ixy + 1 + margin
        new_cols, new_rows = (new_end - new_begin).tolist()
        if new_rows * new_cols > _MAX_CELLS:
            size = (new_end - new_begin) * self.resolution_m
            raise MapError(
                f"occupancy grid would grow to {size[0]:.0f} m x {size[1]:.0f} m; "
                "the poses fed to the mapper are probably diverging"
            )
        grown = np.zeros((new_rows, new_cols), dtype=np.float32)
        shift = begin - new_begin
        grown[shift[1] : shift[1] + rows, shift[0] : shift[0] + cols] = self._log_odds
        self._log_odds, self._offset_ixy = grown, new_begin

    def _flat_index(self, cells_ixy: np.ndarray) -> np.ndarray:
        local = cells_ixy - self._offset_ixy
        return local[:, 1] * self._log_odds.shape[1] + local[:, 0]

    # ------------------------------------------------------------ updates

    def update(
        self, free_cells_ixy: np.ndarray, occupied_cells_ixy: np.ndarray, weight: float = 1.0
    ) -> None:
        """Apply one observation: (N, 2) passed and (K, 2) hit world cells ``[ix, iy]``.

        Duplicates count once; a cell in both sets counts as hit only. ``weight`` scales the
        hit/miss log-odds; ``np.inf`` makes the observation decisive (cells go to the clamps).
        """
        free = np.asarray(free_cells_ixy, dtype=np.int64).reshape(-1, 2)
        occupied = np.asarray(occupied_cells_ixy, dtype=np.int64).reshape(-1, 2)
        cells = np.concatenate([free, occupied])
        if len(cells) == 0:
            return
        self._ensure_contains(cells.min(axis=0), cells.max(axis=0))
        self._apply(self._flat_index(free), self._flat_index(occupied), weight)

    def insert_rays(
        self,
        origin_cells_ixy: np.ndarray,
        end_cells_ixy: np.ndarray,
        max_range: np.ndarray | None = None,
        weight: float = 1.0,
    ) -> None:
        """Ray-cast (N,) rays and apply them as ONE observation (see :func:`raycast`).

        origin_cells_ixy: (2,) or (N, 2) world cells; end_cells_ixy: (N, 2) world cells;
        max_range: (N,) bool, rays that carry free space only; weight as in :meth:`update`.
        Large batches are cast in pieces, so memory stays bounded for millions of rays.
        """
        ends = np.asarray(end_cells_ixy, dtype=np.int64).reshape(-1, 2)
        if len(ends) == 0:
            return
        origins = np.broadcast_to(np.asarray(origin_cells_ixy, dtype=np.int64), ends.shape)
        flags = np.zeros(len(ends), bool) if max_range is None else np.asarray(max_range, bool)
        self._ensure_contains(
            np.minimum(origins.min(axis=0), ends.min(axis=0)),
            np.maximum(origins.max(axis=0), ends.max(axis=0)),
        )
        cumulative = np.cumsum(ray_lengths(origins, ends))
        if cumulative[-1] <= _RAY_CELLS_PER_PIECE:
            free, hits = raycast(origins, ends, flags)
            self._apply(self._flat_index(free), self._flat_index(hits), weight)
            return
        # Millions of cells: cast in pieces and mark passed cells in a mask (bounded memory).
        piece = cumulative // _RAY_CELLS_PER_PIECE
        edges = np.flatnonzero(np.diff(piece, prepend=-1, append=piece[-1] + 1))
        passed = np.zeros(self._log_odds.size, dtype=bool)
        hit_parts = []
        for a, b in itertools.pairwise(edges):
            free, hits = raycast(origins[a:b], ends[a:b], flags[a:b])
            passed[self._flat_index(free)] = True
            hit_parts.append(self._flat_index(hits))
        self._apply(np.flatnonzero(passed), np.concatenate(hit_parts), weight)

    def _apply(self, free_flat: np.ndarray, hit_flat: np.ndarray, weight: float) -> None:
        """Add miss / hit log-odds once per cell; hit cells ignore their passes."""
        log_odds = self._log_odds.reshape(-1)
        hit_before = log_odds[hit_flat]
        miss, hit = weight * self.log_odds_miss, weight * self.log_odds_hit
        # Fancy assignment writes every duplicate with the same value: each cell changes once.
        log_odds[free_flat] = np.maximum(log_odds[free_flat] + miss, self.log_odds_min)
        log_odds[hit_flat] = np.minimum(hit_before + hit, self.log_odds_max)

    # ------------------------------------------------------------ views

    @property
    def log_odds(self) -> np.ndarray:
        """(rows, cols) float32 log-odds, read-only view, indexed ``[iy, ix]`` over ``spec``."""
        view = self._log_odds.view()
        view.flags.writeable = False
        return view

    def probability(self) -> np.ndarray:
        """(rows, cols) float64 occupancy probability; never-observed cells are 0.5."""
        return 1.0 / (1.0 + np.exp(-self._log_odds.astype(np.float64)))

    def to_cells(self) -> np.ndarray:
        """(rows, cols) int8 trinary cells: 100 occupied, 0 free, -1 unknown (map_server)."""
        return trinary_from_probability(self.probability(), self.occupied_thresh, self.free_thresh)


def get_occupancy_grid(config: MappingConfig) -> OccupancyGrid:
    """An empty grid with the mapping config's resolution, log-odds and thresholds."""
    return OccupancyGrid(
        resolution_m=config.resolution_m,
        log_odds_hit=config.log_odds_hit,
        log_odds_miss=config.log_odds_miss,
        log_odds_min=config.log_odds_min,
        log_odds_max=config.log_odds_max,
        occupied_thresh=config.occupied_thresh,
        free_thresh=config.free_thresh,
    )


def resample_nearest(
    values: np.ndarray, spec: GridSpec, target: GridSpec, fill: float | int
) -> np.ndarray:
    """Values of a grid at the centres of another grid's cells (nearest cell), shape target.

    values: (rows, cols) over ``spec``; cells of ``target`` whose centre falls outside
    ``spec`` get ``fill``. Handles different origins and resolutions.
    """
    iy, ix = np.indices(target.shape)
    centres = target.centres_of(np.stack([ix.ravel(), iy.ravel()], axis=1))
    source = spec.cells_of(centres)
    inside = spec.inside(source)
    out = np.full(target.shape[0] * target.shape[1], fill, dtype=values.dtype)
    out[inside] = values[source[inside, 1], source[inside, 0]]
    return out.reshape(target.shape)
