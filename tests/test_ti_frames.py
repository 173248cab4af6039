"""TI mmWave UART frames: decoding (SDK 1.x/2.x and 3.x), resync after damage, fuzzing, and
``import-ti`` to a log that ``run`` replays."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ti_scenes import MAGIC, scene_points, sdk1_frame, sdk3_frame

from smokyslam.errors import ConfigError
from smokyslam.frontends.sensors.ti_config import load_ti_config, parse_ti_config
from smokyslam.frontends.sensors.ti_frames import TiFrameParser

CFG = Path(__file__).resolve().parents[1] / "configs/iwr1443_indoor.cfg"
RESOLUTION = 0.25


def test_the_shipped_cfg_gives_its_documented_resolutions():
    cfg = load_ti_config(CFG)
    assert cfg.doppler_resolution_mps == pytest.approx(0.632, abs=1e-3)
    assert cfg.range_resolution_m == pytest.approx(0.0436, abs=1e-4)
    assert cfg.frame_period_s == pytest.approx(0.1)
    assert cfg.commands[0] == "sensorStop" and cfg.commands[-1] == "sensorStart"
    with pytest.raises(ConfigError, match="no frameCfg line"):
        parse_ti_config("sensorStop\nprofileCfg 0 77 7 7 57 0 0 70 1 256 5209 0 0 30\n")


def test_an_sdk1_frame_decodes_into_ros_axes():
    xyz = np.array([[0.5, 2.0, 0.1], [-1.0, 3.0, -0.2]])
    frame_bytes = sdk1_frame(7, xyz, np.array([2, -3]), peak=np.array([99, 9]), q_format=8)
    (frame,) = TiFrameParser(RESOLUTION).feed(frame_bytes)
    assert frame.frame_number == 7 and frame.sdk == 1
    # ROS axes: x = sensor y (forward), y = -sensor x, z = sensor z; 1/256 m quantisation.
    np.testing.assert_allclose(frame.points_xyz_m, [[2.0, -0.5, 0.1], [3.0, 1.0, -0.2]], atol=2e-3)
    np.testing.assert_allclose(frame.velocity_mps, [0.5, -0.75])
    np.testing.assert_allclose(frame.intensity, [20.0, 10.0])


def test_an_sdk3_frame_decodes_with_its_snr():
    xyz = np.array([[0.5, 2.0, 0.1], [-1.0, 3.0, -0.2], [0.0, 1.0, 0.0]])
    frame_bytes = sdk3_frame(42, xyz, np.array([0.3, -1.2, 0.0]), np.array([12.5, 20.0, 7.3]))
    (frame,) = TiFrameParser(RESOLUTION).feed(frame_bytes)
    assert frame.frame_number == 42 and frame.sdk == 3
    np.testing.assert_allclose(frame.points_xyz_m[:, 0], xyz[:, 1], rtol=1e-6)
    np.testing.assert_allclose(frame.points_xyz_m[:, 1], -xyz[:, 0], rtol=1e-6)
    np.testing.assert_allclose(frame.velocity_mps, [0.3, -1.2, 0.0], rtol=1e-6)
    np.testing.assert_allclose(frame.intensity, [12.5, 20.0, 7.3])


def test_an_empty_frame_is_a_frame_and_bytes_may_come_one_at_a_time():
    stream = sdk1_frame(1, np.zeros((0, 3)), []) + sdk1_frame(2, [[0, 1, 0]], [1])
    parser = TiFrameParser(RESOLUTION)
    frames = [f for byte in stream for f in parser.feed(bytes([byte]))]
    assert [len(f.points_xyz_m) for f in frames] == [0, 1]
    assert parser.stats.frames == 2 and parser.stats.dropped == 0


def damaged_stream(rng) -> tuple[bytes, list[int]]:
    """Valid frames 0..9 with damage between and inside some; returns the frames expected."""
    frames = [sdk1_frame(i, *scene_points(i, rng)) for i in range(10)]
    stream = b"noise before the first frame" + frames[0]
    stream += rng.bytes(37) + frames[1]  # byte noise between frames
    stream += frames[2][:50]  # a truncated frame, cut by the next one
    stream += frames[3]
    lying = bytearray(frames[4])
    lying[8 + 4 * 6 : 8 + 4 * 7] = (9).to_bytes(4, "little")  # numTLVs 9: past the packet
    stream += bytes(lying)
    huge = bytearray(frames[5])
    huge[12:16] = (10**9).to_bytes(4, "little")  # a packet length no frame has
    stream += bytes(huge) + frames[6]
    wrong_count = bytearray(frames[7])
    wrong_count[8 + 4 * 5 : 8 + 4 * 6] = (99).to_bytes(4, "little")  # numDetectedObj 99
    stream += bytes(wrong_count) + frames[8] + frames[9][:-40]  # and cut off at the end
    return stream, [0, 1, 3, 6, 8]


def test_damage_is_dropped_counted_and_parsing_resyncs():
    stream, expected = damaged_stream(np.random.default_rng(1))
    parser = TiFrameParser(RESOLUTION)
    frames = parser.feed(stream)
    parser.finish()
    assert [f.frame_number for f in frames] == expected
    stats = parser.stats
    assert stats.frames == 5 and stats.dropped == 5
    assert stats.reasons == {
        "truncated": 2,
        "tlv past packet": 1,
        "bad header": 1,
        "points size": 1,
    }
    assert stats.bytes_skipped >= len(b"noise before the first frame") + 37


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=3000))
def test_random_bytes_never_raise(data):
    parser = TiFrameParser(RESOLUTION)
    for start in range(0, len(data), 97):
        parser.feed(data[start : start + 97])
    parser.finish()
    assert parser.stats.frames + parser.stats.dropped <= max(1, len(data) // 8)


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_mutated_frames_never_raise_and_good_ones_survive(data):
    rng = np.random.default_rng(data.draw(st.integers(0, 2**16)))
    frames = [sdk1_frame(i, *scene_points(i, rng)) for i in range(4)]
    target = data.draw(st.integers(0, 3))
    mutated = bytearray(frames[target])
    for _ in range(data.draw(st.integers(1, 6))):
        mutated[data.draw(st.integers(0, len(mutated) - 1))] = data.draw(st.integers(0, 255))
    stream = b"".join(bytes(mutated) if i == target else f for i, f in enumerate(frames))
    parser = TiFrameParser(RESOLUTION)
    numbers = [f.frame_number for f in parser.feed(stream)]
    parser.finish()
    # Every untouched frame after the damaged one is still found (resync at its magic word).
    assert set(range(target + 1, 4)) <= set(numbers)
    assert parser.stats.frames + parser.stats.dropped >= 4 - (MAGIC not in mutated)


def smokyslam(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)], capture_output=True, text=True
    )


def test_import_ti_makes_a_log_that_run_replays(tmp_path):
    rng = np.random.default_rng(5)
    capture = tmp_path / "capture.dat"
    stream = b"".join(sdk1_frame(100 + i, *scene_points(i, rng)) for i in range(40))
    damaged, _ = damaged_stream(rng)
    capture.write_bytes(stream + damaged)
    log = tmp_path / "imported.mcap"
    out = smokyslam("import-ti", capture, "--radar-cfg", CFG, "--out", log)
    assert out.returncode == 0, out.stderr
    assert "45 scans" in out.stdout and "5 frames dropped" in out.stdout
    info = smokyslam("info", log)
    assert "/ti_mmwave/radar_scan_pcl" in info.stdout and " 45 " in info.stdout
    run = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path / "run")
    assert run.returncode == 0, run.stderr
    stamps = np.loadtxt(tmp_path / "run" / "trajectory.tum")[:, 0]
    assert len(stamps) == 45 and np.all(np.diff(stamps) > 0)
    assert np.diff(stamps)[:39] == pytest.approx(0.1, abs=1e-6)  # counter x the cfg period
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["odometry"]["lost_frames"] < 45


def test_import_ti_of_pure_noise_is_one_clear_line(tmp_path):
    capture = tmp_path / "noise.dat"
    capture.write_bytes(np.random.default_rng(0).bytes(100_000))
    out = smokyslam("import-ti", capture, "--radar-cfg", CFG, "--out", tmp_path / "x.mcap")
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 1 and len(lines) == 1 and "no TI mmWave frame found" in lines[0]
    assert not (tmp_path / "x.mcap").exists()


def test_the_package_encoder_round_trips_through_the_parser():
    from smokyslam.frontends.sensors.ti_encode import encode_sdk1_frame

    xyz, doppler = scene_points(3, np.random.default_rng(2))
    peak = np.arange(len(xyz)) * 100
    ours = encode_sdk1_frame(3, xyz, doppler, peak)
    (frame,) = TiFrameParser(RESOLUTION).feed(ours)
    (reference,) = TiFrameParser(RESOLUTION).feed(sdk1_frame(3, xyz, doppler, peak))
    np.testing.assert_array_equal(frame.points_xyz_m, reference.points_xyz_m)
    np.testing.assert_array_equal(frame.velocity_mps, reference.velocity_mps)
    np.testing.assert_array_equal(frame.intensity, reference.intensity)


def test_the_bench_parses_what_it_encodes():
    from smokyslam.benchmarks.suite import ti_parse_frames_per_s

    assert ti_parse_frames_per_s(frames=20, points=5) > 0.0
