"""Built-in simulated buildings, generated from a seed: ``office``, ``warehouse``, ``corridor``.

Each generator lays out axis-aligned rectangles in metres (snapped to the grid): free *spaces*
(rooms, corridors, halls), *doors* cut through the walls between spaces, and *solids* standing
inside the spaces (furniture, racks, pillars). Walls are every cell within the wall thickness of
a space, so a wall band exactly that thick separates neighbouring spaces and the outer wall is
always closed. Cells outside the outer wall are ``known=False`` and ``occupied=False``: the
ground truth marks them unknown (-1), and no ray or walker can reach them.

Furniture stands flush against a wall and is at most 0.8 m deep; doors sit at least 1 m from
room corners and keep 0.8 m of floor around them clear. So every room keeps an open centre
(at least 1.1 m from anything) that a door reaches with clearance to spare.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.ndimage import binary_dilation

from smokyslam.config import SimulationConfig
from smokyslam.errors import WorldError
from smokyslam.geometry import GridSpec
from smokyslam.sim.world import World

_MARGIN_M = 1.0  # unknown floor kept around the building in the grid
_DOOR_KEEPOUT_M = 0.8  # furniture stays this far from any door opening
_FURNITURE_GAP_M = 0.3  # between two pieces of furniture
# (length min, length max, depth min, depth max) in metres: desk, cabinet, bookshelf.
_FURNITURE = ((1.2, 1.8, 0.6, 0.8), (0.8, 1.2, 0.4, 0.6), (1.6, 2.4, 0.3, 0.4))


@dataclass(frozen=True)
class _Rect:
    """Axis-aligned rectangle in metres, ``[x0, x1) x [y0, y1)``."""

    x0: float
    y0: float
    x1: float
    y1: float

    def grown(self, d_m: float) -> _Rect:
        return _Rect(self.x0 - d_m, self.y0 - d_m, self.x1 + d_m, self.y1 + d_m)

    def overlaps(self, other: _Rect) -> bool:
        return (
            self.x0 < other.x1 and other.x0 < self.x1 and self.y0 < other.y1 and other.y0 < self.y1
        )


@dataclass
class _Layout:
    """A building before rasterization; every coordinate is a multiple of the resolution."""

    wall_m: float
    start_pose: tuple[float, float, float]
    spaces: list[_Rect] = field(default_factory=list)
    doors: list[_Rect] = field(default_factory=list)
    solids: list[_Rect] = field(default_factory=list)


class _Draw:
    """Seeded random lengths snapped to the grid resolution."""

    def __init__(self, seed: int, resolution_m: float) -> None:
        self.rng = np.random.default_rng(seed)
        self.res = resolution_m

    def snap(self, value_m: float) -> float:
        return round(value_m / self.res) * self.res

    def length(self, low_m: float, high_m: float) -> float:
        return self.snap(self.rng.uniform(low_m, high_m))

    def chance(self, p: float) -> bool:
        return bool(self.rng.random() < p)


def _furnish(room: _Rect, blocked: list[_Rect], draw: _Draw) -> list[_Rect]:
    """2-5 pieces of furniture flush against the walls of ``room``, clear of ``blocked``."""
    items: list[_Rect] = []
    for _ in range(int(draw.rng.integers(2, 6))):
        for _attempt in range(12):
            l_lo, l_hi, d_lo, d_hi = _FURNITURE[int(draw.rng.integers(len(_FURNITURE)))]
            length, depth = draw.length(l_lo, l_hi), draw.length(d_lo, d_hi)
            wall = int(draw.rng.integers(4))
            along_x = wall < 2
            span = (room.x1 - room.x0) if along_x else (room.y1 - room.y0)
            if length > span - 0.2:
                continue
            offset = draw.snap(draw.rng.uniform(0.0, span - length))
            if along_x:
                x0 = room.x0 + offset
                y0 = room.y0 if wall == 0 else room.y1 - depth
                rect = _Rect(x0, y0, x0 + length, y0 + depth)
            else:
                y0 = room.y0 + offset
                x0 = room.x0 if wall == 2 else room.x1 - depth
                rect = _Rect(x0, y0, x0 + depth, y0 + length)
            grown = rect.grown(_FURNITURE_GAP_M)
            if any(rect.overlaps(b) for b in blocked) or any(grown.overlaps(i) for i in items):
                continue
            items.append(rect)
            break
    return items


def _split(total_m: float, wall_m: float, draw: _Draw) -> list[tuple[float, float]]:
    """Room intervals ``[a, b)`` covering ``[0, total)``, 3.8-6 m wide, separated by walls."""
    rooms, x = [], 0.0
    while True:
        width = draw.length(3.8, 6.0)
        if total_m - (x + width + wall_m) < 3.8:
            rooms.append((x, total_m))
            return rooms
        rooms.append((x, x + width))
        x += width + wall_m


def _office(draw: _Draw) -> _Layout:
    """Rooms on both sides of a straight corridor, with doors, side doors and furniture."""
    wall = max(draw.res, draw.snap(float(draw.rng.choice([0.1, 0.2]))))
    width = draw.length(20.0, 30.0)
    corridor_w = draw.length(2.0, 2.4)
    south_d, north_d = draw.length(4.8, 7.5), draw.length(4.8, 7.5)
    corridor = _Rect(0.0, south_d + wall, width, south_d + wall + corridor_w)
    layout = _Layout(wall, (1.5 + 0.5 * draw.res, 0.5 * (corridor.y0 + corridor.y1), 0.0))
    layout.spaces.append(corridor)
    bands = ((0.0, south_d, True), (corridor.y1 + wall, corridor.y1 + wall + north_d, False))
    rooms: list[_Rect] = []
    for y0, y1, door_on_north in bands:
        intervals = _split(width, wall, draw)
        for i, (x0, x1) in enumerate(intervals):
            room = _Rect(x0, y0, x1, y1)
            rooms.append(room)
            door_w = draw.length(0.9, 1.0)
            dx = draw.snap(draw.rng.uniform(x0 + 1.0, x1 - 1.0 - door_w))
            dy = y1 if door_on_north else y0 - wall
            layout.doors.append(_Rect(dx, dy, dx + door_w, dy + wall))
            if i + 1 < len(intervals) and draw.chance(0.35):
                side_y = draw.snap(draw.rng.uniform(y0 + 1.0, y1 - 1.0 - door_w))
                layout.doors.append(_Rect(x1, side_y, x1 + wall, side_y + door_w))
    layout.spaces.extend(rooms)
    keepouts = [d.grown(_DOOR_KEEPOUT_M) for d in layout.doors]
    for room in rooms:
        layout.solids.extend(_furnish(room, keepouts, draw))
    return layout


def _warehouse(draw: _Draw) -> _Layout:
    """A hall with rows of racks split by cross aisles, a staging area with pillars and pallets."""
    width, depth = draw.length(30.0, 40.0), draw.length(20.0, 26.0)
    staging = draw.length(5.0, 7.0)
    end_aisle, rack_d, aisle = draw.length(2.6, 3.2), draw.length(1.0, 1.2), draw.length(2.4, 3.0)
    start = (2.0 + 0.5 * draw.res, draw.snap(0.5 * staging) + 0.5 * draw.res, 0.0)
    layout = _Layout(0.2, start, spaces=[_Rect(0.0, 0.0, width, depth)])
    cuts, x = [], end_aisle  # rack segments along x, shared by every row so cross aisles align
    while width - end_aisle - x >= 2.0:
        x1 = min(x + draw.length(8.0, 12.0), width - end_aisle)
        cuts.append((x, x1))
        x = x1 + aisle
    y = staging
    while y + rack_d + 2.6 <= depth:
        layout.solids.extend(_Rect(a, y, b, y + rack_d) for a, b in cuts)
        y += rack_d + aisle
    x = draw.length(5.0, 7.0)
    while x < width - 3.0:
        pillar_y = draw.snap(0.5 * staging)
        layout.solids.append(_Rect(x, pillar_y, x + 0.4, pillar_y + 0.4))
        x += draw.length(7.0, 9.0)
    blocked = [
        *layout.solids,
        _Rect(start[0] - 1.6, start[1] - 1.6, start[0] + 1.6, start[1] + 1.6),
    ]
    for _ in range(int(draw.rng.integers(3, 7))):
        px, py = draw.length(1.0, width - 2.2), draw.length(0.6, staging - 1.6)
        pallet = _Rect(px, py, px + 1.2, py + 1.0)
        if not any(pallet.grown(1.2).overlaps(b) for b in blocked):
            layout.solids.append(pallet)
            blocked.append(pallet)
    return layout


def _corridor(draw: _Draw) -> _Layout:
    """A long corridor with right-angle bends, side rooms, and wall cabinets along it."""
    wall = max(draw.res, draw.snap(float(draw.rng.choice([0.1, 0.2]))))
    # Half the width on the grid too (every layout coordinate is): an odd number of cells
    # across put every wall half a cell off the lattice that maps are built on.
    half = draw.snap(0.5 * draw.length(2.0, 2.6))
    layout = _Layout(wall, (1.5 + 0.5 * draw.res, 0.5 * draw.res, 0.0))
    segments: list[tuple[_Rect, bool]] = []  # (corridor rectangle, runs along x)
    px = py = 0.0
    for i in range(int(draw.rng.integers(4, 6))):
        along_x = i % 2 == 0
        length = draw.length(8.0, 14.0) if along_x else draw.length(6.0, 10.0)
        qx, qy = (
            (px + length, py) if along_x else (px, py + length * (1 if draw.chance(0.5) else -1))
        )
        rect = _Rect(min(px, qx) - half, min(py, qy) - half, max(px, qx) + half, max(py, qy) + half)
        segments.append((rect, along_x))
        px, py = qx, qy
    layout.spaces.extend(rect for rect, _ in segments)
    rooms: list[_Rect] = []
    for k, (seg, along_x) in enumerate(segments):
        for side in (-1, 1):
            if not draw.chance(0.6):
                continue
            size, depth, door_w = (
                draw.length(3.8, 5.0),
                draw.length(4.0, 5.5),
                draw.length(0.9, 1.0),
            )
            lo, hi = (seg.x0, seg.x1) if along_x else (seg.y0, seg.y1)
            if hi - lo - 4.0 * half < size:
                continue
            # The room can fit exactly; the two sums then differ by rounding (corridor 10062).
            first, last = lo + 2.0 * half, hi - 2.0 * half - size
            a = draw.snap(draw.rng.uniform(first, max(first, last)))
            d = draw.snap(draw.rng.uniform(a + 1.0, a + size - 1.0 - door_w))
            if along_x:
                y0 = seg.y1 + wall if side > 0 else seg.y0 - wall - depth
                room = _Rect(a, y0, a + size, y0 + depth)
                dy = seg.y1 if side > 0 else seg.y0 - wall
                door = _Rect(d, dy, d + door_w, dy + wall)
            else:
                x0 = seg.x1 + wall if side > 0 else seg.x0 - wall - depth
                room = _Rect(x0, a, x0 + depth, a + size)
                dx = seg.x1 if side > 0 else seg.x0 - wall
                door = _Rect(dx, d, dx + wall, d + door_w)
            others = [s for j, (s, _) in enumerate(segments) if j != k] + rooms
            if any(room.grown(wall + 0.5).overlaps(o) for o in others):
                continue
            rooms.append(room)
            layout.doors.append(door)
    layout.spaces.extend(rooms)
    keepouts = [d.grown(_DOOR_KEEPOUT_M) for d in layout.doors]
    for room in rooms:
        layout.solids.extend(_furnish(room, keepouts, draw))
    start_zone = _Rect(-half, -half, 4.0, half)
    for seg, along_x in segments:  # 0.3 m deep wall cabinets, away from bends and doors
        blocked = [*keepouts, start_zone, *layout.solids]
        if along_x and draw.chance(0.7):
            cx = draw.snap(draw.rng.uniform(seg.x0 + 2.5 * half, seg.x1 - 2.5 * half - 0.8))
            y0 = seg.y0 if draw.chance(0.5) else seg.y1 - 0.3
            cabinet = _Rect(cx, y0, cx + 0.8, y0 + 0.3)
            if not any(cabinet.overlaps(b) for b in blocked):
                layout.solids.append(cabinet)
    return layout


def _rasterize(name: str, layout: _Layout, config: SimulationConfig) -> World:
    """Paint a layout onto a grid: spaces free, a wall band around them, doors cut, solids."""
    res = config.resolution_m
    wall_cells = max(1, round(layout.wall_m / res))
    pad = wall_cells * res + _MARGIN_M
    x_min = min(r.x0 for r in layout.spaces) - pad
    y_min = min(r.y0 for r in layout.spaces) - pad
    cols = round((max(r.x1 for r in layout.spaces) + pad - x_min) / res)
    rows = round((max(r.y1 for r in layout.spaces) + pad - y_min) / res)
    spec = GridSpec(origin_xy_m=(x_min, y_min), resolution_m=res, shape=(rows, cols))

    def paint(rects: list[_Rect]) -> np.ndarray:
        mask = np.zeros((rows, cols), dtype=bool)
        for r in rects:
            ix0, ix1 = round((r.x0 - x_min) / res), round((r.x1 - x_min) / res)
            iy0, iy1 = round((r.y0 - y_min) / res), round((r.y1 - y_min) / res)
            mask[max(iy0, 0) : iy1, max(ix0, 0) : ix1] = True
        return mask

    spaces = paint(layout.spaces)
    free = spaces | paint(layout.doors)
    band = np.ones((2 * wall_cells + 1, 2 * wall_cells + 1), dtype=bool)
    walls = binary_dilation(spaces, structure=band) & ~free
    occupied = walls | (paint(layout.solids) & free)
    start = np.array(layout.start_pose, dtype=float)
    return World(name, occupied, free | walls, spec, config.wall_height_m, start)


_GENERATORS: dict[str, Callable[[_Draw], _Layout]] = {
    "office": _office,
    "warehouse": _warehouse,
    "corridor": _corridor,
}
WORLD_NAMES = tuple(_GENERATORS)


def generate_world(name: str, seed: int, config: SimulationConfig) -> World:
    """One of the built-in worlds (``WORLD_NAMES``), laid out from ``seed``; same seed, same world.

    office: 20-30 x 12-18 m, rooms off a 2.0-2.4 m corridor, 0.9-1.0 m doors, furniture.
    warehouse: 30-40 x 20-26 m hall, racks in rows with 2.4-3.0 m aisles, pillars, pallets.
    corridor: a 2.0-2.6 m corridor with 3-4 right-angle bends and furnished side rooms.
    Grids use ``config.resolution_m``; walls stand ``config.wall_height_m`` tall.
    """
    if name not in _GENERATORS:
        raise WorldError(f"unknown world '{name}': choose one of {', '.join(WORLD_NAMES)}")
    layout = _GENERATORS[name](_Draw(seed, config.resolution_m))
    return _rasterize(name, layout, config)


def build_world(name_or_path: str | Path, seed: int, config: SimulationConfig) -> World:
    """A built-in world by name, or a map_server floor plan given as a path to its YAML file."""
    text = str(name_or_path)
    if text in _GENERATORS:
        return generate_world(text, seed, config)
    path = Path(text)
    if path.suffix.lower() in (".yaml", ".yml") or path.exists():
        from smokyslam.sim.floorplan import world_from_floorplan

        return world_from_floorplan(path, config)
    raise WorldError(
        f"unknown world '{text}': choose one of {', '.join(WORLD_NAMES)}, "
        "or give the path of a map_server .yaml floor plan"
    )
