"""Map metrics: eq. 2 by hand, 1-cell tolerance, other origins and resolutions, saved maps."""

from __future__ import annotations

import numpy as np
import pytest

from smokyslam.evaluation.map_metrics import evaluate_map
from smokyslam.geometry import GridSpec
from smokyslam.mapio import load_map, save_map
from smokyslam.mapping.grid import resample_nearest
from smokyslam.sim.world import box_world

KEYS = {"error_index", "occupied_precision", "occupied_recall", "occupied_f1", "occupied_iou"}


def test_error_index_and_occupied_scores_on_a_hand_computed_example():
    spec = GridSpec((0.0, 0.0), 1.0, (2, 3))
    truth = np.array([[100, 0, 0], [-1, 0, 100]], dtype=np.int8)
    mapped = np.array([[100, -1, 100], [0, 0, -1]], dtype=np.int8)
    metrics = evaluate_map(mapped, spec, truth, spec)
    assert set(metrics) >= KEYS
    # Known truth cells: 5. Squared errors: 0, 0.25 (unknown), 1 (wrong), 0, 0.25 (unknown).
    assert metrics["error_index"] == pytest.approx(1.5 / 5)
    # The map's [0, 2] is one cell from the truth's [1, 2]: both count within tolerance.
    assert metrics["occupied_precision"] == 1.0 and metrics["occupied_recall"] == 1.0
    assert metrics["occupied_f1"] == 1.0
    assert metrics["occupied_iou"] == pytest.approx(1 / 3)
    assert metrics["known_fraction"] == pytest.approx(3 / 5)


def test_tolerance_is_one_cell_and_empty_maps_score_zero():
    spec = GridSpec((0.0, 0.0), 0.1, (10, 10))
    truth = np.zeros((10, 10), dtype=np.int8)
    truth[:, 2] = 100
    for shift, expected in ((0, 1.0), (1, 1.0), (2, 0.0)):
        mapped = np.zeros_like(truth)
        mapped[:, 2 + shift] = 100
        metrics = evaluate_map(mapped, spec, truth, spec)
        assert metrics["occupied_precision"] == expected
        assert metrics["occupied_recall"] == expected
        assert metrics["occupied_iou"] == (1.0 if shift == 0 else 0.0)
    metrics = evaluate_map(np.full_like(truth, -1), spec, truth, spec)
    assert metrics["occupied_precision"] == 0.0 and metrics["occupied_f1"] == 0.0
    assert metrics["error_index"] == pytest.approx(0.25)


def test_other_origins_and_resolutions_are_resampled_in_the_truth_grid():
    world = box_world()
    truth, truth_spec = world.ground_truth_cells(), world.spec
    # A finer grid with an origin off the truth's lattice: the same map, cell for cell.
    fine = GridSpec((-0.637, -0.413), 0.05, (170, 210))
    fine_cells = resample_nearest(truth, truth_spec, fine, -1)
    metrics = evaluate_map(fine_cells, fine, truth, truth_spec)
    assert metrics["error_index"] == 0.0 and metrics["occupied_iou"] == 1.0
    # The same resolution shifted by whole cells, covering only the west half.
    shifted = GridSpec((-2.0, -1.5), 0.1, (100, 60))
    half = resample_nearest(truth, truth_spec, shifted, -1)
    metrics = evaluate_map(half, shifted, truth, truth_spec)
    uncovered = np.count_nonzero(
        truth_spec.centres_of(np.argwhere(truth >= -1)[:, ::-1])[:, 0] > 4.0
    )
    assert metrics["error_index"] == pytest.approx(0.25 * uncovered / truth.size)
    assert metrics["occupied_precision"] == 1.0 and 0.4 < metrics["occupied_recall"] < 0.6
    # A coarser map (0.2 m): a cell is a wall if any of its four truth cells is. In the truth
    # grid that thickens every wall by one cell inwards: 2 * 80 + 2 * 58 = 276 wrong cells.
    coarse = GridSpec((-0.1, -0.1), 0.2, (31, 41))
    walls = (truth == 100).reshape(31, 2, 41, 2).any(axis=(1, 3))
    metrics = evaluate_map(np.where(walls, 100, 0).astype(np.int8), coarse, truth, truth_spec)
    assert metrics["error_index"] == pytest.approx(276 / truth.size)
    assert metrics["occupied_precision"] == 1.0 and metrics["occupied_recall"] == 1.0
    assert metrics["occupied_iou"] == pytest.approx(284 / (284 + 276))


def test_probability_maps_are_thresholded_like_map_server():
    spec = GridSpec((0.0, 0.0), 1.0, (1, 4))
    truth = np.array([[100, 0, 0, 100]], dtype=np.int8)
    prob = np.array([[0.9, 0.1, 0.5, 0.6]])
    metrics = evaluate_map(prob, spec, truth, spec)
    assert metrics["error_index"] == pytest.approx((0 + 0 + 0.25 + 0.25) / 4)
    expected = (0.1**2 + 0.1**2 + 0.5**2 + 0.4**2) / 4
    assert metrics["error_index_probability"] == pytest.approx(expected)


def test_error_index_agrees_with_the_saved_map(tmp_path):
    world = box_world()
    rng = np.random.default_rng(0)
    spec = GridSpec((-0.5, -0.3), 0.1, (70, 90))
    cells = rng.choice(np.array([100, 0, -1], dtype=np.int8), size=spec.shape, p=[0.2, 0.5, 0.3])
    path = save_map(tmp_path / "maps" / "radar_sparse.yaml", cells, spec)
    loaded = load_map(path)
    direct = evaluate_map(cells, spec, world.ground_truth_cells(), world.spec)
    from_file = evaluate_map(loaded.cells, loaded.spec, world.ground_truth_cells(), world.spec)
    assert from_file == pytest.approx(direct)


def test_map_scores_nest_the_observed_truth_only_when_there_is_one():
    from smokyslam.evaluation.map_metrics import map_scores
    from smokyslam.types import GroundTruthMap

    spec = GridSpec(origin_xy_m=(0.0, 0.0), resolution_m=0.1, shape=(10, 10))
    truth = np.zeros((10, 10), dtype=np.int8)
    truth[:, 0] = truth[:, 9] = 100
    observed = truth.copy()
    observed[:, 5:] = -1  # the walk saw only the left half
    cells = np.where(np.arange(10)[None, :] < 5, truth, -1).astype(np.int8)
    full = GroundTruthMap(0.0, truth, spec)
    assert set(map_scores(cells, spec, full)) == KEYS
    both = map_scores(cells, spec, full, GroundTruthMap(0.0, observed, spec))
    assert set(both) == KEYS | {"observed"} and set(both["observed"]) == KEYS
    assert both["occupied_recall"] == pytest.approx(0.5)
    assert both["observed"]["occupied_recall"] == 1.0 and both["observed"]["error_index"] == 0.0
