"""Per-step precision of the radar and camera steps against the true motion."""

import numpy as np
import pytest

from smokyslam.evaluation.step_errors import step_errors
from smokyslam.geometry import se2_between
from smokyslam.types import GroundTruthTrajectory, StepPairs


def circle_walk() -> GroundTruthTrajectory:
    """10 s on a 5 m circle at 1 m/s, 100 Hz truth."""
    stamps = np.linspace(0.0, 10.0, 1001)
    angle = stamps / 5.0
    poses = np.column_stack([5 * np.sin(angle), 5 * (1 - np.cos(angle)), angle])
    return GroundTruthTrajectory(stamps, poses)


def test_errors_are_the_offsets_put_into_the_steps():
    truth = circle_walk()
    stamps = np.column_stack([np.arange(0.0, 9.0, 0.5), np.arange(0.5, 9.5, 0.5)])
    index = (stamps * 100).round().astype(int)
    poses = truth.poses_world_base
    true_step = se2_between(poses[index[:, 0]], poses[index[:, 1]])
    radar = true_step + np.array([0.01, 0.0, 0.0])  # 1 cm too long along x, which is forward
    camera = true_step * np.array([1.1, 1.1, 1.0]) + np.array([0.0, 0.0, np.radians(0.5)])
    out = step_errors(StepPairs(stamps, radar, camera), truth)
    assert out["pairs"] == len(stamps)
    assert out["radar"]["translation_rms_m"] == pytest.approx(0.01, rel=1e-6)
    assert out["radar"]["yaw_rms_deg"] == pytest.approx(0.0, abs=1e-9)
    assert out["radar"]["step_length_rms_pct"] == pytest.approx(2.0, rel=0.01)  # 1 cm of 50
    assert out["camera"]["step_length_rms_pct"] == pytest.approx(10.0, rel=1e-6)
    assert out["camera"]["yaw_rms_deg"] == pytest.approx(0.5, rel=1e-9)


def test_pairs_outside_the_truth_and_missing_inputs_give_nothing():
    truth = circle_walk()
    outside = StepPairs(np.array([[20.0, 20.5]]), np.zeros((1, 3)), np.zeros((1, 3)))
    assert step_errors(outside, truth) is None
    assert step_errors(None, truth) is None
    assert step_errors(outside, None) is None
