"""Pictures of maps a reader understands: metric axes, a title, a legend, the path drawn on.

Colours, the same in every picture: map cells black (occupied), white (free) or grey
(unknown); true walls red (dark red where the map agrees); the path blue.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smokyslam.errors import MapFileError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap

# RGB colours.
MAP_COLOURS = {OCCUPIED: (0, 0, 0), FREE: (254, 254, 254), UNKNOWN: (205, 205, 205)}
WALL_RED = np.array([230, 0, 0], dtype=float)
PATH_BLUE = "#0050c8"
FIGURE_WIDTH_IN, DPI = 7.0, 110
"""Every map picture is 7 inches (770 px) wide; its height follows the map's shape."""
MARGINS_IN = {"left": 0.65, "right": 1.15, "bottom": 0.5, "top": 0.35}
"""Room around the map for the axes' labels, the legend (right) and the title: fixed, so no
layout engine measures the text (that took a third of each picture's time)."""


def map_picture(
    cells: np.ndarray, spec: GridSpec, truth: GroundTruthMap | None = None
) -> tuple[np.ndarray, GridSpec]:
    """((rows, cols, 3) uint8 RGB, its grid): the map's cells over the union of its grid and
    the truth's (row 0 the lowest y), true walls tinted red."""
    canvas = spec.covering(truth.spec) if truth is not None else spec
    if min(canvas.shape) == 0:
        raise MapFileError("cannot draw an empty map")
    map_cells = resample_nearest(np.asarray(cells, dtype=np.int8), spec, canvas, UNKNOWN)
    image = np.zeros((*canvas.shape, 3), dtype=float)
    for value, colour in MAP_COLOURS.items():
        image[map_cells == value] = colour
    if truth is not None:
        walls = resample_nearest(truth.cells, truth.spec, canvas, UNKNOWN) == OCCUPIED
        image[walls] = 0.5 * image[walls] + 0.5 * WALL_RED
    return image.astype(np.uint8), canvas


def render_map_png(
    path: Path | str,
    cells: np.ndarray,
    spec: GridSpec,
    truth: GroundTruthMap | None = None,
    trajectory_xy_m: np.ndarray | None = None,
    title: str = "map",
) -> Path:
    """Write a picture of a trinary map over ``spec`` (north up, axes in metres) with the true
    walls, the path ``trajectory_xy_m`` (N, 2) world positions, ``title`` and a legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    path = Path(path)
    try:
        image, canvas = map_picture(cells, spec, truth)
    except MapFileError:
        raise MapFileError(f"cannot render an empty map to {path}") from None
    rows, cols = canvas.shape
    margin_x_in = MARGINS_IN["left"] + MARGINS_IN["right"]
    margin_y_in = MARGINS_IN["bottom"] + MARGINS_IN["top"]
    height_in = float(
        np.clip((FIGURE_WIDTH_IN - margin_x_in) * rows / cols + margin_y_in, 3.0, 10.0)
    )
    fig, ax = plt.subplots(figsize=(FIGURE_WIDTH_IN, height_in), dpi=DPI)
    fig.subplots_adjust(
        left=MARGINS_IN["left"] / FIGURE_WIDTH_IN,
        right=1.0 - MARGINS_IN["right"] / FIGURE_WIDTH_IN,
        bottom=MARGINS_IN["bottom"] / height_in,
        top=1.0 - MARGINS_IN["top"] / height_in,
    )
    ax.imshow(image, origin="lower", extent=canvas.extent_m, interpolation="nearest")
    handles = [
        Patch(facecolor="black", label="occupied"),
        Patch(facecolor="white", edgecolor="0.5", label="free"),
        Patch(facecolor=np.array(MAP_COLOURS[UNKNOWN]) / 255, label="unknown"),
    ]
    if truth is not None:
        handles.append(Patch(facecolor=WALL_RED / 255, label="true wall"))
    if trajectory_xy_m is not None and len(trajectory_xy_m) > 1:
        xy = np.asarray(trajectory_xy_m, dtype=float)
        ax.plot(xy[:, 0], xy[:, 1], color=PATH_BLUE, lw=1.2)
        handles.append(Line2D([], [], color=PATH_BLUE, label="path"))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=9)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
