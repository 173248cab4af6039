"""The walkable grid graph of a World, shortest paths on it, and closed tours of its open spots.

1. Walkable cells: clearance >= ``clearance_m`` + 1.5 cells, connected to the start.
2. Stops: the start, then open spots (clearance maxima with room for a loop) >= 3 m apart.
3. Tours: cheapest insertion + 2-opt on grid distances, one per number of stops, so a short
   walk stays near the start and a long one visits everything (and repeats if need be).
4. Legs: Dijkstra on the 8-connected grid, dearer near walls so paths keep to the middle.

Clearance is the distance transform of the free space (cell centre to the nearest occupied cell
centre), metres. :mod:`smokyslam.sim.planner` turns the tours into smooth, timed walks.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import distance_transform_edt, label, maximum_filter
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from smokyslam.config import TrajectoryConfig
from smokyslam.errors import WorldError
from smokyslam.sim.world import World

_WAYPOINT_SPACING_M = 3.0
_MAX_WAYPOINTS = 30
_COST_REF_M, _COST_WEIGHT = 1.2, 3.0  # grid steps with clearance c cost 1 + w * (1 - c / ref)


def clearance_map_m(world: World) -> np.ndarray:
    """(rows, cols) metres from each cell centre to the nearest occupied cell centre (0 inside)."""
    return distance_transform_edt(~world.occupied) * world.spec.resolution_m


def walk_clearance_m(config: TrajectoryConfig, resolution_m: float) -> float:
    """Clearance of the grid cells paths may use: ``clearance_m`` plus 1.5 cells for smoothing."""
    return config.clearance_m + 1.5 * resolution_m


class WalkGrid:
    """The walkable grid graph from the start, with Dijkstra distances from the waypoints."""

    def __init__(self, world: World, config: TrajectoryConfig) -> None:
        if world.start_pose is None:
            raise WorldError(f"world '{world.name}' has no start pose")
        self.spec = world.spec
        res = world.spec.resolution_m
        self.clearance = clearance_map_m(world)
        walkable = (self.clearance >= walk_clearance_m(config, res)) & world.known
        ix, iy = world.spec.cells_of(np.asarray(world.start_pose[:2])[None])[0]
        inside = bool(world.spec.inside(np.array([[ix, iy]]))[0])
        if not (inside and walkable[iy, ix]):
            have = self.clearance[iy, ix] if inside else 0.0
            raise WorldError(
                f"start pose of world '{world.name}' is {have:.2f} m from a wall; "
                f"a walk needs {walk_clearance_m(config, res):.2f} m"
            )
        labels, _ = label(walkable, structure=np.ones((3, 3)))
        self.walkable = labels == labels[iy, ix]
        self.start_cell = (iy, ix)
        self.node_of = np.full(walkable.shape, -1, dtype=np.int64)
        cells = np.argwhere(self.walkable)
        self.node_of[cells[:, 0], cells[:, 1]] = np.arange(len(cells))
        self.cells = cells
        cost = 1.0 + _COST_WEIGHT * np.clip(1.0 - self.clearance / _COST_REF_M, 0.0, None)
        rows, cols, weights = [], [], []
        for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
            a = cells
            b = a + np.array([dy, dx])
            ok = (b[:, 0] < walkable.shape[0]) & (b[:, 1] >= 0) & (b[:, 1] < walkable.shape[1])
            a, b = a[ok], b[ok]
            ok = self.walkable[b[:, 0], b[:, 1]]
            a, b = a[ok], b[ok]
            step = np.hypot(dy, dx) * res
            rows.append(self.node_of[a[:, 0], a[:, 1]])
            cols.append(self.node_of[b[:, 0], b[:, 1]])
            weights.append(step * 0.5 * (cost[a[:, 0], a[:, 1]] + cost[b[:, 0], b[:, 1]]))
        n = len(cells)
        self.graph = csr_matrix(
            (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
        )

    def waypoints(self, needed_m: float) -> np.ndarray:
        """(K, 2) cells [iy, ix], start first, then open spots >= needed_m clear, spread out."""
        res = self.spec.resolution_m
        # At most ~_MAX_WAYPOINTS stops: big halls get sparser ones (Dijkstra runs once per stop).
        area_m2 = len(self.cells) * res**2
        spacing = round(max(_WAYPOINT_SPACING_M, np.sqrt(area_m2 / _MAX_WAYPOINTS)) / res)
        c = np.where(self.walkable, self.clearance, 0.0)
        peaks = (c >= needed_m) & (c >= maximum_filter(c, size=max(3, spacing // 3)))
        cand = np.argwhere(peaks)
        cand = cand[np.argsort(-c[cand[:, 0], cand[:, 1]], kind="stable")]
        chosen = [np.array(self.start_cell)]
        for cell in cand:
            if np.min(np.hypot(*(np.array(chosen) - cell).T)) >= spacing:
                chosen.append(cell)
        return np.array(chosen)

    def legs(self, waypoint_cells: np.ndarray) -> WalkLegs:
        """Shortest paths between the (K, 2) waypoint cells [iy, ix]; costs in weighted metres."""
        nodes = self.node_of[waypoint_cells[:, 0], waypoint_cells[:, 1]]
        dist, pred = dijkstra(self.graph, directed=False, indices=nodes, return_predecessors=True)
        return WalkLegs(self, nodes, dist[:, nodes], pred)


class WalkLegs:
    """Shortest grid paths between waypoints, as (M, 2) world polylines, extracted on demand."""

    def __init__(self, grid: WalkGrid, nodes: np.ndarray, cost: np.ndarray, pred: np.ndarray):
        self.grid, self.nodes, self.cost, self.pred = grid, nodes, cost, pred
        self._cache: dict[tuple[int, int], np.ndarray] = {}

    def path(self, i: int, j: int) -> np.ndarray:
        """(M, 2) world cell centres, metres, from waypoint ``i`` to waypoint ``j``."""
        if (i, j) not in self._cache:
            chain = [int(self.nodes[j])]
            while chain[-1] != self.nodes[i]:  # loop over path length, not cells
                chain.append(int(self.pred[i, chain[-1]]))
            cells = self.grid.cells[chain[::-1]]
            self._cache[(i, j)] = self.grid.spec.centres_of(cells[:, ::-1])
            self._cache[(j, i)] = self._cache[(i, j)][::-1]
        return self._cache[(i, j)]


def _two_opt(cost: np.ndarray, tour: list[int]) -> list[int]:
    """Reverse the best segment until no reversal shortens the closed tour (symmetric costs)."""
    while len(tour) > 1:
        cycle = np.array([0, *tour, 0])
        i = np.arange(1, len(cycle) - 1)
        before, first, last, after = cycle[i - 1], cycle[i], cycle[i], cycle[i + 1]
        delta = (
            cost[before[:, None], last[None, :]]
            + cost[first[:, None], after[None, :]]
            - cost[before, first][:, None]
            - cost[last, after][None, :]
        )
        delta[np.tril_indices(len(i))] = 0.0
        a, b = np.unravel_index(int(np.argmin(delta)), delta.shape)
        if delta[a, b] > -1e-9:
            break
        tour = tour[:a] + tour[a : b + 1][::-1] + tour[b + 1 :]
    return tour


def growing_tours(cost: np.ndarray, rng: np.random.Generator) -> list[list[int]]:
    """Closed tours from waypoint 0: ``tours[j]`` visits j waypoints, each tour a superset of the
    previous one (cheapest insertion, then 2-opt), so short walks stay near the start.
    """
    k = len(cost)
    tours, tour = [[]], []
    left = list(range(1, k))
    while left:
        cycle = np.array([0, *tour, 0])
        a, b, w = cycle[:-1][None, :], cycle[1:][None, :], np.array(left)[:, None]
        detour = (cost[a, w] + cost[w, b] - cost[a, b]).min(axis=1)
        best = left.pop(int(np.argmin(detour)))
        edge = int(np.argmin(cost[cycle[:-1], best] + cost[best, cycle[1:]] - cost[a[0], b[0]]))
        tour = _two_opt(cost, [*tour[:edge], best, *tour[edge:]])
        tours.append(tour[::-1] if rng.random() < 0.5 else tour)
    return tours


def tour_stops(tours: list[list[int]], c: int) -> list[int]:
    """Stops of the c-th walk in growing order: the start, then ``tours[c]``."""
    return [0, *tours[c]]
