"""A radar run over a log: the trajectory files, metrics and plot it leaves behind."""

import json

import numpy as np
import pytest
from radar_scenes import carmen_poses, write_carmen_log

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.trajectory_io import read_tum
from smokyslam.frontends.readers.carmen import CarmenReader
from smokyslam.geometry import se2_between
from smokyslam.pipelines.run import run_log, run_source


@pytest.fixture(scope="module")
def room_log(tmp_path_factory):
    return write_carmen_log(tmp_path_factory.mktemp("log") / "room.log", carmen_poses(30))


@pytest.mark.parametrize("source", ["radar", "dead-reckoning"])
def test_a_run_writes_trajectory_ground_truth_metrics_and_plot(room_log, tmp_path, source):
    result = run_log(room_log, source, SmokySlamConfig(), tmp_path)
    assert len(result.estimate.stamps_s) == 30 and result.estimate.frames_per_s > 0
    names = {p.name for p in tmp_path.iterdir()}
    assert {"trajectory.tum", "trajectory_kitti.txt", "ground_truth.tum", "metrics.json"} <= names
    assert (tmp_path / "trajectory.png").stat().st_size > 10_000
    on_disk = json.loads((tmp_path / "metrics.json").read_text())
    assert on_disk == result.metrics
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
    i = np.arange(30)
    np.testing.assert_allclose(stamps, 5.0 * i - 3.0 * (i % 3), atol=1e-9)  # the log's own
    gt_stamps, gt_poses = read_tum(tmp_path / "ground_truth.tum")
    np.testing.assert_allclose(gt_stamps, stamps, atol=1e-9)
    np.testing.assert_allclose(gt_poses[:, :2], carmen_poses(30)[:, :2], atol=1e-5)
    np.testing.assert_allclose(np.cos(gt_poses[:, 2] - carmen_poses(30)[:, 2]), 1.0)
    # The written trajectory is the estimate moved rigidly into the ground-truth frame, and
    # its error there is the ATE.
    np.testing.assert_allclose(
        se2_between(poses[0], poses),
        se2_between(result.estimate.poses_world_base[0], result.estimate.poses_world_base),
        atol=1e-6,
    )
    error = np.linalg.norm(poses[:, :2] - gt_poses[:, :2], axis=1)
    assert np.sqrt(np.mean(error**2)) == pytest.approx(trajectory["ate_rmse_m"], abs=1e-6)
    assert len(np.loadtxt(tmp_path / "trajectory_kitti.txt")) == 30


def _sensor_log(room_log, path):
    """The room walk's radar and gyro as a ROS2 log with no ground truth."""
    from smokyslam.config import TopicsConfig
    from smokyslam.sim.recorder import LogWriter
    from smokyslam.types import ImuSample, RadarScan

    with LogWriter(path, TopicsConfig()) as writer:
        for frame in CarmenReader(room_log, SmokySlamConfig()).frames():
            if isinstance(frame, RadarScan):
                writer.write_radar(frame)
            elif isinstance(frame, ImuSample):
                writer.write_imu(frame)
    return path


def test_a_log_without_ground_truth_gets_a_trajectory_only(room_log, tmp_path):
    log = _sensor_log(room_log, tmp_path / "no_truth.mcap")
    metrics = run_log(log, "radar", SmokySlamConfig(), tmp_path / "out").metrics
    out = tmp_path / "out"
    assert "trajectory" not in metrics and "maps" not in metrics
    assert metrics["alignment"]["method"] == "none"
    assert metrics["odometry"]["source"] == "radar"
    assert not (out / "ground_truth.tum").exists()
    assert (out / "trajectory.tum").exists() and (out / "trajectory.png").exists()
    assert (out / "maps" / "radar_sparse.pgm").exists()
    _, poses = read_tum(out / "trajectory.tum")
    np.testing.assert_allclose(poses[0], 0.0, atol=1e-6)  # the estimate's own frame


def test_metrics_stay_strict_json_when_a_metric_is_undefined(tmp_path):
    # Half a metre of travel: no 1 m relative-pose pairs, so the RPE is undefined.
    path = write_carmen_log(tmp_path / "short.log", carmen_poses(2), malformed=False)
    run_log(path, "radar", SmokySlamConfig(), tmp_path / "out")
    text = (tmp_path / "out" / "metrics.json").read_text()
    assert "NaN" not in text
    assert json.loads(text)["trajectory"]["rpe_trans_rmse_m"] is None


def test_the_estimate_starts_at_the_first_keyframe(room_log):
    reader = CarmenReader(room_log, SmokySlamConfig())
    for source in ("radar", "dead-reckoning"):
        estimate = run_source(reader, source, SmokySlamConfig())
        np.testing.assert_allclose(estimate.poses_world_base[0], 0.0, atol=1e-9)
