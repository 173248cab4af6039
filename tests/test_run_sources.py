"""`smokyslam run` for every source: the files and metrics.json keys of the contract."""

import json

import numpy as np
import pytest

from smokyslam.config import load_config
from smokyslam.evaluation.trajectory_io import read_tum
from smokyslam.pipelines.run import run_log

TRAJECTORY_KEYS = {
    "ate_rmse_m",
    "ate_alignment",
    "rpe_trans_rmse_m",
    "path_length_m",
    "drift_pct",
    "frames",
    "lost_frames",
}


@pytest.mark.parametrize(("source", "main_map"), [("camera", "visual"), ("radar", "radar_sparse")])
def test_a_run_writes_the_contract_files(office_log, tmp_path, source, main_map):
    result = run_log(office_log, source, load_config(), tmp_path)
    for name in (
        "trajectory.tum",
        "trajectory_kitti.txt",
        "ground_truth.tum",
        "config.yaml",
        "trajectory.png",
        f"maps/{main_map}.pgm",
        f"maps/{main_map}.yaml",
    ):
        assert (tmp_path / name).is_file(), name
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics == result.metrics
    trajectory = metrics["trajectory"]
    assert set(trajectory) >= TRAJECTORY_KEYS
    assert trajectory["ate_alignment"] == "se2"
    assert metrics["alignment"]["method"] == "se2"
    if source == "camera":  # metric through the camera height, Sim(2) beside it
        assert 0.0 < trajectory["ate_sim2_rmse_m"] <= trajectory["ate_rmse_m"]
        assert abs(trajectory["scale_error_pct"]) < 20.0
        assert metrics["odometry"]["metric_scale"] is True
    assert trajectory["frames"] == len(read_tum(tmp_path / "trajectory.tum")[0])
    assert 0.0 < trajectory["drift_pct"] < 8.0
    assert trajectory["lost_frames"] <= 0.1 * trajectory["frames"]
    assert 0.0 < metrics["maps"][main_map]["error_index"] < 0.35
    assert metrics["realtime_factor"] == pytest.approx(metrics["duration_s"] / metrics["wall_s"])


def test_camera_without_a_camera_is_a_clear_error(tmp_path):
    from smokyslam.config import TopicsConfig
    from smokyslam.errors import TopicError
    from smokyslam.sim.recorder import LogWriter
    from smokyslam.types import RadarScan

    log = tmp_path / "radar_only.mcap"
    with LogWriter(log, TopicsConfig()) as writer:
        writer.write_radar(RadarScan(0.0, np.ones((1, 3)), np.ones(1), np.zeros(1)))
    with pytest.raises(TopicError, match="camera"):
        run_log(log, "camera", load_config(), tmp_path / "out")
