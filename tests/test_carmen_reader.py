"""CARMEN laser logs: parsing (malformed lines skipped and counted; FLASER and ROBOTLASER1
lines), beam geometry, the laser's mount, no-return detection, and the radar emulation
(Doppler, gyro) checked against the logged poses."""

import gzip

import numpy as np
import pytest
from radar_scenes import NO_RETURN, _flaser, box_ranges, carmen_poses, write_carmen_log

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError
from smokyslam.frontends.radar.doppler import estimate_ego_velocity
from smokyslam.frontends.radar.odometry import DeadReckoning
from smokyslam.frontends.readers.carmen import CarmenReader
from smokyslam.frontends.readers.carmen_emulation import beam_bearings, detect_no_return
from smokyslam.frontends.readers.registry import open_log
from smokyslam.geometry import se2_between, se2_compose
from smokyslam.types import ImuSample, RadarScan


def _quiet_config(**carmen) -> SmokySlamConfig:
    """Default emulation with the given overrides, and exact bearings (the Doppler fit uses
    the measured bearings, so azimuth noise would blur the velocity)."""
    config = SmokySlamConfig()
    config.simulation.radar.azimuth_sigma_deg = 0.0
    for key, value in carmen.items():
        setattr(config.carmen, key, value)
    return config


NOISE_FREE = dict(
    doppler_scale_error=0.0,
    velocity_noise_rel=0.0,
    velocity_noise_abs_m=0.0,
    doppler_point_sigma_mps=0.0,
    gyro_noise_deg=0.0,
    gyro_bias_deg=0.0,
)


def test_malformed_lines_are_skipped_and_counted(tmp_path, caplog):
    poses = carmen_poses()
    reader = CarmenReader(write_carmen_log(tmp_path / "a.log", poses), SmokySlamConfig())
    assert reader.skipped_lines == 4
    assert "skipped 4 malformed" in caplog.text
    truth = reader.ground_truth_trajectory()
    assert len(truth) == len(poses)
    np.testing.assert_allclose(truth.poses_world_base, poses, atol=1e-6)
    np.testing.assert_allclose(truth.stamps_s, reader.stamps_s)
    summary = reader.summary()
    assert summary.format == "carmen"
    assert summary.streams[0].count == len(poses)


def test_frames_order_and_nominal_stamps(tmp_path):
    config = SmokySlamConfig()
    config.carmen.nominal_rate_hz = 2.0
    reader = CarmenReader(
        write_carmen_log(tmp_path / "a.log", carmen_poses(4), malformed=False), config
    )
    kinds = [(type(f).__name__, f.stamp_s) for f in reader.frames()]
    assert kinds[:5] == [
        ("RadarScan", 0.0),
        ("ImuSample", 0.5),
        ("RadarScan", 0.5),
        ("ImuSample", 1.0),
        ("RadarScan", 1.0),
    ]
    assert reader.summary().duration_s == pytest.approx(1.5)


def test_full_scans_follow_the_beam_geometry_without_no_returns(tmp_path):
    poses = carmen_poses(3)
    config = _quiet_config(emulate_radar=False)
    config.simulation.radar.max_range_m = 50.0
    reader = CarmenReader(write_carmen_log(tmp_path / "a.log.gz", poses, opener=gzip.open), config)
    assert reader.beams.no_return_m == pytest.approx(NO_RETURN)
    scan = next(f for f in reader.frames() if isinstance(f, RadarScan))
    bearings = beam_bearings(180)
    expected = box_ranges(poses[0], bearings)
    keep = np.ones(180, dtype=bool)
    keep[::17] = False
    keep &= expected >= config.simulation.radar.min_range_m
    np.testing.assert_allclose(np.hypot(*scan.points_xy_m.T), expected[keep], atol=2e-3)
    np.testing.assert_allclose(np.arctan2(*scan.points_xy_m.T[::-1]), bearings[keep], atol=1e-3)
    np.testing.assert_allclose(scan.points_xyz_m[:, 2], 0.0)


def test_emulated_scans_are_sparse_noisy_and_inside_the_field_of_view(tmp_path):
    config = SmokySlamConfig()
    reader = CarmenReader(write_carmen_log(tmp_path / "a.log", carmen_poses()), config)
    scans = [f for f in reader.frames() if isinstance(f, RadarScan)]
    counts = np.array([len(s) for s in scans])
    assert counts.max() <= config.carmen.points_per_scan
    assert counts.mean() == pytest.approx(config.carmen.points_per_scan * 0.9, abs=4)
    bearings = np.concatenate([np.arctan2(s.points_xy_m[:, 1], s.points_xy_m[:, 0]) for s in scans])
    assert np.abs(bearings).max() < np.radians(config.simulation.radar.fov_deg + 12)
    again = [f for f in reader.frames() if isinstance(f, RadarScan)]
    np.testing.assert_array_equal(scans[3].points_xyz_m, again[3].points_xyz_m)  # seeded


def test_doppler_matches_the_logged_motion(tmp_path):
    poses = carmen_poses()
    reader = CarmenReader(write_carmen_log(tmp_path / "a.log", poses), _quiet_config(**NOISE_FREE))
    scans = [f for f in reader.frames() if isinstance(f, RadarScan)]
    step = se2_between(poses[4], poses[5])
    velocity = estimate_ego_velocity(
        np.arctan2(scans[5].points_xy_m[:, 1], scans[5].points_xy_m[:, 0]), scans[5].doppler_mps
    ).velocity_mps
    # A constant twist over the step: the chord is the velocity turned by half the yaw.
    c, s = np.cos(step[2] / 2), np.sin(step[2] / 2)
    chord_dir = np.array([[c, -s], [s, c]]) @ (velocity / np.linalg.norm(velocity))
    np.testing.assert_allclose(chord_dir, step[:2] / np.linalg.norm(step[:2]), atol=1e-6)
    assert np.linalg.norm(velocity) == pytest.approx(
        np.linalg.norm(step[:2]) * (step[2] / 2) / np.sin(step[2] / 2), rel=1e-6
    )


def _dead_reckon(reader: CarmenReader) -> np.ndarray:
    odometry, imu, poses = DeadReckoning(SmokySlamConfig().radar_odometry, np.zeros(3)), [], []
    for frame in reader.frames():
        if isinstance(frame, ImuSample):
            imu.append(frame)
        elif isinstance(frame, RadarScan):
            poses += [o.pose_world_sensor for o in odometry.register(frame, imu)]
            imu = []
    return np.array(poses)


def test_noise_free_dead_reckoning_reproduces_the_logged_path(tmp_path):
    poses = carmen_poses()
    reader = CarmenReader(write_carmen_log(tmp_path / "a.log", poses), _quiet_config(**NOISE_FREE))
    estimate = _dead_reckon(reader)
    np.testing.assert_allclose(
        se2_between(estimate[:-1], estimate[1:]), se2_between(poses[:-1], poses[1:]), atol=1e-6
    )


def test_emulated_errors_have_the_configured_size(tmp_path):
    poses = carmen_poses()
    scaled = _quiet_config(**{**NOISE_FREE, "doppler_scale_error": 0.1})
    estimate = _dead_reckon(CarmenReader(write_carmen_log(tmp_path / "a.log", poses), scaled))
    steps = np.linalg.norm(np.diff(estimate[:, :2], axis=0), axis=1)
    expected = 1.1 * np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, expected, atol=1e-5)
    biased = _quiet_config(**{**NOISE_FREE, "gyro_bias_deg": 0.5})
    estimate = _dead_reckon(CarmenReader(write_carmen_log(tmp_path / "b.log", poses), biased))
    drift = np.degrees(np.unwrap(estimate[:, 2]) - np.unwrap(poses[:, 2]))
    np.testing.assert_allclose(drift - drift[0], 0.5 * np.arange(len(poses)), atol=1e-4)


@pytest.mark.parametrize(
    ("n", "first_deg", "step_deg"), [(180, -90, 1.0), (361, -90, 0.5), (360, -90, 0.5)]
)
def test_beam_geometry_is_derived_from_the_count(n, first_deg, step_deg):
    bearings = np.degrees(beam_bearings(n))
    assert bearings[0] == pytest.approx(first_deg)
    np.testing.assert_allclose(np.diff(bearings), step_deg)


def test_no_return_detection():
    ranges = np.random.default_rng(0).uniform(0.5, 20.0, size=(50, 180))
    assert detect_no_return(ranges) == float("inf")
    ranges[:, 7] = 50.0
    assert detect_no_return(ranges) == 50.0


def test_unreadable_logs_raise_log_errors(tmp_path):
    with pytest.raises(LogError, match="no such log"):
        CarmenReader(tmp_path / "missing.log", SmokySlamConfig())
    empty = tmp_path / "empty.log"
    empty.write_text("PARAM x 1\nODOM 0 0 0 0 0 0 0 h 0\n")
    with pytest.raises(LogError, match="no FLASER"):
        CarmenReader(empty, SmokySlamConfig())
    broken = tmp_path / "broken.log.gz"
    broken.write_bytes(b"not gzip at all")
    with pytest.raises(LogError, match="cannot read"):
        CarmenReader(broken, SmokySlamConfig())


def test_trajectory_stamps_use_the_logs_own_times_when_they_increase(tmp_path, caplog):
    bearings = beam_bearings(180)
    poses = carmen_poses(6)
    lines = [_flaser(box_ranges(p, bearings), p, 1000.0 + 2.5 * i) for i, p in enumerate(poses)]
    increasing = tmp_path / "increasing.log"
    increasing.write_text("\n".join(lines) + "\n")
    reader = CarmenReader(increasing, SmokySlamConfig())
    stamps = reader.ground_truth_trajectory().stamps_s
    np.testing.assert_allclose(reader.log_time_s(stamps), 1000.0 + 2.5 * np.arange(6))
    # Between lines, the log's clock is interpolated.
    assert reader.log_time_s(np.array([0.5 * reader.dt_s]))[0] == pytest.approx(1001.25)
    assert "do not increase" not in caplog.text

    times = [1000.0, 1002.0, 1001.0, 1003.0, 1004.0, 1005.0]  # one step back
    lines = [_flaser(box_ranges(p, bearings), p, t) for p, t in zip(poses, times, strict=True)]
    backwards = tmp_path / "backwards.log"
    backwards.write_text("\n".join(lines) + "\n")
    reader = CarmenReader(backwards, SmokySlamConfig())
    stamps = reader.ground_truth_trajectory().stamps_s
    np.testing.assert_array_equal(reader.log_time_s(stamps), stamps)  # by index
    assert "timestamps do not increase" in caplog.text and "by scan index" in caplog.text


def _robotlaser(ranges, robot, mount, start_rad, resolution_rad, stamp):
    """A ``ROBOTLASER1`` line: the scan ``ranges`` of a laser mounted at ``mount`` on a robot
    at ``robot``, with two remission values."""
    laser = se2_compose(robot, mount)
    fov = resolution_rad * (len(ranges) - 1)
    head = f"ROBOTLASER1 0 {start_rad:.6f} {fov:.6f} {resolution_rad:.8f} {NO_RETURN} 0.01 0"
    values = " ".join(f"{r:.4f}" for r in ranges)
    poses = " ".join(f"{v:.6f}" for v in np.concatenate([laser, robot]))
    return (
        f"{head} {len(ranges)} {values} 2 0.5 0.5 {poses} 0.3 0.1 0.5 0.3 0.0 {stamp} host {stamp}"
    )


MOUNT = np.array([0.25, -0.05, 0.1])
"""A laser ahead of the robot, a little right, turned 5.7 degrees left."""


def _robotlaser_log(path, poses):
    """A log of 241 beams from -120 deg at 1 deg, two malformed lines among them."""
    start_rad, resolution_rad = np.radians(-120.0), np.radians(1.0)
    bearings = start_rad + resolution_rad * np.arange(241)
    lines = ["# CARMEN log with ROBOTLASER1 lines", "ODOM 0 0 0 0 0 0 0 host 0"]
    for i, pose in enumerate(poses):
        ranges = box_ranges(se2_compose(pose, MOUNT), bearings)
        lines.append(_robotlaser(ranges, pose, MOUNT, start_rad, resolution_rad, 10.0 + i))
    lines.insert(3, lines[2].rsplit(" ", 30)[0])  # truncated
    lines.insert(4, lines[2].replace(" 241 ", " 241x ", 1))  # bad beam count
    path.write_text("\n".join(lines) + "\n")
    return path, bearings


def test_robotlaser_lines_give_their_own_beams_and_the_laser_mount(tmp_path):
    poses = carmen_poses(6)
    path, bearings = _robotlaser_log(tmp_path / "a.clf", poses)
    config = _quiet_config(emulate_radar=False)
    config.simulation.radar.max_range_m = 50.0
    reader = open_log(path, config)  # .clf is a CARMEN log
    assert reader.skipped_lines == 2
    assert reader.summary().streams[0].topic == "ROBOTLASER1"
    np.testing.assert_allclose(reader.radar_mount, MOUNT, atol=1e-5)
    np.testing.assert_allclose(reader.beams.bearings_rad, bearings, atol=1e-5)
    np.testing.assert_allclose(reader.ground_truth_trajectory().poses_world_base, poses, atol=1e-5)
    np.testing.assert_allclose(reader.log_time_s(reader.stamps_s), 10.0 + np.arange(6))
    scan = next(f for f in reader.frames() if isinstance(f, RadarScan))
    # Every beam's end lies on the room's walls once placed with the mount and the pose.
    ends = se2_compose(
        se2_compose(poses[0], MOUNT),
        np.column_stack([scan.points_xy_m, 0 * scan.points_xy_m[:, 0]]),
    )
    on_wall = np.minimum.reduce([ends[:, 0], 12.0 - ends[:, 0], ends[:, 1], 8.0 - ends[:, 1]])
    assert len(scan) > 200
    np.testing.assert_allclose(on_wall, 0.0, atol=2e-3)


def test_a_log_with_both_kinds_is_read_as_the_kind_most_lines_are(tmp_path):
    poses = carmen_poses(6)
    robot_lines = _robotlaser_log(tmp_path / "r.log", poses)[0].read_text().splitlines()
    flaser_lines = write_carmen_log(tmp_path / "f.log", poses[:4], malformed=False)
    mixed = tmp_path / "mixed.log.gz"
    with gzip.open(mixed, "wt") as stream:
        stream.write("\n".join(flaser_lines.read_text().splitlines() + robot_lines) + "\n")
    reader = CarmenReader(mixed, SmokySlamConfig())
    assert reader.summary().streams[0].topic == "ROBOTLASER1"
    assert len(reader.ground_truth_trajectory()) == 6
    flaser_lines.write_text(flaser_lines.read_text() + "\n".join(robot_lines[2:4]) + "\n")
    assert CarmenReader(flaser_lines, SmokySlamConfig()).summary().streams[0].topic == "FLASER"
