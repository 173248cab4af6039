"""Radar calibration YAML (radar on the IMU body) and levelled radar odometry."""

import dataclasses

import numpy as np
import pytest

from smokyslam.config import load_config
from smokyslam.errors import ConfigError
from smokyslam.frontends.readers.registry import open_log
from smokyslam.pipelines.run import run_source
from smokyslam.rig import extrinsics_from_calibration
from smokyslam.types import RadarScan

ROLL_PI = np.diag([1.0, -1.0, -1.0])
"""An upside-down radar: 180 deg about its x axis (boresight kept, left and up swapped)."""

CALIBRATION = """\
topic_radar_scan: "/ti_mmwave/radar_scan_pcl"
l_b_r_x: 0.1
l_b_r_y: -0.2
l_b_r_z: 0.3
q_b_r_x: {qx}
q_b_r_y: 0.0
q_b_r_z: 0.0
q_b_r_w: {qw}
"""


def test_calibration_yaml_gives_the_radar_mount(tmp_path):
    path = tmp_path / "rig.calib.yaml"
    path.write_text(CALIBRATION.format(qx=1.0, qw=0.0))  # 180 deg about x
    T = extrinsics_from_calibration(path).T_base_radar
    np.testing.assert_allclose(T[:3, :3], ROLL_PI, atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [0.1, -0.2, 0.3])
    path.write_text(CALIBRATION.format(qx=np.sin(0.25), qw=np.cos(0.25)))  # 0.5 rad about x
    T = extrinsics_from_calibration(path).T_base_radar
    assert T[1, 2] == pytest.approx(-np.sin(0.5)) and T[2, 1] == pytest.approx(np.sin(0.5))


def test_real_calibration_puts_the_ti_radar_upside_down(real_data_dir):
    T = extrinsics_from_calibration(real_data_dir / "ti_mmwave_rospkg_demo.calib.yaml").T_base_radar
    boresight = T[:3, 0]
    assert np.degrees(np.arctan2(boresight[1], boresight[0])) == pytest.approx(44.3, abs=0.5)
    assert T[2, 2] < -0.95  # the radar's z points down
    np.testing.assert_allclose(T[:3, 3], [0.03, 0.03, -0.06])


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("l_b_r_x: 0.1\n", "missing l_b_r_y"),
        (CALIBRATION.format(qx=0.5, qw=0.5), "not a unit quaternion"),
        (CALIBRATION.format(qx="abc", qw=0.0), "must be numbers"),
        ("- just\n- a list\n", "not a YAML mapping"),
    ],
)
def test_bad_calibration_is_one_clear_error(tmp_path, text, problem):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=problem):
        extrinsics_from_calibration(path)


class _UpsideDownRadar:
    """The office log as seen by a radar mounted upside down (rolled 180 deg); its extrinsics
    say so when ``calibrated``."""

    def __init__(self, reader, calibrated: bool) -> None:
        self.reader, self.path, self.calibrated = reader, reader.path, calibrated

    def __getattr__(self, name):
        return getattr(self.reader, name)

    def frames(self, streams=None):
        for frame in self.reader.frames(streams):
            if isinstance(frame, RadarScan):
                frame = dataclasses.replace(frame, points_xyz_m=frame.points_xyz_m @ ROLL_PI)
            yield frame

    def extrinsics(self):
        extrinsics = self.reader.extrinsics()
        T = extrinsics.T_base_radar.copy()
        if self.calibrated:
            T[:3, :3] = T[:3, :3] @ ROLL_PI
        return dataclasses.replace(extrinsics, T_base_radar=T)


def test_upside_down_radar_tracks_like_an_upright_one_once_calibrated(office_log):
    """Scans are levelled through the mount before odometry, so the gyro and the scans turn
    the same way; without the calibration the flipped scans contradict the gyro."""
    config = load_config()
    upright = run_source(open_log(office_log, config), "radar", config)
    flipped = run_source(_UpsideDownRadar(open_log(office_log, config), True), "radar", config)
    np.testing.assert_allclose(flipped.poses_world_base, upright.poses_world_base, atol=1e-6)
    wrong = run_source(_UpsideDownRadar(open_log(office_log, config), False), "radar", config)
    error_xy = wrong.poses_world_base[:, :2] - upright.poses_world_base[:, :2]
    assert np.linalg.norm(error_xy, axis=1).max() > 1.0
