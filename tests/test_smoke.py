"""SmokeEmulator: exact drop/noise counts, the haze formula, seeded per-frame determinism."""

import math

import numpy as np
import pytest

from smokyslam.config import SmokeConfig, load_config
from smokyslam.errors import ConfigError
from smokyslam.smoke import SmokeEmulator, SmokeLevel, parse_smoke
from smokyslam.types import CameraFrame, ImuSample, RadarScan


def _scan(n: int, stamp_s: float = 1.0) -> RadarScan:
    marker = np.arange(n, dtype=float)
    xyz = np.stack([marker, 2 * marker, 3 * marker], axis=1)
    return RadarScan(stamp_s, xyz, marker + 0.5, -marker)


def _grey(value: int, stamp_s: float = 1.0, depth_m: np.ndarray | None = None) -> CameraFrame:
    return CameraFrame(stamp_s, np.full((240, 320), value, np.uint8), depth_m=depth_m)


@pytest.mark.parametrize(
    ("loss", "n", "kept"),
    [(0.0, 41, 41), (0.3, 41, 29), (0.5, 41, 20), (0.5, 40, 20), (1.0, 41, 0), (0.25, 0, 0)],
)
def test_radar_drops_exactly_the_asked_fraction(loss: float, n: int, kept: int) -> None:
    scan = _scan(n)
    out = SmokeEmulator(SmokeConfig(radar_loss=loss)).apply(scan)
    assert len(out) == kept and out.stamp_s == scan.stamp_s
    # surviving returns keep their attributes together and in order
    marker = out.intensity - 0.5
    np.testing.assert_array_equal(out.points_xyz_m[:, 1], 2 * marker)
    np.testing.assert_array_equal(out.doppler_mps, -marker)
    assert (np.diff(marker) > 0).all()
    assert len(scan) == n  # input untouched


def test_radar_loss_is_random_and_seeded() -> None:
    emulator = SmokeEmulator(SmokeConfig(radar_loss=0.5, seed=3))
    frames = [_scan(60, 0.1 * i) for i in range(20)]
    first = [emulator.apply(f).intensity for f in frames]
    # per-frame streams: reprocessing in reverse order, alone, or by a new emulator is identical
    again = [
        SmokeEmulator(SmokeConfig(radar_loss=0.5, seed=3)).apply(f).intensity for f in frames[::-1]
    ]
    for a, b in zip(first, again[::-1], strict=True):
        np.testing.assert_array_equal(a, b)
    # different frames and different seeds drop different returns
    assert len({tuple(k) for k in first}) == 20
    other = SmokeEmulator(SmokeConfig(radar_loss=0.5, seed=4)).apply(frames[0]).intensity
    assert not np.array_equal(other, first[0])
    # every return is dropped about half of the time over many frames
    kept = np.zeros(60)
    for f in frames:
        kept[(emulator.apply(f).intensity - 0.5).astype(int)] += 1
    assert kept.sum() == 20 * 30 and kept.max() <= 18 and kept.min() >= 2


def test_haze_formula_on_constant_image() -> None:
    config = SmokeConfig(haze=0.5, airlight=200.0, default_depth_m=3.0)
    emulator = SmokeEmulator(config)
    at_2m = emulator.apply(_grey(100, depth_m=np.full((240, 320), 2.0, np.float32)))
    t = math.exp(-0.5 * 2.0)
    assert (at_2m.image == round(100 * t + 200 * (1 - t))).all()  # 163
    assert at_2m.image[0, 0] == 163
    no_depth = emulator.apply(_grey(100))
    t = math.exp(-0.5 * 3.0)
    assert (no_depth.image == round(100 * t + 200 * (1 - t))).all()  # 178
    depth = np.full((240, 320), 2.0, np.float32)
    depth[:10] = np.nan  # unknown depth falls back to default_depth_m
    depth[-10:] = 40.0  # far away: almost pure airlight
    mixed = emulator.apply(_grey(100, depth_m=depth)).image
    assert (mixed[:10] == 178).all() and (mixed[10:-10] == 163).all() and (mixed[-10:] == 200).all()


def test_salt_and_pepper_exact_count_half_black_half_white() -> None:
    emulator = SmokeEmulator(SmokeConfig(camera_noise=0.2))
    frame = _grey(128)
    out = emulator.apply(frame)
    changed = out.image != 128
    assert changed.sum() == round(0.2 * 240 * 320)
    assert set(np.unique(out.image[changed])) == {0, 255}
    assert (out.image == 255).sum() == pytest.approx(changed.sum() / 2, rel=0.05)
    assert (frame.image == 128).all()  # input untouched
    np.testing.assert_array_equal(emulator.apply(frame).image, out.image)
    assert not np.array_equal(emulator.apply(_grey(128, stamp_s=2.0)).image, out.image)


def test_haze_then_noise() -> None:
    config = SmokeConfig(haze=0.5, camera_noise=0.01, default_depth_m=2.0)
    out = SmokeEmulator(config).apply(_grey(100)).image
    noisy = (out == 0) | (out == 255)
    assert noisy.sum() == 768 and (out[~noisy] == 163).all()


def test_other_frames_and_clean_config_pass_through() -> None:
    emulator = SmokeEmulator(SmokeConfig(radar_loss=0.9, camera_noise=0.5, haze=1.0))
    imu = ImuSample(0.0, np.zeros(3), np.zeros(3))
    assert emulator.apply(imu) is imu
    clean = SmokeEmulator(SmokeConfig())
    frame, scan = _grey(77), _scan(10)
    np.testing.assert_array_equal(clean.apply(frame).image, frame.image)
    assert len(clean.apply(scan)) == 10


def test_smoke_levels_are_nested_so_more_smoke_degrades_the_same_log_further():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(60, 3))
    scan = RadarScan(2.5, points, np.zeros(60), np.zeros(60))
    kept = [
        {tuple(p) for p in SmokeEmulator(SmokeConfig(radar_loss=r)).apply(scan).points_xyz_m}
        for r in (0.1, 0.2, 0.5)
    ]
    assert [len(k) for k in kept] == [54, 48, 30]
    assert kept[2] < kept[1] < kept[0]
    image = np.full((40, 50), 128, dtype=np.uint8)
    frame = CameraFrame(1.0, image)
    noisy = [
        SmokeEmulator(SmokeConfig(camera_noise=f)).apply(frame).image != 128 for f in (0.05, 0.2)
    ]
    assert noisy[0].sum() == 100 and noisy[1].sum() == 400
    assert np.all(noisy[1][noisy[0]])


@pytest.mark.parametrize(
    ("text", "values", "label"),
    [
        ("0:0", (0.0, 0.0, 0.0), "r0-c0"),
        ("0.1:0.2", (0.1, 0.2, 0.0), "r0.1-c0.2"),
        (" 0.1:0.2:0.5 ", (0.1, 0.2, 0.5), "r0.1-c0.2-h0.5"),
        ("0.2:0.40:0", (0.2, 0.4, 0.0), "r0.2-c0.40"),  # haze 0 is haze-free
    ],
)
def test_smoke_notation_keeps_the_numbers_as_typed(text, values, label) -> None:
    level = parse_smoke(text)
    assert (level.radar_loss, level.camera_noise, level.haze) == values
    assert level.label == label
    assert parse_smoke(level.notation) == level
    smoke = level.apply(load_config(None, {"smoke": {"airlight": 150.0, "seed": 4}})).smoke
    assert (smoke.radar_loss, smoke.camera_noise, smoke.haze) == values
    assert (smoke.airlight, smoke.seed) == (150.0, 4)
    assert SmokeLevel.from_values(*values) == parse_smoke(
        f"{values[0]:g}:{values[1]:g}:{values[2]:g}"
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0.1", "radar_loss:camera_noise\\[:haze\\]"),
        ("0:0:0:0", "radar_loss:camera_noise"),
        ("a:0", "radar_loss in 'a:0' is not a number"),
        ("0:1.5", "camera_noise in '0:1.5' must be between 0 and 1"),
        ("0:0:-1", "haze in '0:0:-1' must be 0 or more"),
        ("nan:0", "must be between 0 and 1"),
        ("1e-1:0", "plain decimal"),
    ],
)
def test_bad_smoke_notation_is_one_config_error(text, message) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_smoke(text)
