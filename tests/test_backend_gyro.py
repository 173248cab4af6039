"""Gyro factors: the raw turn between two stamps, and a graph that finds the gyro's bias."""

import numpy as np
import pytest

from smokyslam.backends.gyro import MAX_GAP_S, GyroTurns
from smokyslam.backends.pose_graph import get_pose_graph
from smokyslam.backends.slam import Primary, SlamBackend
from smokyslam.config import BackendConfig, load_config
from smokyslam.geometry import se2_between, se2_compose, se2_exp, wrap_angle
from smokyslam.types import ImuSample, Odometry, OdometryHealth

SCAN = np.array([[2.0, 0.0], [2.0, 1.0], [3.0, -1.0]])
"""A radar frame's points (base_link), for the keyframer's submaps."""


def samples(stamps_s: np.ndarray, rate_radps) -> list[ImuSample]:
    rates = np.broadcast_to(rate_radps, stamps_s.shape)
    return [
        ImuSample(stamp_s=float(t), gyro_radps=np.array([0.0, 0.0, w]), accel_mps2=np.zeros(3))
        for t, w in zip(stamps_s, rates, strict=True)
    ]


def test_turn_integrates_the_rate_between_any_two_stamps():
    gyro = GyroTurns()
    for sample in samples(np.arange(0.0, 10.0, 0.01), 0.3):
        gyro.add(sample)
    assert gyro.turn(1.234, 5.678) == pytest.approx(0.3 * (5.678 - 1.234), abs=1e-9)
    assert gyro.turn(2.0, 2.0) == pytest.approx(0.0, abs=1e-12)
    assert gyro.turn(-0.5, 1.0) is None  # before the first sample
    # a little past the last sample (the scan stored before the IMU): its rate held
    assert gyro.turn(9.0, 10.2) == pytest.approx(0.3 * 1.2, abs=1e-9)
    assert gyro.turn(9.0, 10.0 + MAX_GAP_S) is None


def test_turn_across_a_gap_in_the_gyro_is_not_measured():
    gyro = GyroTurns()
    stamps = np.concatenate([np.arange(0.0, 2.0, 0.01), np.arange(2.0 + MAX_GAP_S, 4.0, 0.01)])
    for sample in samples(stamps, -0.1):
        gyro.add(sample)
    assert gyro.turn(0.5, 1.5) == pytest.approx(-0.1, abs=1e-9)
    assert gyro.turn(1.5, 3.0) is None
    assert gyro.turn(3.0, 3.5) == pytest.approx(-0.05, abs=1e-9)


def test_a_rate_that_changes_is_held_from_each_sample_back_to_the_one_before():
    gyro = GyroTurns()
    for sample in samples(np.array([0.0, 0.2, 0.4, 0.6]), np.array([9.0, 1.0, 2.0, 3.0])):
        gyro.add(sample)
    assert gyro.turn(0.0, 0.6) == pytest.approx(0.2 * (1.0 + 2.0 + 3.0))
    assert gyro.turn(0.1, 0.3) == pytest.approx(0.1 * 1.0 + 0.1 * 2.0)


def walk(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) poses 0.2 m apart, turning by random amounts."""
    poses = [np.zeros(3)]
    for turn in rng.normal(0.0, 0.15, n - 1):
        x, y, yaw = poses[-1]
        poses.append(np.array([x + 0.2 * np.cos(yaw), y + 0.2 * np.sin(yaw), yaw + turn]))
    return np.array(poses)


def heading_errors(graph, truth: np.ndarray) -> np.ndarray:
    return np.degrees(wrap_angle(graph.estimates()[:, 2] - truth[:, 2]))


def test_the_graph_finds_the_gyro_bias_and_holds_the_heading_to_its_turns():
    """Steps whose turns are off by 0.3 deg, a heading fix at the middle and at the end (as
    loop closures give), and a gyro 30x better than the steps but off by a bias of 0.5 deg/s:
    the graph finds the bias from the fixes and holds the heading between them to the gyro."""
    rng = np.random.default_rng(3)
    n, dt_s, bias = 300, 0.4, np.radians(0.5)
    truth = walk(n, rng)
    step_sigma, gyro_sigma, fix_sigma = np.radians(0.3), np.radians(0.01), np.radians(0.1)
    graphs = {}
    for with_gyro in (False, True):
        graph = get_pose_graph(BackendConfig(floor_sigmas=(1e-4, 1e-4, 1e-5)))
        graph.add_prior(0, truth[0], np.diag([1e-8, 1e-8, 1e-10]))
        step_noise = np.random.default_rng(4)
        gyro_noise = np.random.default_rng(5)
        for j in range(1, n):
            delta = se2_between(truth[j - 1], truth[j])
            measured = delta + np.array([0.0, 0.0, step_noise.normal(0.0, step_sigma)])
            graph.add_between(j - 1, j, measured, np.diag([1e-4, 1e-4, step_sigma**2]))
            turn = delta[2] + bias * dt_s + gyro_noise.normal(0.0, gyro_sigma)
            if with_gyro:
                graph.add_gyro_turn(j - 1, j, turn, dt_s, gyro_sigma, 1e-6, np.radians(2.0))
            if j in (n // 2, n - 1):
                graph.add_prior(j, truth[j], np.diag([1e2, 1e2, fix_sigma**2]))
            graph.optimize()
        graphs[with_gyro] = graph
    # the fixes 60 s apart see the bias to about 0.1 deg / 60 s
    assert np.degrees(graphs[True].gyro_bias(n - 1)) == pytest.approx(0.5, abs=0.01)
    assert graphs[True].factor_counts["gyro"] == n - 1
    assert graphs[False].gyro_bias(n - 1) is None
    rms = {g: np.sqrt(np.mean(heading_errors(graph, truth) ** 2)) for g, graph in graphs.items()}
    assert rms[True] < 0.2
    assert rms[True] < 0.2 * rms[False]


def test_a_pair_without_gyro_leaves_the_turn_to_the_steps():
    graph = get_pose_graph(BackendConfig())
    graph.add_prior(0, np.zeros(3), np.diag([1e-8, 1e-8, 1e-10]))
    graph.add_between(0, 1, np.array([0.2, 0.0, 0.1]), np.diag([1e-4, 1e-4, 1e-4]))
    graph.add_gyro_turn(0, 1, None, 0.4, 1e-4, 1e-6, 0.01)
    graph.optimize()
    assert graph.estimates()[1, 2] == pytest.approx(0.1, abs=1e-9)
    assert graph.factor_counts["gyro"] == 0
    assert graph.gyro_bias(1) == pytest.approx(0.0, abs=1e-9)


def test_the_backend_holds_its_keyframe_turns_to_the_gyro_between_them():
    """Radar steps whose turns are off by 0.3 deg each, and a gyro (100 Hz) with no bias that
    the config says is known to be small: with gyro factors the keyframe headings follow the
    gyro's turns between the keyframe stamps, and drift far less than the steps' own."""
    config = load_config(None, {"slam": {"gyro_factors": True, "gyro_bias_sigma_degps": 0.001}})
    truth_rate = np.array([0.5, 0.0, 0.2])  # m/s, m/s, rad/s: an arc

    def truth(t: float) -> np.ndarray:
        return se2_exp(truth_rate * t)

    imu_stamps = np.arange(0.0, 30.0, 0.01)
    gyro_noise = np.random.default_rng(1).normal(0.0, 0.002, len(imu_stamps))
    imu = samples(imu_stamps, truth_rate[2] + gyro_noise)
    headings = {}
    for with_gyro in (False, True):
        backend = SlamBackend(config, Primary("radar", np.zeros(3), 1.0), None, False, with_gyro)
        step_noise = np.random.default_rng(2)
        pose, next_imu = np.zeros(3), 0
        for t in np.arange(0.1, 29.9, 0.1):
            while imu[next_imu].stamp_s <= t + 0.05:  # the IMU runs ahead of the radar
                backend.add_imu(imu[next_imu])
                next_imu += 1
            delta = se2_between(truth(t - 0.1), truth(t))
            delta[2] += step_noise.normal(0.0, np.radians(0.3))
            pose = se2_compose(pose, delta)
            health = OdometryHealth(inliers=30, fitness=0.02, lost=False)
            sigmas = np.array([0.01, 0.01, np.radians(0.3)])
            backend.add_odometry(Odometry(t, pose, delta, np.diag(sigmas**2), health), SCAN)
        stamps = np.asarray(backend.keyframe_stamps_s)
        true_yaw = np.array([truth(t)[2] for t in stamps]) - truth(stamps[0])[2]
        errors = wrap_angle(backend.keyframe_poses()[:, 2] - true_yaw)
        headings[with_gyro] = np.degrees(np.sqrt(np.mean(errors**2)))
        if with_gyro:
            assert backend.factor_counts["gyro"] == len(stamps) - 1
            assert abs(np.degrees(backend.gyro_bias_radps)) < 0.002
        else:
            assert backend.gyro_bias_radps is None and "gyro" not in backend.factor_counts
    assert headings[False] > 1.0  # the steps' random walk
    assert headings[True] < 0.1 * headings[False]


def test_a_held_bias_prior_replaces_the_one_before():
    """Gyro turns and steps that agree say nothing of the bias: a held prior sets it, and a
    newer one replaces it (a running estimate, not a second measurement)."""
    graph = get_pose_graph(BackendConfig())
    graph.add_prior(0, np.zeros(3), np.diag([1e-8, 1e-8, 1e-10]))
    graph.optimize()
    sigma = np.radians(0.01)
    for j, mean_degps in enumerate([0.2, 0.2, 0.2, -0.1, -0.1], start=1):
        step = np.array([0.2, 0.0, 0.05])
        graph.add_between(j - 1, j, step, np.diag([1e-4, 1e-4, 1e-2]))
        graph.add_gyro_turn(j - 1, j, 0.05, 0.4, sigma, 1e-6, np.radians(1.0))
        graph.hold_gyro_bias(np.radians(mean_degps), np.radians(0.001))
        graph.optimize()
        assert np.degrees(graph.gyro_bias(j)) == pytest.approx(mean_degps, abs=1e-3)
    # the turns follow the gyro less the held bias (turn - b dt)
    np.testing.assert_allclose(
        np.diff(graph.estimates()[:, 2])[-1], 0.05 - np.radians(-0.1) * 0.4, atol=1e-6
    )


def test_a_floor_on_the_bias_prior_lets_the_steps_correct_an_overconfident_estimate():
    """The radar odometry hands the graph a bias of 0 with a sigma of 0.001 deg/s while the
    gyro is off by 0.3 deg/s and the steps' turns are good (0.02 deg each): held at that sigma
    the graph keeps the wrong bias; floored at 0.05 deg/s (``gyro_bias_prior_floor_degps``)
    the steps over 30 s pull it most of the way to the true one."""
    truth_rate = np.array([0.5, 0.0, 0.1])
    bias = np.radians(0.3)
    imu_stamps = np.arange(0.0, 30.0, 0.01)
    imu = samples(imu_stamps, truth_rate[2] + bias)
    found = {}
    for floor in (0.0, 0.05):
        config = load_config(None, {"slam": {"gyro_bias_prior_floor_degps": floor}})
        backend = SlamBackend(config, Primary("radar", np.zeros(3), 1.0), None, False, True)
        step_noise = np.random.default_rng(2)
        pose, next_imu = np.zeros(3), 0
        for t in np.arange(0.1, 29.9, 0.1):
            while imu[next_imu].stamp_s <= t + 0.05:
                backend.add_imu(imu[next_imu])
                next_imu += 1
            delta = se2_between(se2_exp(truth_rate * (t - 0.1)), se2_exp(truth_rate * t))
            delta[2] += step_noise.normal(0.0, np.radians(0.02))
            pose = se2_compose(pose, delta)
            extra = {"gyro_bias_radps": 0.0, "gyro_bias_sigma_radps": np.radians(0.001)}
            health = OdometryHealth(inliers=30, fitness=0.02, lost=False, extra=extra)
            sigmas = np.array([0.01, 0.01, np.radians(0.02)])
            backend.add_odometry(Odometry(t, pose, delta, np.diag(sigmas**2), health), SCAN)
        found[floor] = np.degrees(backend.gyro_bias_radps)
    assert abs(found[0.0]) < 0.01
    assert 0.2 < found[0.05] < 0.32  # 0.227: the steps' 75 keyframe turns against the prior
