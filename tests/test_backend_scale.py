"""Metric scale of camera odometry against radar translations."""

import numpy as np
import pytest

from smokyslam.backends.scale import (
    ScaleEstimate,
    ScaleEstimator,
    SharedScale,
    get_scale_estimator,
    metric_relative_pose,
)
from smokyslam.config import ScaleConfig


def motions(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 2) keyframe translations of a walk: 0.2-0.4 m, mostly forward."""
    length = rng.uniform(0.2, 0.4, count)
    heading = rng.normal(0.0, 0.3, count)
    return np.stack([length * np.cos(heading), length * np.sin(heading)], axis=1)


def feed(estimator: ScaleEstimator, metric: np.ndarray, scale: float, rng) -> ScaleEstimate:
    """Camera sees ``metric / scale`` with 3% noise; radar sees ``metric`` with 2 cm noise."""
    estimate = None
    for t in metric:
        camera = t / scale * (1.0 + rng.normal(0.0, 0.03))
        radar = t + rng.normal(0.0, 0.02, 2)
        estimate = estimator.update(camera, radar)
    return estimate


def test_scaled_camera_translations_come_out_metric():
    rng = np.random.default_rng(0)
    true_scale = 1.0 / 0.37  # the camera reports 0.37 units per metre
    estimator = get_scale_estimator(ScaleConfig(window=30, min_pairs=5))
    estimate = feed(estimator, motions(rng, 30), true_scale, rng)
    # Over 200 seeds: mean error 0.3%, std 1.5%, worst 3.5%; the reported sigma was 1.3%.
    assert estimate.scale == pytest.approx(true_scale, rel=0.04)
    assert 0.005 < estimate.relative_sigma < 0.03
    assert abs(estimate.scale / true_scale - 1.0) < 3.0 * estimate.relative_sigma
    camera_delta = np.array([0.37 * 0.3, 0.0, 0.1])
    metric, covariance = metric_relative_pose(camera_delta, np.diag([1e-4, 1e-4, 1e-4]), estimate)
    assert metric[0] == pytest.approx(0.3, rel=0.04)
    assert metric[2] == 0.1
    # Translation variance scaled by s^2 plus the scale's own spread along the motion.
    assert covariance[0, 0] > estimate.scale**2 * 1e-4
    assert covariance[2, 2] == pytest.approx(1e-4)


def test_a_noisy_camera_does_not_shrink_the_scale():
    """Camera step lengths 15 % off and radar 2 % (as measured per keyframe step): a fit of
    the radar lengths on the camera's came out 1.9 % low on average over these windows; the
    ratio of sums is within 0.5 %."""
    rng = np.random.default_rng(3)
    errors = []
    for _ in range(200):
        estimator = get_scale_estimator(ScaleConfig(window=20, min_pairs=5, inlier_tolerance=1.0))
        estimate = None
        for t in motions(rng, 20):
            camera = t / 2.0 * (1.0 + rng.normal(0.0, 0.15))
            estimate = estimator.update(camera, t * (1.0 + rng.normal(0.0, 0.02)))
        errors.append(estimate.scale / 2.0 - 1.0)
    assert abs(np.mean(errors)) < 0.005


def test_outlier_pairs_do_not_bias_the_scale():
    rng = np.random.default_rng(1)
    estimator = get_scale_estimator(ScaleConfig(window=30, min_pairs=5))
    metric = motions(rng, 30)
    estimate = None
    for k, t in enumerate(metric):
        camera = t / 2.0 * (1.0 + rng.normal(0.0, 0.03))
        if k % 7 == 3:  # a bad camera pair: wildly wrong length
            camera = camera * rng.choice([0.2, 5.0])
        estimate = estimator.update(camera, t)
    assert estimate.scale == pytest.approx(2.0, rel=0.03)
    assert estimate.pairs <= 26


def test_reset_starts_a_fresh_scale():
    rng = np.random.default_rng(2)
    estimator = get_scale_estimator(ScaleConfig(window=20, min_pairs=5))
    feed(estimator, motions(rng, 20), 0.5, rng)
    estimator.reset()
    assert estimator.estimate() is None
    # The camera re-enters with a different scale; without reset the window would mix both.
    estimate = feed(estimator, motions(rng, 8), 3.0, rng)
    assert estimate.scale == pytest.approx(3.0, rel=0.04)


def test_short_motions_carry_no_scale():
    estimator = get_scale_estimator(ScaleConfig(min_pairs=2, min_translation_m=0.05))
    for _ in range(5):
        assert estimator.update(np.array([0.01, 0.0]), np.array([0.01, 0.0])) is None


def test_a_shared_scale_reads_its_source_and_never_feeds_it():
    rng = np.random.default_rng(3)
    source = get_scale_estimator(ScaleConfig())
    shared = SharedScale(source)
    assert shared.update(np.array([0.4, 0.0]), np.array([0.1, 0.0])) is None  # none yet
    truth = feed(source, motions(rng, 12), 0.25, rng)
    assert truth is not None and truth.scale == pytest.approx(0.25, rel=0.06)
    # A short step of another ratio changes nothing: the estimate is the source's.
    for _ in range(20):
        estimate = shared.update(np.array([0.1, 0.0]), np.array([0.09, 0.0]))
    assert estimate == truth == source.estimate()
    shared.reset()
    assert source.estimate() == truth
