"""Ground truth from a lidar point cloud (``.ply`` / ``.pcd``), flattened onto a map's grid.

Real datasets ship their lidar maps as point clouds. The points in a height band (leaving
out floor and ceiling) are walls: their cells are occupied. A cloud says nothing directly
about free space, so the truth takes as free the cells the scored map knows inside the
cloud's footprint (its xy bounding box) that hold no wall point; elsewhere it is unknown.
Precision, recall and F1 of occupied cells do not depend on that choice.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from smokyslam.errors import MapFileError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN
from smokyslam.types import GroundTruthMap

logger = logging.getLogger(__name__)

CLOUD_SUFFIXES = (".ply", ".pcd")
"""Point-cloud files ``evaluate --truth`` reads with open3d."""

TALL_CLOUD_M = 0.5
"""A cloud spanning more height than this likely holds floor or ceiling: say so."""


def read_cloud_points(path: Path | str) -> np.ndarray:
    """(N, 3) finite float64 points of a PLY or PCD file (open3d I/O)."""
    path = Path(path)
    if not path.is_file():
        raise MapFileError(f"{path}: no such point cloud")
    import open3d as o3d  # heavy; only here

    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    with _c_stderr_silenced():  # the PLY parser prints its complaints straight to fd 2
        cloud = o3d.io.read_point_cloud(str(path), format="auto", print_progress=False)
    points = np.asarray(cloud.points, dtype=float)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) == 0:
        raise MapFileError(f"{path}: no readable points (not a PLY/PCD cloud, or empty)")
    return points


@contextlib.contextmanager
def _c_stderr_silenced() -> Iterator[None]:
    """File descriptor 2 sent to /dev/null (C libraries bypass ``sys.stderr``)."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def parse_z_band(text: str | None) -> tuple[float, float] | None:
    """``"LO:HI"`` (metres) as (lo, hi); None keeps every point."""
    if text is None:
        return None
    try:
        lo, hi = (float(part) for part in text.split(":"))
    except ValueError:
        raise MapFileError(
            f"--z-band must be LO:HI in metres (e.g. 0.2:2.0), got '{text}'"
        ) from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise MapFileError(f"--z-band needs finite LO < HI, got '{text}'")
    return lo, hi


def cloud_truth(
    path: Path | str,
    map_cells: np.ndarray,
    map_spec: GridSpec,
    z_band: tuple[float, float] | None = None,
) -> GroundTruthMap:
    """The truth on ``map_spec`` from the cloud at ``path``: occupied where points of the
    z-band fall, free where the map (trinary ``map_cells``) knows a cell inside the cloud's
    footprint that holds none, unknown elsewhere."""
    points = read_cloud_points(path)
    z_min, z_max = points[:, 2].min(), points[:, 2].max()
    if z_band is None:
        if z_max - z_min > TALL_CLOUD_M:
            logger.warning(
                "%s spans z %.2f..%.2f m: pass --z-band LO:HI to leave out floor and ceiling",
                path,
                z_min,
                z_max,
            )
        band = points
    else:
        band = points[(points[:, 2] >= z_band[0]) & (points[:, 2] <= z_band[1])]
        if len(band) == 0:
            raise MapFileError(
                f"{path}: no points in the z-band {z_band[0]:g}..{z_band[1]:g} m "
                f"(the cloud spans z {z_min:.2f}..{z_max:.2f} m)"
            )
    cells = map_spec.cells_of(band[:, :2])
    cells = cells[map_spec.inside(cells)]
    if len(cells) == 0:
        raise MapFileError(f"{path}: no point of the cloud falls on the map's grid")
    occupied = np.zeros(map_spec.shape, dtype=bool)
    occupied[cells[:, 1], cells[:, 0]] = True
    footprint = _footprint(map_spec, points[:, :2].min(axis=0), points[:, :2].max(axis=0))
    truth = np.full(map_spec.shape, UNKNOWN, dtype=np.int8)
    truth[footprint & (np.asarray(map_cells) != UNKNOWN)] = FREE
    truth[occupied] = OCCUPIED
    return GroundTruthMap(stamp_s=0.0, cells=truth, spec=map_spec)


def _footprint(spec: GridSpec, lo_xy: np.ndarray, hi_xy: np.ndarray) -> np.ndarray:
    """(rows, cols) bool: cells whose centres lie in the box ``lo_xy``..``hi_xy``."""
    rows, cols = spec.shape
    x = spec.origin_xy_m[0] + (np.arange(cols) + 0.5) * spec.resolution_m
    y = spec.origin_xy_m[1] + (np.arange(rows) + 0.5) * spec.resolution_m
    inside_x = (x >= lo_xy[0]) & (x <= hi_xy[0])
    inside_y = (y >= lo_xy[1]) & (y <= hi_xy[1])
    return inside_y[:, None] & inside_x[None, :]
