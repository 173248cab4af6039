"""Camera odometry geometry on synthetic scenes with exact truth: LK, triangulation, PnP, BA."""

import cv2
import numpy as np
import pytest

from smokyslam.config import CameraModelConfig, CameraOdometryConfig
from smokyslam.frontends.camera.bundle import WindowProblem, adjust
from smokyslam.frontends.camera.landmarks import (
    EPIPOLE_CLEARANCE_DEG,
    RAY_ANGLE_FLOOR_DEG,
    project,
    triangulate,
)
from smokyslam.frontends.camera.pose import (
    camera_from_planar,
    planar_from_camera,
    project_planar,
    solve_pnp,
)
from smokyslam.frontends.camera.tracker import LKTracker
from smokyslam.geometry import R_BODY_OPTICAL, se2_compose
from smokyslam.sim.camera import CameraRenderer
from smokyslam.sim.world import box_world

K = np.array([[220.0, 0.0, 159.5], [0.0, 220.0, 119.5], [0.0, 0.0, 1.0]])


def scene_points(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) world points 2-7 m ahead of the origin (body axes), inside a 70 deg cone."""
    x = rng.uniform(2.0, 7.0, n)
    return np.column_stack([x, rng.uniform(-0.6, 0.6, n) * x, rng.uniform(-1.0, 1.2, n)])


def test_planar_pose_conversions_round_trip_and_agree():
    pose = np.array([1.5, -0.7, 2.9])
    T = camera_from_planar(pose)
    assert np.allclose(planar_from_camera(T), pose)
    assert np.allclose(T[:3, :3], camera_from_planar(np.array([0, 0, 2.9]))[:3, :3])
    assert np.allclose(camera_from_planar(np.zeros(3))[:3, :3], R_BODY_OPTICAL)
    points = scene_points(50, np.random.default_rng(0)) + np.array([1.5, -0.7, 0.0])
    uv_a, z_a = project(camera_from_planar(np.array([1.5, -0.7, 0.0])), points, K)
    uv_b, z_b = project_planar(np.array([1.5, -0.7, 0.0]), points, K)
    assert np.allclose(uv_a, uv_b) and np.allclose(z_a, z_b)
    # a point straight ahead on the axis lands on the principal point
    uv, z = project_planar(np.zeros(3), np.array([[4.0, 0.0, 0.0]]), K)
    assert np.allclose(uv, [[159.5, 119.5]]) and z[0] == pytest.approx(4.0)


def test_triangulation_recovers_points_and_rejects_far_and_along_the_path():
    rng = np.random.default_rng(1)
    points = scene_points(100, rng)
    points[:5] = [[500.0, 0.0, 0.0]] * 5  # too far for a 0.3 m baseline
    T_a = camera_from_planar(np.zeros(3))
    T_b = camera_from_planar(np.array([0.25, 0.15, 0.05]))
    points[5:8] = T_b[:3, 3] + np.array([0.25, 0.15, 0.0]) * [[8.0], [12.0], [16.0]]  # on path
    uv_a, _ = project(T_a, points, K)
    uv_b, _ = project(T_b, points, K)
    found, angles, ok = triangulate(T_a, T_b, uv_a, uv_b, K, max_error_px=1.0)
    assert not ok[:8].any()
    travel = (T_b[:3, 3] - T_a[:3, 3]) / np.linalg.norm(T_b[:3, 3] - T_a[:3, 3])
    seen = (points - T_b[:3, 3]) / np.linalg.norm(points - T_b[:3, 3], axis=1, keepdims=True)
    off_path = np.degrees(np.arccos(np.clip(np.abs(seen @ travel), 0, 1))) >= EPIPOLE_CLEARANCE_DEG
    assert np.array_equal(ok[8:], off_path[8:] & (angles[8:] >= RAY_ANGLE_FLOOR_DEG))
    assert ok.mean() > 0.85
    assert np.abs(found[ok] - points[ok]).max() < 1e-6
    _, _, ok_swapped = triangulate(T_a, T_b, uv_b, uv_a, K, max_error_px=1.0)
    assert ok_swapped.mean() < 0.2  # swapped views put most points behind a camera


def test_pnp_finds_pose_and_outliers_with_a_covariance_that_shrinks_with_points():
    rng = np.random.default_rng(2)
    truth = np.array([0.4, 0.1, 0.08])
    points = scene_points(200, rng)
    uv, _ = project_planar(truth, points, K)
    uv += rng.normal(0.0, 0.3, uv.shape)
    outliers = rng.random(len(points)) < 0.2
    uv[outliers] = rng.uniform([0, 0], [320, 240], (outliers.sum(), 2))
    guess = camera_from_planar(np.array([0.3, 0.0, 0.0]))
    estimate = solve_pnp(points, uv, K, guess, threshold_px=2.0, planar=True)
    assert estimate is not None
    pose = planar_from_camera(estimate.T_world_camera)
    assert np.abs(pose[:2] - truth[:2]).max() < 0.01
    assert abs(np.degrees(pose[2] - truth[2])) < 0.1
    assert np.mean(estimate.inliers == ~outliers) > 0.97
    assert 0.2 < estimate.residual_rms_px < 0.6
    cov = estimate.covariance
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    assert not np.allclose(cov, np.diag(np.diag(cov)))  # x, y and yaw are correlated
    few = solve_pnp(points[:50], uv[:50], K, guess, threshold_px=2.0, planar=True)
    assert np.trace(few.covariance) > 2.0 * np.trace(cov)
    six_dof = solve_pnp(points, uv, K, guess, threshold_px=2.0, planar=False)
    assert np.abs(planar_from_camera(six_dof.T_world_camera)[:2] - truth[:2]).max() < 0.03


def test_pnp_gives_up_on_garbage():
    rng = np.random.default_rng(3)
    points = scene_points(40, rng)
    uv = rng.uniform([0, 0], [320, 240], (40, 2))
    estimate = solve_pnp(points, uv, K, np.eye(4), threshold_px=1.0, planar=True)
    assert estimate is None or estimate.inliers.sum() < 12


def _window(rng, n_keyframes=6, n_points=200):
    """Keyframes walking forward with turns, every point seen from every keyframe."""
    steps = np.array([[0.12, 0.02, 0.04]] * (n_keyframes - 1))
    poses = [np.zeros(3)]
    for step in steps:
        poses.append(se2_compose(poses[-1], step))
    poses = np.array(poses)
    points = scene_points(n_points, rng) + np.array([1.0, 0.0, 0.0])
    uv = np.stack([project_planar(p, points, K)[0] for p in poses])
    return poses, points, uv


def test_bundle_adjustment_restores_perturbed_poses_and_depths():
    rng = np.random.default_rng(4)
    poses, points, uv = _window(rng)
    n_kf, n_pt = uv.shape[:2]
    _, depth = project_planar(poses[0], points, K)
    ray = np.column_stack([uv[0], np.ones(n_pt)]) @ np.linalg.inv(K).T
    fixed = np.arange(n_kf) < 2
    start = poses.copy()
    start[~fixed] += rng.normal(0.0, [0.02, 0.02, 0.01], (n_kf - 2, 3))
    problem = WindowProblem(
        poses=start,
        fixed=fixed,
        anchor=np.zeros(n_pt, dtype=int),
        anchor_ray=ray,
        inverse_depth=(1.0 / depth) * rng.uniform(0.8, 1.25, n_pt),
        obs_landmark=np.tile(np.arange(n_pt), n_kf - 1),
        obs_keyframe=np.repeat(np.arange(1, n_kf), n_pt),
        obs_uv_px=uv[1:].reshape(-1, 2),
    )
    errors = adjust(problem, K, iterations=10)
    assert np.abs(problem.poses - poses).max() < 1e-4
    assert np.allclose(problem.poses[fixed], poses[fixed])
    assert np.abs(problem.inverse_depth * depth - 1.0).max() < 1e-3
    assert errors.max() < 1e-2


def test_lk_tracks_a_shifted_rendered_image_and_drops_occluded_points():
    renderer = CameraRenderer(box_world(), CameraModelConfig(), 1.2, seed=1)
    image, _ = renderer.render(np.array([2.0, 2.0, 0.4]))
    tracker = LKTracker(CameraOdometryConfig())
    corners = tracker.detect(image, np.zeros((0, 2)), 200)
    assert len(corners) > 150
    shift = np.array([3.3, -1.7])
    moved = cv2.warpAffine(image, np.array([[1, 0, shift[0]], [0, 1, shift[1]]]), (320, 240))
    occluded = (corners[:, 0] > 200) & (corners[:, 1] > 120)
    near_patch = (corners[:, 0] > 185) & (corners[:, 1] > 105)  # LK windows reach in
    noise = np.random.default_rng(5).integers(0, 256, (120, 120), dtype=np.uint8)
    moved[120:, 200:] = noise
    uv, ok = tracker.track(image, moved, corners)
    inside = (corners + shift)[:, 0] < 316
    good = ok & ~occluded
    assert np.median(np.linalg.norm(uv[good] - (corners[good] + shift), axis=1)) < 0.05
    assert ok[~near_patch & inside].mean() > 0.95
    assert ok[occluded].mean() < 0.2
    again = tracker.detect(image, corners, 100)  # new corners keep away from existing ones
    nearest = np.linalg.norm(again[:, None] - corners[None], axis=2).min(axis=1)
    assert np.all(nearest >= CameraOdometryConfig().min_distance_px - 1.0)
