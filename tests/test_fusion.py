"""Fusion: the rule on hand-made maps, the trust index from measured smoke, the union grid."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from smokyslam.config import CameraModelConfig, CameraOdometryConfig, FusionConfig, SmokeConfig
from smokyslam.errors import FusionError
from smokyslam.frontends.camera.preprocess import Preprocessor
from smokyslam.fusion.fuse import MapValues, fuse_maps
from smokyslam.fusion.fuser import MapFuser, get_trust_model, union_spec
from smokyslam.fusion.placement import place_visual_map
from smokyslam.fusion.trust import trust_grid
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN
from smokyslam.sim.camera import CameraRenderer
from smokyslam.sim.world import box_world
from smokyslam.smoke import SmokeEmulator
from smokyslam.types import CameraFrame

W, F, U = OCCUPIED, FREE, UNKNOWN  # wall, free, unknown
SPEC3 = GridSpec((0.0, 0.0), 0.1, (3, 3))
RADAR = np.array([[W, W, F], [F, U, W], [U, F, U]])
VISUAL = np.array([[W, F, F], [U, W, F], [F, U, U]])


def _fuse(trust, rule="linear", keep=0.3):
    radar, visual = MapValues.from_cells(RADAR, SPEC3), MapValues.from_cells(VISUAL, SPEC3)
    return fuse_maps(radar, visual, trust, rule, keep, 0.05)


def test_linear_rule_on_a_hand_made_map():
    fused = _fuse(0.7).values
    expected = np.array(
        [
            [1.0, 0.7, 0.0],  # both walls; radar wall vs visual free: t; both free
            [0.0, 1.0, 0.7],  # radar alone (t 0.7 >= 0.3: kept); visual alone (0.3: kept)
            [0.0, 0.0, 0.5],  # visual alone; radar alone; nobody
        ]
    )
    np.testing.assert_allclose(fused, expected, atol=1e-6)
    assert _fuse(0.7).summary() == {"rule": "linear", "trust_mean": pytest.approx(0.7)}
    # The camera trusted 0.2 < keep 0.3: what it alone saw is dropped.
    np.testing.assert_allclose(_fuse(0.8).values[[1, 2], [1, 0]], [0.5, 0.5])
    # The radar trusted 0.2: what it alone saw is dropped, the visual kept.
    blind_radar = _fuse(0.2).values
    assert blind_radar[1, 0] == 0.5 and blind_radar[2, 1] == 0.5 and blind_radar[1, 1] == 1.0


def test_trust_per_cell_and_the_trinary_result():
    trust = np.full((3, 3), 0.9)
    trust[0, 1] = 0.1  # there the camera is believed: its "free" wins
    cells = _fuse(trust).to_cells()
    assert cells[0, 1] == FREE and cells[0, 0] == OCCUPIED and cells[2, 2] == UNKNOWN
    assert _fuse(0.9).to_cells()[0, 1] == OCCUPIED


def test_log_odds_rule_sums_weighted_evidence():
    fused = _fuse(0.5, rule="log-odds").values
    assert fused[0, 0] > 0.99 and fused[0, 2] < 0.01  # agreeing evidence adds up
    assert fused[0, 1] == pytest.approx(0.5)  # equal and opposite at t = 0.5
    assert fused[2, 2] == pytest.approx(0.5)
    assert _fuse(0.8, rule="log-odds").values[0, 1] > 0.65  # the radar's wall wins
    assert _fuse(0.2, rule="log-odds").values[0, 1] < 0.196


@pytest.mark.parametrize("trust", [-0.1, 1.5, np.nan])
def test_trust_outside_the_unit_interval_is_refused(trust):
    with pytest.raises(FusionError, match=r"\[0, 1\]"):
        _fuse(trust)


def test_union_grid_keeps_both_maps_and_refuses_other_resolutions():
    a = GridSpec((0.0, 0.0), 0.1, (10, 20))
    b = GridSpec((-0.5, 0.3), 0.1, (30, 5))
    union = union_spec(a, b)
    assert union.origin_xy_m == pytest.approx((-0.5, 0.0))
    assert union.shape == (33, 25)
    with pytest.raises(FusionError, match="different resolution"):
        union_spec(a, GridSpec((0.0, 0.0), 0.05, (10, 10)))


def test_fuser_places_maps_of_one_frame_by_world_coordinates():
    radar = np.full((10, 10), FREE, dtype=np.int8)
    radar[:, 9] = OCCUPIED
    visual = np.full((10, 10), FREE, dtype=np.int8)
    visual[:, 4] = OCCUPIED  # the same wall: the visual grid starts 0.5 m further east
    fuser = MapFuser(FusionConfig(trust=0.5))
    fused = fuser.fuse(
        radar,
        GridSpec((0.0, 0.0), 0.1, (10, 10)),
        visual,
        GridSpec((0.5, 0.0), 0.1, (10, 10)),
        None,
    )
    cells = fused.to_cells()
    assert cells.shape == (10, 15)
    assert (cells[:, 9] == OCCUPIED).all() and (cells[:, 5] == FREE).all()
    with pytest.raises(FusionError, match="no measured trust"):
        MapFuser(FusionConfig()).fuse(radar, SPEC3, visual, SPEC3, None)


@pytest.fixture(scope="module")
def frames() -> list[CameraFrame]:
    renderer = CameraRenderer(box_world(), CameraModelConfig(), 1.2, seed=3)
    out = []
    for i, pose in enumerate([[2.0, 3.0, 0.3], [6.0, 3.0, 2.5], [1.0, 1.0, 0.8]]):
        image, depth = renderer.render(np.array(pose))
        out.append(CameraFrame(float(i), image, depth_m=depth))
    return out


def _trust_index(frames, **smoke) -> float:
    model = get_trust_model(FusionConfig())
    emulator = SmokeEmulator(SmokeConfig(**smoke))
    values = []
    for frame in frames:
        _, quality = Preprocessor(CameraOdometryConfig()).apply(emulator.apply(frame).image)
        camera = model.camera_trust(quality.impulse_fraction, quality.rms_contrast, True)
        values.append(float(model.radar_trust(camera)))
    return float(np.mean(values))


def test_the_trust_index_rises_with_salt_and_pepper_noise_and_with_haze(frames):
    t_clear = FusionConfig().trust_model.t_clear

    def rise(**smoke) -> float:
        """How far t has risen from a clear camera's t_clear towards 1 (a blind camera's)."""
        return (_trust_index(frames, **smoke) - t_clear) / (1.0 - t_clear)

    noise = [rise(camera_noise=c) for c in (0.0, 0.1, 0.2, 0.3, 0.45)]
    haze = [rise(haze=h) for h in (0.0, 0.2, 0.5, 1.0)]
    assert noise[0] == pytest.approx(0.0, abs=0.1)  # a clear camera: t_clear
    assert all(b > a + 0.06 for a, b in itertools.pairwise(noise)), noise
    assert all(b > a + 0.02 for a, b in itertools.pairwise(haze)), haze
    assert noise[-1] > 0.8 and haze[-1] > 0.5


def test_a_lost_camera_leaves_all_trust_to_the_radar():
    model = get_trust_model(FusionConfig())
    assert model.radar_trust(model.camera_trust(0.0, 0.2, False)) == 1.0


def _rooms(shift_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """(radar, visual): a 6 x 4 m room with a pillar; the visual map's walls ``shift_cells``
    out to the east and north, as where the camera's depths run long."""
    radar = np.full((60, 80), UNKNOWN, dtype=np.int8)
    radar[10:50, 10:70] = FREE
    radar[10, 10:70] = radar[49, 10:70] = radar[10:50, 10] = radar[10:50, 69] = OCCUPIED
    radar[28:32, 38:42] = OCCUPIED
    visual = np.full_like(radar, UNKNOWN)
    k = shift_cells
    visual[12 : 48 + k, 12 : 68 + k] = FREE
    visual[48 + k, 12 : 68 + k] = visual[12 : 48 + k, 68 + k] = OCCUPIED
    visual[28 + k : 32 + k, 38 + k : 42 + k] = OCCUPIED
    return radar, visual


def test_a_visual_map_that_disagrees_with_the_radar_map_is_trusted_less():
    spec = GridSpec((0.0, 0.0), 0.1, (60, 80))
    fuser = MapFuser(FusionConfig())
    sound = fuser.fuse(_rooms(0)[0], spec, _rooms(0)[1], spec, 0.5)
    assert sound.agreement > 0.8 and sound.trust_mean == pytest.approx(0.5)
    off = fuser.fuse(_rooms(3)[0], spec, _rooms(3)[1], spec, 0.5)  # walls 0.3 m out
    assert 0.2 < off.agreement < 0.6
    expected = 1.0 - 0.5 * off.agreement / 0.6  # t' = 1 - (1 - t) rho / agreement_clear
    assert off.trust_mean == pytest.approx(expected)
    assert off.summary()["agreement"] == pytest.approx(off.agreement)
    # Walls 0.6 m out contradict the radar map: the camera's map drops out, even where it
    # alone knows cells (its trust 0 is below keep_trust).
    contradicting = fuser.fuse(_rooms(6)[0], spec, _rooms(6)[1], spec, 0.5)
    assert contradicting.agreement < 0.0 and contradicting.trust_mean == 1.0
    assert (contradicting.to_cells()[49 + 6, 20:60] == UNKNOWN).all()
    # A forced t is used as given, and no agreement is reported.
    forced = MapFuser(FusionConfig(trust=0.5)).fuse(_rooms(6)[0], spec, _rooms(6)[1], spec, None)
    assert forced.trust_mean == pytest.approx(0.5) and "agreement" not in forced.summary()


def test_the_agreement_factor_spares_a_sound_or_unmeasured_map():
    model = get_trust_model(FusionConfig())
    assert model.agreement_factor(0.9) == 1.0 and model.agreement_factor(None) == 1.0
    assert model.agreement_factor(0.3) == pytest.approx(0.5)
    assert model.agreement_factor(-0.2) == 0.0
    unused = FusionConfig.model_validate({"trust_model": {"agreement_clear": 0.0}})
    assert get_trust_model(unused).agreement_factor(0.1) == 1.0


def test_trust_grid_spreads_each_keyframe_over_the_cells_it_saw():
    spec = GridSpec((0.0, 0.0), 1.0, (2, 3))
    points = np.array([[0.5, 0.5], [0.6, 0.4], [1.5, 0.5], [1.5, 0.5], [2.5, 1.5]])
    keyframe = np.array([0, 0, 0, 1, 1])
    grid = trust_grid(spec, np.array([0.6, 1.0]), points, keyframe, 0.7)
    # Cell (0, 0): keyframe 0 only, once despite two points; (0, 1): both keyframes.
    np.testing.assert_allclose(grid, [[0.6, 0.8, 0.7], [0.7, 0.7, 1.0]])


def test_an_unconfident_placement_is_never_applied():
    from smokyslam.config import RegistrationConfig

    rng = np.random.default_rng(0)
    radar = np.where(rng.random((120, 120)) < 0.1, OCCUPIED, FREE).astype(np.int8)
    visual = np.full((80, 80), FREE, dtype=np.int8)
    visual[20:60, 20] = OCCUPIED
    visual[20, 20:60] = OCCUPIED
    with pytest.raises(FusionError, match="could not be registered"):
        place_visual_map(visual, radar, RegistrationConfig())
