"""Map quality against a ground-truth grid; every metric is computed in the ground-truth grid.

The map is resampled at the centres of the ground-truth cells (nearest map cell; places the
map does not cover are unknown), so maps with other origins and resolutions compare fairly.
Map occupied cells outside the ground-truth grid are not scored.

- ``error_index``: the paper's eq. 2, ``mean((truth - map)^2)`` over the cells the ground
  truth knows, with occupied = 1, free = 0 and unknown = 0.5, on the map's trinary cells
  (what the saved PGM holds). Unknown map cells thus cost 0.25 and wrong ones 1.
- ``occupied_precision``: the share of map occupied cells with a ground-truth occupied cell
  within one cell (8-neighbourhood); ``occupied_recall``: the share of ground-truth occupied
  cells with a map occupied cell within one cell; ``occupied_f1`` their harmonic mean.
- ``occupied_iou``: intersection over union of the occupied sets, cell for cell (no slack).
- ``known_fraction`` (extra): the share of known ground-truth cells the map also knows.
- ``error_index_probability`` (extra, only for probability maps): eq. 2 on the probabilities.

Empty sets score 0 (never NaN, so metrics stay valid JSON).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.ndimage import binary_dilation

from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, trinary_from_probability
from smokyslam.mapping.grid import resample_nearest
from smokyslam.types import GroundTruthMap

MAP_METRIC_KEYS = (
    "error_index",
    "occupied_precision",
    "occupied_recall",
    "occupied_f1",
    "occupied_iou",
)
"""The five map metrics of the contract (``metrics.json`` ``maps.<name>``)."""

_NEIGHBOURHOOD = np.ones((3, 3), dtype=bool)


def _values(cells: np.ndarray) -> np.ndarray:
    """Trinary cells as eq. 2 values: occupied 1, free 0, unknown 0.5."""
    return np.select([cells == OCCUPIED, cells == FREE], [1.0, 0.0], 0.5)


def _ratio(numerator: float, denominator: float) -> float:
    return float(numerator) / float(denominator) if denominator else 0.0


def evaluate_map(
    map_cells_or_prob: np.ndarray,
    map_spec: GridSpec,
    truth_cells: np.ndarray,
    truth_spec: GridSpec,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
) -> dict[str, float]:
    """Score a map against ground truth.

    map_cells_or_prob: (rows, cols) over ``map_spec``; either int trinary cells (100 / 0 / -1)
    or float occupancy probabilities (made trinary with the two thresholds, map_server style).
    truth_cells: (rows, cols) int8 trinary ground truth over ``truth_spec``.
    Returns the keys listed in the module docstring.
    """
    values = np.asarray(map_cells_or_prob)
    probability = None
    if np.issubdtype(values.dtype, np.floating):
        probability = resample_nearest(values.astype(float), map_spec, truth_spec, 0.5)
        cells = trinary_from_probability(values, occupied_thresh, free_thresh)
    else:
        cells = values.astype(np.int8)
    cells = resample_nearest(cells, map_spec, truth_spec, UNKNOWN)
    truth = np.asarray(truth_cells)
    known = truth != UNKNOWN
    truth_occupied = truth == OCCUPIED
    map_occupied = cells == OCCUPIED

    truth_values = _values(truth)[known]
    squared_error = (truth_values - _values(cells)[known]) ** 2
    near_truth = binary_dilation(truth_occupied, _NEIGHBOURHOOD)
    near_map = binary_dilation(map_occupied, _NEIGHBOURHOOD)
    precision = _ratio(np.count_nonzero(map_occupied & near_truth), np.count_nonzero(map_occupied))
    recall = _ratio(np.count_nonzero(truth_occupied & near_map), np.count_nonzero(truth_occupied))
    metrics = {
        "error_index": _ratio(squared_error.sum(), squared_error.size),
        "occupied_precision": precision,
        "occupied_recall": recall,
        "occupied_f1": _ratio(2.0 * precision * recall, precision + recall),
    }
    metrics["occupied_iou"] = _ratio(
        np.count_nonzero(map_occupied & truth_occupied),
        np.count_nonzero(map_occupied | truth_occupied),
    )
    metrics["known_fraction"] = _ratio(
        np.count_nonzero(known & (cells != UNKNOWN)), np.count_nonzero(known)
    )
    if probability is not None:
        squared_error = (truth_values - probability[known]) ** 2
        metrics["error_index_probability"] = _ratio(squared_error.sum(), squared_error.size)
    return metrics


def map_scores(
    cells: np.ndarray,
    spec: GridSpec,
    truth: GroundTruthMap,
    observed: GroundTruthMap | None = None,
) -> dict[str, Any]:
    """The contract's five map metrics of trinary cells over ``spec`` against a true map;
    with the ``observed`` truth (what a lidar saw along the walk) the same five again, under
    ``observed``."""
    scores = evaluate_map(cells, spec, truth.cells, truth.spec)
    out: dict[str, Any] = {key: scores[key] for key in MAP_METRIC_KEYS}
    if observed is not None:
        out["observed"] = map_scores(cells, spec, observed)
    return out


def wall_agreement(
    truth_cells: np.ndarray, truth_spec: GridSpec, points_xy_m: np.ndarray, tolerance_m: float
) -> float:
    """The share of (N, 2) world points (e.g. radar returns) within ``tolerance_m`` of an
    occupied ground-truth cell: how well the truth's walls match what the sensors hit."""
    from scipy.ndimage import distance_transform_edt

    points = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
    if len(points) == 0:
        return 0.0
    # Distance from every cell centre to the nearest occupied cell's edge (about).
    distance_m = distance_transform_edt(truth_cells != OCCUPIED) * truth_spec.resolution_m
    distance_m = np.maximum(distance_m - 0.5 * truth_spec.resolution_m, 0.0)
    cells = truth_spec.cells_of(points)
    inside = truth_spec.inside(cells)
    near = np.zeros(len(points), dtype=bool)
    near[inside] = distance_m[cells[inside, 1], cells[inside, 0]] <= tolerance_m
    return float(near.mean())


def score_text(scores: dict[str, Any]) -> str:
    """``, error index 0.123 (observed 0.101)`` of a map's scores."""
    text = f", error index {scores['error_index']:.3f}"
    if "observed" in scores:
        text += f" (observed truth {scores['observed']['error_index']:.3f})"
    return text
