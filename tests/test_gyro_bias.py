"""The gyro's true bias over a run, scored against ground truth beside the radar's estimate."""

import json

import numpy as np
import pytest

from smokyslam.config import load_config
from smokyslam.evaluation.gyro_bias import GyroTally, gyro_bias_metrics
from smokyslam.frontends.readers.registry import open_log
from smokyslam.pipelines.run import run_log
from smokyslam.sim.simulate import simulate
from smokyslam.types import GroundTruthTrajectory, ImuSample

TRUE_RATE = 0.3  # rad/s, turning steadily
BIAS = 0.002  # rad/s


def _turning_truth(duration_s: float) -> GroundTruthTrajectory:
    stamps = np.arange(0.0, duration_s + 1e-9, 0.02)
    yaw = np.angle(np.exp(1j * TRUE_RATE * stamps))  # wrapped, as logs store it
    return GroundTruthTrajectory(stamps, np.column_stack([stamps, 0 * stamps, yaw]))


def _tally(stamps: np.ndarray, rate: float) -> GyroTally:
    tally = GyroTally()
    for stamp in stamps:
        tally.add(ImuSample(float(stamp), np.array([0.0, 0.0, rate]), np.zeros(3)))
    return tally


def test_the_true_bias_is_the_gyro_s_mean_rate_less_the_true_one():
    tally = _tally(np.arange(0.5, 20.0, 0.01), TRUE_RATE + BIAS)
    scores = gyro_bias_metrics(tally, _turning_truth(20.0), 0.05)
    assert scores["true_degps"] == pytest.approx(np.degrees(BIAS), abs=1e-6)
    assert scores["estimated_degps"] == 0.05
    assert scores["residual_degps"] == pytest.approx(np.degrees(BIAS) - 0.05, abs=1e-6)
    unestimated = gyro_bias_metrics(tally, _turning_truth(20.0), None)
    assert unestimated["residual_degps"] == pytest.approx(np.degrees(BIAS), abs=1e-6)


def test_no_score_without_truth_over_the_imu_s_span():
    tally = _tally(np.arange(0.0, 20.0, 0.01), TRUE_RATE)
    assert gyro_bias_metrics(tally, None, 0.0) is None
    assert gyro_bias_metrics(tally, _turning_truth(10.0), 0.0) is None  # truth ends early
    assert gyro_bias_metrics(_tally(np.array([1.0]), TRUE_RATE), _turning_truth(10.0), 0.0) is None


@pytest.fixture(scope="module")
def biased_log(tmp_path_factory):
    """20 s of office, radar and a gyro with a large bias and no noise."""
    config = load_config()
    imu = config.simulation.imu.model_copy(update={"gyro_bias_radps": 0.01, "gyro_noise_radps": 0})
    config = config.model_copy(
        update={"simulation": config.simulation.model_copy(update={"imu": imu})}
    )
    path = tmp_path_factory.mktemp("gyro") / "office.mcap"
    simulate("office", 20.0, 3, path, config, sensors=frozenset({"radar", "imu"}))
    return path


def _independent_bias_degps(path) -> float:
    """Mean of the gyro's rate less the true yaw rate, sample by sample (not the tally's way)."""
    reader = open_log(path, load_config())
    samples = [f for f in reader.frames(("imu",)) if isinstance(f, ImuSample)]
    stamps = np.array([s.stamp_s for s in samples])
    gyro = np.array([s.gyro_radps[2] for s in samples])
    truth = reader.ground_truth_trajectory()
    yaw = np.unwrap(truth.poses_world_base[:, 2])
    true_rate = np.interp(stamps, truth.stamps_s, np.gradient(yaw, truth.stamps_s))
    return float(np.degrees(np.mean(gyro - true_rate)))


@pytest.mark.parametrize("source", ["radar", "dead-reckoning"])
def test_a_run_reports_the_gyro_s_true_bias_beside_its_estimate(biased_log, tmp_path, source):
    run_log(biased_log, source, load_config(), tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    scores = metrics["gyro_bias"]
    expected = _independent_bias_degps(biased_log)
    assert abs(expected) > 0.2  # the draw is not near zero, so the check means something
    assert scores["true_degps"] == pytest.approx(expected, abs=1e-3)
    estimated = metrics["odometry"].get("gyro_bias_degps")
    assert scores["estimated_degps"] == estimated
    if source == "radar":  # the heading filter estimates a bias; dead reckoning does not
        assert estimated is not None
        assert scores["residual_degps"] == pytest.approx(scores["true_degps"] - estimated)
    else:
        assert estimated is None and scores["residual_degps"] == scores["true_degps"]
