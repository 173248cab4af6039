"""Trajectory metrics: planar Umeyama, ATE/RPE definitions, TUM/KITTI files (read back by evo)."""

import numpy as np
import pytest

from smokyslam.errors import EstimationError, TrajectoryFileError
from smokyslam.evaluation.trajectory_io import read_tum, write_kitti, write_tum
from smokyslam.evaluation.trajectory_metrics import (
    Similarity2D,
    evaluate_trajectory,
    path_length_m,
    rpe_translation_rmse,
    umeyama_2d,
)
from smokyslam.geometry import se2_compose, se2_matrix


def _walk(n: int = 200, seed: int = 0) -> np.ndarray:
    """(n, 3) a wandering planar path with 0.1 m steps."""
    rng = np.random.default_rng(seed)
    yaw = np.cumsum(rng.normal(0.0, 0.1, n))
    xy = np.cumsum(0.1 * np.stack([np.cos(yaw), np.sin(yaw)], axis=1), axis=0)
    return np.column_stack([xy, np.angle(np.exp(1j * yaw))])


def test_umeyama_recovers_a_known_sim2_exactly():
    source = _walk()[:, :2]
    truth = Similarity2D(yaw_rad=2.5, translation_m=np.array([3.0, -7.0]), scale=1.7)
    target = truth.apply(np.column_stack([source, np.zeros(len(source))]))[:, :2]
    found = umeyama_2d(source, target, with_scale=True)
    assert found.yaw_rad == pytest.approx(2.5, abs=1e-12)
    assert found.scale == pytest.approx(1.7, abs=1e-12)
    np.testing.assert_allclose(found.translation_m, [3.0, -7.0], atol=1e-10)
    rigid = umeyama_2d(source, target, with_scale=False)
    assert rigid.scale == 1.0
    assert rigid.yaw_rad == pytest.approx(2.5, abs=1e-12)


def test_umeyama_never_returns_a_reflection():
    # A mirrored path: the best proper rotation is not the mirror, and scale stays positive.
    source = _walk()[:, :2]
    mirrored = source * np.array([1.0, -1.0])
    found = umeyama_2d(source, mirrored, with_scale=True)
    assert found.scale > 0
    R = se2_matrix(0.0, 0.0, found.yaw_rad)[:2, :2]
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_umeyama_rejects_too_few_points():
    with pytest.raises(EstimationError):
        umeyama_2d(np.zeros((1, 2)), np.zeros((1, 2)), with_scale=False)


def test_ate_is_zero_after_alignment_and_sim2_undoes_scale():
    gt = _walk()
    stamps = np.arange(len(gt)) * 0.1
    moved = se2_compose(np.array([5.0, 2.0, 1.0]), gt)
    metrics = evaluate_trajectory(stamps, moved, stamps, gt, "se2")
    assert metrics.ate_rmse_m < 1e-9
    assert metrics.rpe_trans_rmse_m < 1e-9
    assert metrics.path_length_m == pytest.approx(path_length_m(gt))
    assert metrics.frames == len(gt)
    scaled = moved.copy()
    scaled[:, :2] *= 0.5
    assert evaluate_trajectory(stamps, scaled, stamps, gt, "se2").ate_rmse_m > 0.1
    sim2 = evaluate_trajectory(stamps, scaled, stamps, gt, "sim2")
    assert sim2.ate_rmse_m < 1e-9
    assert sim2.scale == pytest.approx(2.0)
    assert sim2.ate_alignment == "sim2"


def test_ate_and_drift_of_a_known_offset():
    gt = _walk()
    stamps = np.arange(len(gt)) * 0.1
    est = gt.copy()
    est[::2, 0] += 0.1  # alternate +0.1 / 0 in x: alignment removes the mean, 0.05 m remains
    metrics = evaluate_trajectory(stamps, est, stamps, gt, "se2", lost=np.arange(len(gt)) < 3)
    assert metrics.ate_rmse_m == pytest.approx(0.05, rel=0.02)
    assert metrics.drift_pct == pytest.approx(100 * metrics.ate_rmse_m / path_length_m(gt))
    assert metrics.lost_frames == 3


def test_rpe_per_metre_of_a_scale_error():
    # Travelling 10% too far: every 1 m of ground truth becomes about 1.1 m.
    gt = np.column_stack([np.arange(50) * 0.1, np.zeros(50), np.zeros(50)])
    est = gt * np.array([1.1, 1.0, 1.0])
    assert rpe_translation_rmse(est, gt) == pytest.approx(0.1, rel=0.02)
    assert np.isnan(rpe_translation_rmse(est[:5], gt[:5]))


def test_association_interpolates_ground_truth_and_drops_frames_outside_it():
    gt = np.column_stack([np.arange(11.0), np.zeros(11), np.zeros(11)])  # 1 m/s along x
    gt_stamps = np.arange(11.0)
    stamps = np.array([-1.0, 0.5, 2.25, 9.75, 12.0])
    est = np.column_stack([stamps, np.zeros(5), np.zeros(5)])
    metrics = evaluate_trajectory(stamps, est, gt_stamps, gt)
    assert metrics.ate_rmse_m < 1e-9  # the two frames outside the span are left out
    assert metrics.frames == 5


def test_tum_round_trip_and_evo_reads_it(tmp_path):
    from evo.tools import file_interface

    poses = _walk(50)
    stamps = 100.0 + np.arange(50) * 0.1
    path = write_tum(tmp_path / "t.tum", stamps, poses)
    stamps_back, poses_back = read_tum(path)
    np.testing.assert_allclose(stamps_back, stamps, atol=1e-9)
    np.testing.assert_allclose(poses_back, poses, atol=1e-8)
    traj = file_interface.read_tum_trajectory_file(str(path))
    np.testing.assert_allclose(traj.positions_xyz[:, :2], poses[:, :2], atol=1e-8)
    np.testing.assert_allclose(traj.positions_xyz[:, 2], 0.0)
    # evo stores wxyz: yaw from its quaternions must match.
    q = traj.orientations_quat_wxyz
    yaw = np.arctan2(
        2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]), 1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2)
    )
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - poses[:, 2]))), 0.0, atol=1e-8)


def test_kitti_rows_are_the_3x4_matrices(tmp_path):
    from evo.tools import file_interface

    poses = _walk(20)
    path = write_kitti(tmp_path / "trajectory_kitti.txt", poses)
    rows = np.loadtxt(path)
    assert rows.shape == (20, 12)
    np.testing.assert_allclose(rows[7].reshape(3, 4)[:2, [0, 1, 3]], se2_matrix(*poses[7])[:2])
    traj = file_interface.read_kitti_poses_file(str(path))
    np.testing.assert_allclose(traj.positions_xyz[:, :2], poses[:, :2], atol=1e-8)


def test_malformed_tum_files_are_reported(tmp_path):
    with pytest.raises(TrajectoryFileError, match="no such"):
        read_tum(tmp_path / "missing.tum")
    bad = tmp_path / "bad.tum"
    bad.write_text("0 1 2 3\n")
    with pytest.raises(TrajectoryFileError, match="8 columns"):
        read_tum(bad)
    worse = tmp_path / "worse.tum"
    worse.write_text("0 1 2 3 4 5 6 seven\n")
    with pytest.raises(TrajectoryFileError, match="not a TUM"):
        read_tum(worse)
    with pytest.raises(TrajectoryFileError, match="stamps"):
        write_tum(tmp_path / "x.tum", np.zeros(3), np.zeros((2, 3)))
