"""Scoring a generator on the validation maps, and calibrating its logit offset there.

The generator runs once per map (its logits); scores at any logit offset then only threshold
them again. The offset written with the weights is searched from ``-log(occupied_weight)``
(the offset that undoes the training's weight on wall cells) upwards, never below it: the
network answers "no evidence" with a logit near 0, which must stay unknown (below it, cells
nobody observed turn free, outside the building too; the error index, which counts only
cells the truth knows, would reward that, a navigator would not). Of those offsets, the one
with the best occupied F1 among those whose error index is at most
:data:`ERROR_INDEX_SHARE` of the sparse maps'; the lowest error index if none is.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smokyslam.config.upsample import UpsamplerModelConfig
from smokyslam.evaluation.map_metrics import evaluate_map
from smokyslam.geometry import GridSpec
from smokyslam.upsample.dataset import MapPair
from smokyslam.upsample.encoding import cells_from_values

OFFSET_STEPS = np.arange(0.0, 1.51, 0.25)
"""The calibration grid, added to the starting offset."""

ERROR_INDEX_SHARE = 0.45
"""An offset qualifies when its error index is at most this share of the sparse maps'."""


def validation_logits(
    generator: Any,
    model: UpsamplerModelConfig,
    pairs: list[MapPair],
    margin_cells: int,
    max_pass_cells: int,
) -> list[np.ndarray]:
    """The generator's (rows, cols) logits of every pair's sparse map (no offset)."""
    from smokyslam.upsample.infer import GanUpsampler
    from smokyslam.upsample.weights import UpsamplerWeights

    # The network alone (no walls kept from the radar map): its offset is calibrated on this.
    weights = UpsamplerWeights(generator, model, 0.0)
    upsampler = GanUpsampler(weights, margin_cells, max_pass_cells, keep_walls_above=1.0)
    logits = []
    for pair in pairs:
        spec = GridSpec((0.0, 0.0), 0.1, pair.truth.shape)
        values = np.clip(upsampler.values(pair.sparse, spec).astype(float), 1e-7, 1.0 - 1e-7)
        logits.append(np.log(values / (1.0 - values)))
    return logits


def validation_scores(
    pairs: list[MapPair], logits: list[np.ndarray], offset: float
) -> dict[str, float]:
    """Mean error index and occupied F1 of the dense maps at ``offset``, and of the sparse."""
    dense, sparse = [], []
    for pair, logit in zip(pairs, logits, strict=True):
        spec = GridSpec((0.0, 0.0), 0.1, pair.truth.shape)
        cells = cells_from_values(1.0 / (1.0 + np.exp(-(logit + offset))))
        dense.append(evaluate_map(cells, spec, pair.truth, spec))
        sparse.append(evaluate_map(pair.sparse, spec, pair.truth, spec))
    return {
        "val_error_index": float(np.mean([d["error_index"] for d in dense])),
        "val_occupied_f1": float(np.mean([d["occupied_f1"] for d in dense])),
        "val_sparse_error_index": float(np.mean([d["error_index"] for d in sparse])),
        "val_sparse_occupied_f1": float(np.mean([d["occupied_f1"] for d in sparse])),
    }


def calibrate(
    pairs: list[MapPair], logits: list[np.ndarray], start: float
) -> tuple[float, dict[str, float]]:
    """(the chosen offset on the grid from ``start`` up, its scores); see the module."""
    scored = [
        (float(start + step), validation_scores(pairs, logits, float(start + step)))
        for step in OFFSET_STEPS
    ]
    qualified = [
        item
        for item in scored
        if item[1]["val_error_index"] <= ERROR_INDEX_SHARE * item[1]["val_sparse_error_index"]
    ]
    if qualified:
        return max(qualified, key=lambda item: item[1]["val_occupied_f1"])
    return min(scored, key=lambda item: item[1]["val_error_index"])
