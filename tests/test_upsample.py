"""The up-sampler: model, weights files, seamless inference, the classical baseline."""

from __future__ import annotations

import numpy as np
import pytest

from smokyslam.config import UpsampleConfig, UpsamplerModelConfig, UpsamplerTrainingConfig
from smokyslam.errors import UpsamplerError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN
from smokyslam.sim.world import box_world
from smokyslam.upsample.crops import CropSampler
from smokyslam.upsample.dataset import MapPair
from smokyslam.upsample.infer import ClassicalUpsampler, GanUpsampler, get_upsampler, upsample
from smokyslam.upsample.weights import load_weights, save_weights

torch = pytest.importorskip("torch")

SMALL = UpsamplerModelConfig(base_channels=4, depth=3, max_channels=16)


def _generator(model: UpsamplerModelConfig = SMALL, seed: int = 0):
    from smokyslam.upsample.model import UNetGenerator

    torch.manual_seed(seed)
    return UNetGenerator(model.base_channels, model.depth, model.max_channels).eval()


def _weights(tmp_path, model: UpsamplerModelConfig = SMALL):
    path = save_weights(tmp_path / "w.pt", _generator(model), model, 0.0, {"command": "test"})
    return load_weights(path)


def _sparse_room(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(sparse, truth) of an 8 x 6 m room: the truth, with 70 % of its walls and a band of
    its free space left unknown, as a sparse radar map leaves them."""
    truth = box_world(8.0, 6.0).ground_truth_cells()
    rng = np.random.default_rng(seed)
    sparse = truth.copy()
    sparse[(truth == OCCUPIED) & (rng.random(truth.shape) < 0.7)] = UNKNOWN
    sparse[(truth == FREE) & (rng.random(truth.shape) < 0.5)] = UNKNOWN
    return sparse, truth


def test_a_tiny_model_learns_on_generated_pairs():
    from smokyslam.upsample.model import UNetGenerator

    torch.manual_seed(0)
    pairs = [MapPair(*_sparse_room(seed), f"room {seed}") for seed in range(4)]
    config = UpsamplerTrainingConfig(crop_cells=48, occupied_weight=3.0)
    sampler = CropSampler(pairs, config, np.random.default_rng(0))
    generator = UNetGenerator(8, 2, 32)
    optimiser = torch.optim.Adam(generator.parameters(), 3e-3)
    losses = []
    for _ in range(60):
        inputs, targets, weights = (torch.from_numpy(a) for a in sampler.batch(8))
        value = torch.sigmoid(generator(inputs))
        loss = (weights * (value - targets).abs()).sum() / weights.sum()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        losses.append(float(loss.detach()))
    assert np.mean(losses[-10:]) < 0.5 * np.mean(losses[:5])


def test_crops_keep_input_and_target_aligned_through_rotations_and_flips():
    sparse, truth = _sparse_room()
    config = UpsamplerTrainingConfig(crop_cells=32)
    sampler = CropSampler([MapPair(sparse, truth, "room")], config, np.random.default_rng(1))
    inputs, targets, weights = sampler.batch(64)
    known_occupied = inputs[:, 0] == 1.0
    assert known_occupied.any()
    assert (targets[:, 0][known_occupied] == 1.0).all()  # an input wall is a target wall
    assert (targets[:, 0][inputs[:, 0] == -1.0] == 0.0).all()
    assert set(np.unique(weights)) <= {1.0, config.occupied_weight, config.unknown_weight}


def test_weights_round_trip_and_give_the_same_map(tmp_path):
    generator = _generator()
    path = save_weights(tmp_path / "w.pt", generator, SMALL, -0.5, {"command": "smokyslam x"})
    loaded = load_weights(path)
    assert loaded.model == SMALL and loaded.training["command"] == "smokyslam x"
    assert loaded.logit_offset == -0.5
    x = torch.randn(1, 2, 32, 32)
    with torch.inference_mode():
        assert torch.equal(generator(x), loaded.generator(x))


def test_the_shipped_weights_load_and_are_small():
    from smokyslam.upsample.weights import shipped_weights_path

    path = shipped_weights_path()
    assert path.stat().st_size <= 20 * 2**20
    weights = load_weights()
    assert weights.training["command"].startswith("smokyslam train-upsampler")


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "not a readable weights file"),
        (b"\x00" * 1000, "not a readable weights file"),
        ("foreign", "not a smokyslam up-sampler weights file"),
        ("truncated", "not a readable weights file"),
        ("mismatched", "do not fit the model"),
    ],
)
def test_bad_weights_files_are_one_clear_error(tmp_path, content, message):
    path = tmp_path / "bad.pt"
    if content == "foreign":
        torch.save({"state_dict": {}}, path)
    elif content == "truncated":
        good = save_weights(tmp_path / "good.pt", _generator(), SMALL, 0.0, {})
        path.write_bytes(good.read_bytes()[:5000])
    elif content == "mismatched":
        good = save_weights(tmp_path / "good.pt", _generator(), SMALL, 0.0, {})
        payload = torch.load(good, weights_only=True)
        payload["model"]["base_channels"] = 8
        torch.save(payload, path)
    else:
        path.write_bytes(content)
    with pytest.raises(UpsamplerError, match=message):
        load_weights(path)
    with pytest.raises(UpsamplerError, match="no such weights file"):
        load_weights(tmp_path / "missing.pt")


@pytest.mark.parametrize("half_turn", [False, True])
def test_a_map_and_a_shifted_copy_up_sample_alike(tmp_path, half_turn):
    """The pass is anchored to the world grid: the same place gives the same value in a map
    extended by unknown cells on any side (any shift, not only multiples of the stride)."""
    upsampler = GanUpsampler(
        _weights(tmp_path),
        margin_cells=24,
        max_pass_cells=1024,
        keep_walls_above=1.0,
        half_turn=half_turn,
    )
    sparse, _ = _sparse_room()
    spec = GridSpec((-0.1, -0.1), 0.1, sparse.shape)
    base = upsampler.values(sparse, spec)
    for rows, cols in ((5, 0), (0, 3), (7, 11), (16, 16)):
        bigger = np.pad(sparse, ((rows, 9), (cols, 2)), constant_values=UNKNOWN)
        origin = (spec.origin_xy_m[0] - 0.1 * cols, spec.origin_xy_m[1] - 0.1 * rows)
        shifted = upsampler.values(bigger, GridSpec(origin, 0.1, bigger.shape))
        crop = shifted[rows : rows + sparse.shape[0], cols : cols + sparse.shape[1]]
        assert np.abs(crop - base).max() < 1e-4


def test_the_dense_map_covers_the_known_cells_and_its_extension_wherever_the_window_ends(
    tmp_path,
):
    """The dense grid is the known cells' box grown by ``extend_cells``: the same for a sparse
    window with much unknown slack and for one cut off at the known cells, and its values
    beyond the window's edge are the network's, as in a wider window."""
    upsampler = GanUpsampler(_weights(tmp_path), 24, 1024, 1.0, extend_cells=10)
    sparse, _ = _sparse_room()
    rows, cols = np.nonzero(sparse != UNKNOWN)
    tight = sparse[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
    tight_spec = GridSpec((0.3, -0.2), 0.1, tight.shape)
    slack = np.pad(tight, ((4, 30), (25, 2)), constant_values=UNKNOWN)
    slack_spec = GridSpec((0.3 - 2.5, -0.2 - 0.4), 0.1, slack.shape)
    dense_tight = upsample(upsampler, tight, tight_spec)
    dense_slack = upsample(upsampler, slack, slack_spec)
    assert dense_tight.values.shape == (tight.shape[0] + 20, tight.shape[1] + 20)
    assert dense_tight.values.shape == dense_slack.values.shape
    assert dense_tight.spec.origin_xy_m == pytest.approx((0.3 - 1.0, -0.2 - 1.0))
    assert dense_slack.spec.origin_xy_m == pytest.approx((0.3 - 1.0, -0.2 - 1.0))
    np.testing.assert_allclose(dense_tight.values, dense_slack.values, atol=1e-4)
    wide = np.pad(tight, 10, constant_values=UNKNOWN)
    np.testing.assert_allclose(dense_tight.values, upsampler.values(wide, dense_tight.spec))
    # Without the extension the dense map keeps the sparse grid, slack and all.
    upsampler.extend_cells = None
    assert upsample(upsampler, slack, slack_spec).spec == slack_spec


@pytest.mark.parametrize("half_turn", [False, True])
def test_with_the_half_turn_a_turned_map_up_samples_to_the_turned_result(tmp_path, half_turn):
    """Averaged with its half turn, the dense map of a map turned by 180 degrees about the
    world origin is the dense map turned; the network alone (here untrained) is not so."""
    sparse, _ = _sparse_room()
    upsampler = GanUpsampler(_weights(tmp_path), 24, 1024, 1.0, half_turn=half_turn)
    spec = GridSpec((-0.3, 0.5), 0.1, sparse.shape)
    last_xy = np.array(spec.origin_xy_m) + 0.1 * np.array(
        [sparse.shape[1] - 1, sparse.shape[0] - 1]
    )
    turned_spec = GridSpec(tuple(-last_xy), 0.1, sparse.shape)
    values = upsampler.values(sparse, spec)
    turned = upsampler.values(np.ascontiguousarray(sparse[::-1, ::-1]), turned_spec)
    difference = np.abs(turned[::-1, ::-1] - values).max()
    assert difference < 1e-5 if half_turn else difference > 1e-3


def test_the_channels_last_layout_gives_the_same_values(tmp_path):
    sparse, _ = _sparse_room()
    spec = GridSpec((0.0, 0.0), 0.1, sparse.shape)
    plain = GanUpsampler(_weights(tmp_path), 24, 1024, 1.0).values(sparse, spec)
    fast = GanUpsampler(_weights(tmp_path), 24, 1024, 1.0, channels_last=True)
    np.testing.assert_allclose(fast.values(sparse, spec), plain, atol=1e-5)


def test_tiles_blend_into_the_one_pass_result(tmp_path):
    weights = _weights(tmp_path)
    rng = np.random.default_rng(3)
    cells = rng.choice(np.array([OCCUPIED, FREE, UNKNOWN], dtype=np.int8), size=(150, 230))
    spec = GridSpec((0.0, 0.0), 0.1, cells.shape)
    whole = GanUpsampler(weights, 24, 1024, 1.0).values(cells, spec)
    tiled = GanUpsampler(weights, 24, 64, 1.0).values(cells, spec)
    assert tiled.shape == whole.shape
    assert np.abs(tiled - whole).mean() < 0.01 and np.abs(tiled - whole).max() < 0.1
    # No seam: neighbouring cells differ no more along tile borders than anywhere else.
    step = np.abs(np.diff(tiled, axis=1)).mean(axis=0)
    assert step.max() < 3.0 * np.median(step) + 0.05


def test_walls_the_radar_saw_stay_unless_the_network_is_sure_they_are_free(tmp_path):
    weights = _weights(tmp_path)
    sparse, _ = _sparse_room()
    spec = GridSpec((-0.1, -0.1), 0.1, sparse.shape)
    alone = GanUpsampler(weights, 24, 1024, 1.0).values(sparse, spec)
    wall = sparse == OCCUPIED
    above = float(np.median(alone[wall]))  # an untrained network: values near 0.5
    kept = GanUpsampler(weights, 24, 1024, above).values(sparse, spec)
    sure_free = wall & (alone < above)
    assert wall.sum() > 10 and 0 < sure_free.sum() < wall.sum()  # both cases occur
    assert np.all(kept[wall & ~sure_free] == 1.0)
    assert np.array_equal(kept[~wall | sure_free], alone[~wall | sure_free])


@pytest.mark.parametrize("shape", [(1, 1), (5, 3), (17, 40)])
def test_maps_smaller_than_a_stride_work(tmp_path, shape):
    upsampler = GanUpsampler(_weights(tmp_path), 8, 1024, 1.0)
    cells = np.full(shape, FREE, dtype=np.int8)
    values = upsampler.values(cells, GridSpec((0.0, 0.0), 0.1, shape))
    assert values.shape == shape and np.isfinite(values).all()


def test_an_all_unknown_map_stays_unknown(tmp_path):
    upsampler = GanUpsampler(_weights(tmp_path), 8, 1024, 1.0)
    cells = np.full((40, 30), UNKNOWN, dtype=np.int8)
    values = upsampler.values(cells, GridSpec((0.0, 0.0), 0.1, cells.shape))
    assert (values == 0.5).all()
    assert (ClassicalUpsampler(2, 3).values(cells, None) == 0.5).all()


def test_classical_closes_wall_gaps_and_fills_between_rays():
    cells = np.full((20, 40), UNKNOWN, dtype=np.int8)
    cells[10, ::2] = OCCUPIED  # a wall seen every other cell
    cells[2:9:2, 5:35] = FREE  # free rays with unknown gaps between them
    values = ClassicalUpsampler(1, 2).values(cells, None)
    assert (values[10, 1:39] == 1.0).all()
    assert (values[3:8, 8:32] == 0.0).all()
    assert (values[15:, :] == 0.5).all()  # nothing observed there: still unknown


def test_get_upsampler_names_the_choices(tmp_path):
    with pytest.raises(UpsamplerError, match="choose gan, classical"):
        get_upsampler(UpsampleConfig(), "bicubic")
    config = UpsampleConfig(weights=str(tmp_path / "nothing.pt"))
    with pytest.raises(UpsamplerError, match="no such weights file"):
        get_upsampler(config)


@pytest.mark.parametrize("worker_process", [True, False])
def test_the_refresher_up_samples_in_the_background_at_its_period(worker_process):
    import time

    from smokyslam.upsample.online import DenseRefresher

    sparse, _ = _sparse_room()
    spec = GridSpec((0.0, 0.0), 0.1, sparse.shape)
    config = UpsampleConfig(method="classical", refresh_period_s=5.0, worker_process=worker_process)
    refresher = DenseRefresher(config)
    try:
        assert refresher.due(0.0)
        refresher.refresh(0.0, sparse, spec)
        deadline = time.monotonic() + 120
        while refresher.latest is None and time.monotonic() < deadline:
            assert not refresher.due(1.0) or refresher.latest is not None
            time.sleep(0.05)
        assert refresher.refreshes == 1 and refresher.latest_stamp_s == 0.0
        expected = upsample(get_upsampler(config), sparse, spec).values
        np.testing.assert_array_equal(refresher.latest.values, expected)
        assert not refresher.due(4.9) and refresher.due(5.0)
        np.testing.assert_array_equal(refresher.final(sparse, spec).result().values, expected)
        assert refresher.stats()["refreshes"] == 1
    finally:
        refresher.close()


@pytest.mark.parametrize("worker_process", [True, False])
def test_unusable_weights_stop_the_run_at_the_next_keyframe(tmp_path, worker_process):
    import time

    from smokyslam.upsample.online import DenseRefresher

    (tmp_path / "junk.pt").write_bytes(b"junk")
    config = UpsampleConfig(weights=str(tmp_path / "junk.pt"), worker_process=worker_process)
    refresher = DenseRefresher(config)
    sparse, _ = _sparse_room()
    try:
        refresher.refresh(0.0, sparse, GridSpec((0.0, 0.0), 0.1, sparse.shape))
        deadline = time.monotonic() + 120
        with pytest.raises(UpsamplerError, match=r"junk\.pt"):
            while time.monotonic() < deadline:
                refresher.due(10.0)
                time.sleep(0.05)
    finally:
        refresher.close()
