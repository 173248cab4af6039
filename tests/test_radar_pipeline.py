"""run_radar_odometry + write_odometry_outputs: the files a radar run leaves behind."""

import json

import numpy as np
import pytest
from radar_scenes import carmen_poses, write_carmen_log

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.trajectory_io import read_tum
from smokyslam.frontends.readers.carmen import CarmenReader
from smokyslam.pipelines.odometry import run_radar_odometry, write_odometry_outputs
from smokyslam.types import GroundTruthPose


@pytest.fixture(scope="module")
def reader(tmp_path_factory):
    path = write_carmen_log(tmp_path_factory.mktemp("log") / "room.log", carmen_poses(30))
    return CarmenReader(path, SmokySlamConfig())


@pytest.mark.parametrize("source", ["radar", "dead-reckoning"])
def test_a_run_writes_trajectory_ground_truth_metrics_and_plot(reader, tmp_path, source):
    run = run_radar_odometry(reader, SmokySlamConfig(), source)
    assert len(run.stamps_s) == 30 and run.frames_per_s > 0
    metrics = write_odometry_outputs(run, tmp_path)
    names = {p.name for p in tmp_path.iterdir()}
    assert {"trajectory.tum", "trajectory_kitti.txt", "ground_truth.tum", "metrics.json"} <= names
    assert (tmp_path / "trajectory.png").stat().st_size > 10_000
    on_disk = json.loads((tmp_path / "metrics.json").read_text())
    assert on_disk == metrics
    trajectory = on_disk["trajectory"]
    assert set(trajectory) >= {
        "ate_rmse_m",
        "ate_alignment",
        "rpe_trans_rmse_m",
        "path_length_m",
        "drift_pct",
        "frames",
        "lost_frames",
    }
    assert trajectory["ate_alignment"] == "se2"
    assert trajectory["frames"] == 30 and trajectory["lost_frames"] == 0
    assert trajectory["path_length_m"] == pytest.approx(14.5, abs=0.01)  # 29 steps of 0.5 m
    assert 0 < trajectory["ate_rmse_m"] < 0.5
    stamps, poses = read_tum(tmp_path / "trajectory.tum")
    np.testing.assert_allclose(stamps, run.stamps_s, atol=1e-9)
    np.testing.assert_allclose(poses, run.poses_world_base, atol=1e-8)
    gt_stamps, gt_poses = read_tum(tmp_path / "ground_truth.tum")
    np.testing.assert_allclose(gt_stamps, run.gt_stamps_s, atol=1e-9)
    np.testing.assert_allclose(gt_poses[:, :2], carmen_poses(30)[:, :2], atol=1e-5)
    np.testing.assert_allclose(np.cos(gt_poses[:, 2] - carmen_poses(30)[:, 2]), 1.0)
    assert len(np.loadtxt(tmp_path / "trajectory_kitti.txt")) == 30


class _WithoutGroundTruth:
    def __init__(self, reader):
        self._reader = reader

    def frames(self):
        return (f for f in self._reader.frames() if not isinstance(f, GroundTruthPose))

    def extrinsics(self):
        return self._reader.extrinsics()


def test_a_log_without_ground_truth_gets_a_trajectory_only(reader, tmp_path):
    run = run_radar_odometry(_WithoutGroundTruth(reader), SmokySlamConfig(), "radar")
    metrics = write_odometry_outputs(run, tmp_path)
    assert "trajectory" not in metrics
    assert metrics["odometry"]["source"] == "radar"
    assert not (tmp_path / "ground_truth.tum").exists()
    assert (tmp_path / "trajectory.tum").exists() and (tmp_path / "trajectory.png").exists()


def test_metrics_stay_strict_json_when_a_metric_is_undefined(tmp_path):
    # Half a metre of travel: no 1 m relative-pose pairs, so the RPE is undefined.
    path = write_carmen_log(tmp_path / "short.log", carmen_poses(2), malformed=False)
    run = run_radar_odometry(CarmenReader(path, SmokySlamConfig()), SmokySlamConfig(), "radar")
    write_odometry_outputs(run, tmp_path / "out")
    text = (tmp_path / "out" / "metrics.json").read_text()
    assert "NaN" not in text
    assert json.loads(text)["trajectory"]["rpe_trans_rmse_m"] is None
