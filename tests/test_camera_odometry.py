"""Camera odometry end to end on rendered walks with known truth (Sim(2)-aligned: up to scale)."""

import numpy as np
import pytest
from camera_scenes import RATE_HZ, ellipse_walk, pillar_room

from smokyslam.config import CameraModelConfig, CameraOdometryConfig
from smokyslam.frontends.camera import CameraOdometry, TrackingStatus
from smokyslam.frontends.camera.initializer import start_two_view
from smokyslam.frontends.camera.pose import camera_from_planar, planar_from_camera
from smokyslam.frontends.camera.tracker import LKTracker
from smokyslam.geometry import se2_compose, wrap_angle
from smokyslam.sim.camera import CameraRenderer
from smokyslam.types import CameraFrame


def salt_and_pepper(image: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    noisy = image.copy()
    n = round(fraction * image.size)
    pixels = rng.choice(image.size, n, replace=False)
    noisy.reshape(-1)[pixels] = rng.integers(0, 2, n, dtype=np.uint8) * 255
    return noisy


def sim2_ate(estimate_xy: np.ndarray, truth_xy: np.ndarray) -> float:
    """RMS position error after the best similarity alignment (Umeyama) of estimate to truth."""
    mu_e, mu_t = estimate_xy.mean(axis=0), truth_xy.mean(axis=0)
    e, t = estimate_xy - mu_e, truth_xy - mu_t
    U, S, Vt = np.linalg.svd(t.T @ e / len(e))
    D = np.diag([1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    scale = np.trace(np.diag(S) @ D) / np.mean(np.sum(e**2, axis=1))
    aligned = scale * e @ R.T + mu_t
    return float(np.sqrt(np.mean(np.sum((aligned - truth_xy) ** 2, axis=1))))


@pytest.fixture(scope="module")
def renderer() -> CameraRenderer:
    return CameraRenderer(pillar_room(), CameraModelConfig(), 1.2, seed=0)


@pytest.fixture(scope="module")
def walk():
    """The walk's frames, from a renderer of their own (its pixel noise has a state)."""
    renderer = CameraRenderer(pillar_room(), CameraModelConfig(), 1.2, seed=0)
    poses = ellipse_walk(180)
    images = [renderer.render(p)[0] for p in poses]
    return poses, images


def run(renderer, images, config=None):
    odometry = CameraOdometry(renderer.intrinsics, config or CameraOdometryConfig(), None)
    return [
        odometry.track(CameraFrame(i / RATE_HZ, image, renderer.intrinsics))
        for i, image in enumerate(images)
    ], odometry


def path_length(poses: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1)))


@pytest.mark.parametrize(
    ("start", "step"),
    [
        ([2.0, 1.2, 0.5], [0.25, 0.0, np.radians(4.0)]),
        ([6.5, 4.5, 2.8], [0.2, 0.15, np.radians(-6.0)]),
        ([1.5, 2.5, -0.3], [0.1, -0.2, np.radians(3.0)]),
    ],
)
def test_two_rendered_views_give_rotation_and_translation_direction(renderer, start, step):
    config = CameraOdometryConfig(init_parallax_deg=0.5)
    a, b = np.array(start), se2_compose(np.array(start), np.array(step))
    image_a, image_b = renderer.render(a)[0], renderer.render(b)[0]
    tracker = LKTracker(config)
    uv_a = tracker.detect(image_a, np.zeros((0, 2)), 300)
    uv_b, ok = tracker.track(image_a, image_b, uv_a)
    K = renderer.intrinsics.camera_matrix
    start_view = start_two_view(camera_from_planar(np.zeros(3)), uv_a[ok], uv_b[ok], K, 1.0, config)
    assert start_view is not None
    relative = planar_from_camera(start_view.T_world_camera)
    assert abs(np.degrees(wrap_angle(relative[2] - step[2]))) < 0.5
    direction_error = wrap_angle(
        np.arctan2(relative[1], relative[0]) - np.arctan2(step[1], step[0])
    )
    assert abs(np.degrees(direction_error)) < 5.0
    assert np.hypot(*relative[:2]) == pytest.approx(1.0, abs=0.01)  # the scale is ours to pick


def test_walk_is_tracked_up_to_scale(renderer, walk):
    poses, images = walk
    results, odometry = run(renderer, images)
    lost = np.array([r.lost for r in results])
    assert lost.mean() <= 0.10
    assert results[-1].reinitializations == 0
    estimate = np.array([r.pose_world_camera for r in results])
    ate = sim2_ate(estimate[~lost, :2], poses[~lost, :2])
    assert ate < 0.02 * path_length(poses)  # measured about 1 % of the 5 m walk
    heading_change = estimate[-1, 2] - estimate[~lost][0, 2]
    truth_change = poses[-1, 2] - poses[~lost][0, 2]
    assert abs(np.degrees(wrap_angle(heading_change - truth_change))) < 3.0
    tracked = [r for r in results if not r.lost]
    for r in tracked:
        assert np.all(np.linalg.eigvalsh(r.covariance) > 0)
        assert r.health.inliers >= CameraOdometryConfig().min_inliers
        assert r.landmarks_world.shape == (r.health.inliers, 3)
    keyframes = [r for r in results if r.is_keyframe]
    assert 5 < len(keyframes) < 100
    # relative_pose chains from the keyframe it names; at a keyframe, that previous keyframe
    # has just been moved by the window adjustment
    keyframe_pose = {r.keyframe_id + 1: r.pose_world_camera for r in keyframes}
    step = np.median(np.linalg.norm(np.diff(estimate[~lost, :2], axis=0), axis=1))
    exact, adjusted = [], []
    for r in tracked:
        if r.keyframe_id in keyframe_pose:
            gap = se2_compose(keyframe_pose[r.keyframe_id], r.relative_pose) - r.pose_world_camera
            (adjusted if r.is_keyframe else exact).append(np.abs(gap).max())
    assert len(exact) > 100 and max(exact) < 1e-9
    assert np.median(adjusted) < step and max(adjusted) < 10 * step
    landmarks = odometry.landmarks_world()
    assert landmarks.shape[1] == 3 and len(landmarks) > 300
    assert np.isfinite(landmarks).all()
    assert results[0].metres_per_unit is None  # no camera height given: up to scale


def test_walk_survives_salt_and_pepper_noise(renderer, walk):
    poses, images = walk
    rng = np.random.default_rng(7)
    noisy = [salt_and_pepper(image, 0.2, rng) for image in images]
    results, _ = run(renderer, noisy)
    lost = np.array([r.lost for r in results])
    assert lost.mean() <= 0.10
    estimate = np.array([r.pose_world_camera for r in results])
    assert sim2_ate(estimate[~lost, :2], poses[~lost, :2]) < 0.03 * path_length(poses)
    assert all(r.quality.impulse_fraction == pytest.approx(0.2, abs=0.02) for r in results)


def test_black_stream_gives_lost_frames(renderer):
    mono = np.zeros((240, 320), np.uint8)
    colour = np.zeros((240, 320, 3), np.uint8)
    black = [mono] * 10 + [colour] * 5 + [np.zeros((240, 640), np.uint8)[:, ::2]] * 5
    results, odometry = run(renderer, black)
    assert all(r.lost for r in results)
    assert all(r.status is not TrackingStatus.TRACKING for r in results)
    assert all(np.isfinite(r.pose_world_camera).all() for r in results)
    assert all(np.diag(r.covariance).min() > 1e5 for r in results)
    assert len(odometry.landmarks_world()) == 0


def test_blackout_is_lost_then_a_new_map_starts(renderer, walk):
    poses, images = walk
    blackout = slice(60, 75)
    stream = [
        np.zeros_like(im) if blackout.start <= i < blackout.stop else im
        for i, im in enumerate(images)
    ]
    results, _ = run(renderer, stream)
    status = [r.status for r in results]
    assert all(s is TrackingStatus.LOST for s in status[blackout.start + 1 : blackout.stop])
    assert sum(r.reinitialized for r in results) == 1
    assert results[-1].reinitializations == 1
    restart = next(i for i, r in enumerate(results) if r.reinitialized)
    assert blackout.stop <= restart < blackout.stop + 20
    assert all(s is TrackingStatus.TRACKING for s in status[restart:])
    # Across the gap the new map is placed by the speed before the loss: positions keep going.
    estimate = np.array([r.pose_world_camera for r in results])
    after = slice(restart, len(results))
    assert sim2_ate(estimate[after, :2], poses[after, :2]) < 0.03 * path_length(poses[after])
