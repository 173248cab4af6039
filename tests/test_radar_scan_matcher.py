"""Scan matching recovers known SE(2) motions on simulated radar frames in a room."""

import numpy as np
import pytest
from radar_scenes import dense_map_points, radar_points

from smokyslam.config import RadarOdometryConfig
from smokyslam.frontends.radar.doppler import EgoVelocity
from smokyslam.frontends.radar.kiss_matcher import KissBatchMatcher
from smokyslam.frontends.radar.motion_prior import MotionPrior
from smokyslam.frontends.radar.scan_matcher import JointIcpMatcher
from smokyslam.geometry import se2_between, se2_compose, wrap_angle

START = np.array([4.0, 4.0, 0.3])
MOTION = np.array([0.35, 0.12, np.radians(6.0)])
PRIOR_ERROR = np.array([0.08, -0.06, np.radians(2.5)])
PRIOR_SIGMA = np.array([0.08, 0.08, np.radians(3.0)])
# The noise of radar_points, and no extra sigma for the viewpoint change: the map is exact.
EXACT_MAP = RadarOdometryConfig(
    range_sigma_m=0.02, azimuth_sigma_deg=0.5, point_sigma_m=0.02, viewpoint_sigma_ratio=0.0
)


def _prior(delta, sigma=PRIOR_SIGMA):
    doppler = EgoVelocity(np.zeros(2), np.eye(2), 0, np.zeros(0, dtype=bool))
    return MotionPrior(np.asarray(delta, float), np.diag(np.asarray(sigma) ** 2), doppler)


def _error(a, b):
    e = se2_between(a, b)
    return np.hypot(e[0], e[1]), abs(float(wrap_angle(e[2])))


def _matcher_with_map(config=None):
    matcher = JointIcpMatcher(config or RadarOdometryConfig())
    matcher.map.insert(dense_map_points(START), START[:2])
    return matcher


@pytest.mark.parametrize("seed", range(3))
def test_joint_icp_recovers_a_known_motion_from_a_wrong_prior(seed):
    rng = np.random.default_rng(seed)
    matcher = _matcher_with_map(EXACT_MAP)
    truth = se2_compose(START, MOTION)
    points, _ = radar_points(truth, rng)
    result = matcher.register_batch([points], START, [_prior(MOTION + PRIOR_ERROR)])[0]
    translation, yaw = _error(truth, result.pose_world_sensor)
    assert translation < 0.03
    assert yaw < np.radians(0.2)
    assert result.matched and result.inliers >= 0.8 * len(points)
    assert result.fitness < 0.05
    np.testing.assert_allclose(result.delta, se2_between(START, result.pose_world_sensor))
    # The registered step is better known than the prior, and the covariance says so.
    sigma = np.sqrt(np.diag(result.covariance))
    assert np.all(sigma < PRIOR_SIGMA)
    assert np.all(np.linalg.eigvalsh(result.covariance) > 0)


def test_default_settings_improve_a_wrong_prior_threefold():
    matcher = _matcher_with_map()
    truth = se2_compose(START, MOTION)
    points, _ = radar_points(truth, np.random.default_rng(11))
    result = matcher.register_batch([points], START, [_prior(MOTION + PRIOR_ERROR)])[0]
    translation, yaw = _error(truth, result.pose_world_sensor)
    assert translation < np.hypot(*PRIOR_ERROR[:2]) / 3
    assert yaw < PRIOR_ERROR[2] / 3


def test_a_batch_of_frames_is_solved_jointly():
    config = EXACT_MAP.model_copy(update={"joint_batch_frames": 3})
    matcher = _matcher_with_map(config)
    rng = np.random.default_rng(7)
    truths = [START]
    for _ in range(3):
        truths.append(se2_compose(truths[-1], MOTION))
    frames = [radar_points(pose, rng)[0] for pose in truths[1:]]
    priors = [_prior(MOTION + PRIOR_ERROR) for _ in frames]
    results = matcher.register_batch(frames, START, priors)
    for truth, result in zip(truths[1:], results, strict=True):
        translation, yaw = _error(truth, result.pose_world_sensor)
        assert translation < 0.03
        assert yaw < np.radians(0.4)


def test_without_a_map_or_correspondences_the_prior_is_kept():
    matcher = JointIcpMatcher(RadarOdometryConfig())
    points, _ = radar_points(START, np.random.default_rng(0))
    first = matcher.register_batch([points], START, [_prior(MOTION)])[0]
    np.testing.assert_allclose(first.pose_world_sensor, se2_compose(START, MOTION))
    assert first.matched  # the first frame defines the map: nothing to match yet
    far = points + 100.0
    lost = matcher.register_batch([far], first.pose_world_sensor, [_prior(MOTION)])[0]
    assert not lost.matched and lost.inliers == 0
    np.testing.assert_allclose(lost.delta, MOTION, atol=1e-9)


def test_kiss_icp_batches_recover_a_known_motion():
    config = RadarOdometryConfig(matcher="kiss-icp", kiss_batch_frames=4)
    matcher = KissBatchMatcher(config)
    rng = np.random.default_rng(3)
    truths = [START]
    for _ in range(8):
        truths.append(se2_compose(truths[-1], MOTION))
    # The first batch builds the map (exact priors); the second starts from wrong priors.
    first = [radar_points(pose, rng, n=80)[0] for pose in truths[1:5]]
    anchor = matcher.register_batch(first, START, [_prior(MOTION)] * 4)[-1].pose_world_sensor
    second = [radar_points(pose, rng)[0] for pose in truths[5:9]]
    # The batch is stitched rigidly by the prior: only its offset from the map is wrong.
    priors = [_prior(MOTION + PRIOR_ERROR)] + [_prior(MOTION)] * 3
    results = matcher.register_batch(second, anchor, priors)
    translation, yaw = _error(truths[-1], results[-1].pose_world_sensor)
    assert translation < 0.03
    assert yaw < np.radians(0.5)
    assert results[-1].matched and results[-1].inliers > 10
    assert np.all(np.linalg.eigvalsh(results[-1].covariance) > 0)
    # Frames inside a batch keep the prior's shape: the batch moved as one rigid cloud.
    np.testing.assert_allclose(results[2].delta, MOTION, atol=1e-9)
