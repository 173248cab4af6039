"""Fused SLAM: keyframe steps and their covariances, camera factors, the online pipeline."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from smokyslam.backends.camera_factors import CameraFactorMaker, get_camera_factor_maker
from smokyslam.backends.camera_gate import get_camera_gate
from smokyslam.backends.keyframes import KeyframeGate, Keyframer
from smokyslam.backends.scale import get_scale_estimator
from smokyslam.backends.slam import Primary, SlamBackend
from smokyslam.config import SmokySlamConfig, load_config
from smokyslam.errors import ConfigError
from smokyslam.frontends.camera.pose import camera_from_planar, planar_from_camera
from smokyslam.frontends.camera.preprocess import ImageQuality
from smokyslam.frontends.camera.result import CameraHealth, CameraOdometryResult, TrackingStatus
from smokyslam.frontends.readers.registry import open_log
from smokyslam.geometry import (
    se2_between,
    se2_compose,
    se2_compose_with_covariance,
    se2_conjugate,
    se2_exp,
    se2_inverse,
    se2_log,
    transform_points_2d,
    wrap_angle,
)
from smokyslam.pipelines.run import evaluate_source, run_log, run_source
from smokyslam.types import CameraFrame, ImuSample, Odometry, OdometryHealth

MOUNT_RADAR = np.array([0.1, 0.0, 0.0])


def _sampled_covariance(mean: np.ndarray, samples: np.ndarray) -> np.ndarray:
    """Covariance of ``Log(mean^-1 * sample)``: the tangent (right) convention."""
    xi = se2_log(se2_between(mean, samples))
    return np.cov(xi.T)


def test_composed_step_covariance_matches_sampling():
    rng = np.random.default_rng(0)
    a, b = np.array([0.3, 0.1, 0.4]), np.array([0.2, -0.05, -0.3])
    cov_a = np.diag([0.02, 0.01, 0.03]) ** 2
    cov_b = np.array([[4e-4, 1e-4, 0.0], [1e-4, 2e-4, 5e-5], [0.0, 5e-5, 9e-4]])
    delta, covariance = se2_compose_with_covariance(a, cov_a, b, cov_b)
    n = 100_000
    a_samples = se2_compose(a, se2_exp(rng.multivariate_normal(np.zeros(3), cov_a, n)))
    b_samples = se2_compose(b, se2_exp(rng.multivariate_normal(np.zeros(3), cov_b, n)))
    sampled = _sampled_covariance(delta, se2_compose(a_samples, b_samples))
    np.testing.assert_allclose(delta, se2_compose(a, b))
    np.testing.assert_allclose(covariance, sampled, atol=0.05 * np.abs(sampled).max())


def test_conjugate_moves_a_radar_step_and_its_covariance_to_base_link():
    rng = np.random.default_rng(1)
    mount = np.array([0.1, -0.05, 0.3])
    radar_a, radar_b = np.array([1.0, 2.0, 0.5]), np.array([1.3, 2.1, 0.8])
    step = se2_between(radar_a, radar_b)
    cov = np.diag([0.01, 0.02, 0.01]) ** 2
    delta, covariance = se2_conjugate(step, cov, mount)
    base_a, base_b = (
        se2_compose(radar_a, se2_inverse(mount)),
        se2_compose(radar_b, se2_inverse(mount)),
    )
    np.testing.assert_allclose(delta, se2_between(base_a, base_b), atol=1e-12)
    steps = se2_compose(step, se2_exp(rng.multivariate_normal(np.zeros(3), cov, 100_000)))
    moved = se2_compose(se2_compose(mount, steps), se2_inverse(mount))
    sampled = _sampled_covariance(delta, moved)
    np.testing.assert_allclose(covariance, sampled, atol=0.05 * np.abs(sampled).max())


def _odometry(stamp_s: float, pose: np.ndarray, delta: np.ndarray, sigma: float) -> Odometry:
    health = OdometryHealth(inliers=30, fitness=0.02, lost=False)
    return Odometry(stamp_s, pose, delta, np.eye(3) * sigma**2, health)


SCAN_XY = np.array([[2.0, 0.0], [2.0, 1.0], [3.0, -1.0]])
"""A radar frame's points, radar frame."""


def test_keyframer_gate_steps_and_frame_offsets_rebuild_the_trajectory():
    # The radar walks 0.06 m a frame while turning 0.02 rad: a keyframe every 4th frame
    # (>= 0.2 m), with base_link 0.1 m behind the radar.
    keyframer = Keyframer(KeyframeGate(0.2, np.pi / 8), MOUNT_RADAR, submap_frames=12)
    points_base = transform_points_2d(MOUNT_RADAR, SCAN_XY)
    step = np.array([0.06, 0.0, 0.02])
    pose, keyframes = np.zeros(3), []
    truth = []
    for i in range(21):
        delta = step if i else np.zeros(3)
        pose = se2_compose(pose, delta)
        truth.append(se2_compose(pose, se2_inverse(MOUNT_RADAR)))
        keyframe = keyframer.add(_odometry(0.1 * i, pose, delta, 0.01), points_base)
        if keyframe is not None:
            keyframes.append(keyframe)
    assert [k.index for k in keyframes] == list(range(6))
    assert [round(k.stamp_s, 6) for k in keyframes] == [0.0, 0.4, 0.8, 1.2, 1.6, 2.0]
    keyframe_poses = [truth[0]]
    for k in keyframes[1:]:
        keyframe_poses.append(se2_compose(keyframe_poses[-1], k.delta))
        # Four independent steps of 0.01 m: at least 4x one step's variance along x.
        assert k.covariance[0, 0] == pytest.approx(4e-4, rel=0.05)
        assert k.covariance[2, 2] == pytest.approx(4e-4, rel=1e-9)
    rebuilt = se2_compose(
        np.array(keyframe_poses)[keyframer.frame_keyframe], np.array(keyframer.frame_offset)
    )
    np.testing.assert_allclose(rebuilt, np.array(truth), atol=1e-12)
    # Submap: the recent frames' points in the latest base_link; the newest one lies as seen,
    # seen from the radar's mount.
    submap, origins = keyframer.submap(voxel_m=0.0)
    np.testing.assert_allclose(submap[-3:], SCAN_XY + MOUNT_RADAR[:2])
    np.testing.assert_allclose(origins[-3:], np.tile(MOUNT_RADAR[:2], (3, 1)))
    assert origins.shape == submap.shape


def _camera_result(stamp_s: float, pose: np.ndarray, noise: float = 0.0, map_id: int = 0):
    quality = ImageQuality(noise, 0.2, 0.1, 0, False)
    return CameraOdometryResult(
        stamp_s=stamp_s,
        status=TrackingStatus.TRACKING,
        pose_world_camera=pose,
        T_world_camera=camera_from_planar(pose),
        keyframe_id=0,
        relative_pose=np.zeros(3),
        covariance=np.diag([1e-4, 1e-4, 1e-6]),
        health=CameraHealth(tracked=200, landmarks=150, inliers=140, inlier_ratio=0.93),
        quality=quality,
        is_keyframe=False,
        reinitialized=False,
        reinitializations=map_id,
        landmarks_world=np.zeros((0, 3)),
    )


def _camera_scene(noise: float = 0.0, yaw_jump_at_s: float | None = None, kind: str = "pose"):
    """A base_link arc (0.5 m/s, 0.2 rad/s), radar keyframes every 0.4 s, and a camera at
    15 Hz seeing it in units 2.5x smaller, from 0.05 m ahead of base_link; ``kind``: what its
    factors hold (yaw ones with the camera's reported yaw variance scaled by 16)."""
    config = SmokySlamConfig()
    T_base_camera = np.eye(4)
    T_base_camera[:3, :3] = camera_from_planar(np.zeros(3))[:3, :3]
    T_base_camera[:3, 3] = [0.05, 0.0, 1.2]
    mount = planar_from_camera(T_base_camera)
    maker = CameraFactorMaker(
        T_base_camera,
        get_camera_gate(config.backend.camera_gate),
        get_scale_estimator(config.backend.scale),
        covariance_scale=1.0,
        consistency_chi2=11.34,
        kind=kind,
        yaw_variance_scale=16.0,
    )

    def base(t):
        return se2_exp(np.array([0.5, 0.0, 0.2]) * t)

    camera_t = np.arange(0.0, 6.0, 1 / 15)
    for t in camera_t:
        pose = se2_compose(base(t), mount)
        pose[:2] /= 2.5
        if yaw_jump_at_s is not None and t >= yaw_jump_at_s:
            pose[2] += 0.2
        maker.add(_camera_result(t, pose, noise))
    outcomes = []
    for t in np.arange(0.4, 5.6, 0.4):
        true_delta = se2_between(base(t - 0.4), base(t))
        cov = np.diag([0.01, 0.01, 0.003]) ** 2
        outcomes.append((true_delta, maker.factor(t - 0.4, t, true_delta, cov)))
    return maker, outcomes


def test_camera_factor_becomes_metric_in_base_link_once_the_scale_is_known():
    maker, outcomes = _camera_scene()
    factors = [f for _, f in outcomes]
    min_pairs = SmokySlamConfig().backend.scale.min_pairs
    assert all(f is None for f in factors[: min_pairs - 1])
    assert all(f is not None for f in factors[min_pairs - 1 :])
    assert maker.scale_m == pytest.approx(2.5, rel=1e-3)
    for true_delta, factor in outcomes[min_pairs - 1 :]:
        np.testing.assert_allclose(factor.delta, true_delta, atol=2e-3)
        assert factor.weight == 1.0 and np.all(np.linalg.eigvalsh(factor.covariance) > 0)


def test_a_noisy_camera_is_weighed_a_blinding_one_gated_an_inconsistent_one_refused():
    _, clean = _camera_scene()
    maker, noisy = _camera_scene(noise=0.6)  # salt and pepper 0.6, still tracking
    weight = (0.6 - 0.7) / (0.05 - 0.7)  # the gate's default quality ramp
    for (_, factor), (_, reference) in zip(noisy, clean, strict=True):
        assert (factor is None) == (reference is None)
        if factor is not None:
            assert factor.weight == pytest.approx(weight)
            np.testing.assert_allclose(factor.covariance, reference.covariance / weight**2)
    maker, outcomes = _camera_scene(noise=0.75)  # nothing left of the image
    assert all(f is None for _, f in outcomes) and maker.outcomes["gated"] == len(outcomes)
    maker, outcomes = _camera_scene(yaw_jump_at_s=3.1)
    assert maker.outcomes["inconsistent"] == 1  # the pair over the 0.2 rad jump
    assert outcomes[7][1] is None and outcomes[8][1] is not None


def test_a_yaw_factor_holds_the_camera_turn_from_the_first_pair_and_leaves_translation_free():
    maker, outcomes = _camera_scene(kind="yaw")
    # No metric scale is needed: every pair gets a factor, the first one included.
    assert all(f is not None for _, f in outcomes) and maker.outcomes["used"] == len(outcomes)
    yaw_variance = 16.0 * 2 * 1e-6  # the two frames' reported 1e-6 rad^2, scaled
    radar_covariance = np.diag([0.01, 0.01, 0.003]) ** 2
    for true_delta, factor in outcomes:
        assert factor.delta[2] == pytest.approx(true_delta[2], abs=1e-3)  # the camera's turn
        np.testing.assert_array_equal(factor.delta[:2], true_delta[:2])  # the radar's step
        np.testing.assert_allclose(np.diag(factor.covariance), [1e4, 1e4, yaw_variance])
    # The scale is still learned, for the visual map and the kept metric steps.
    assert maker.scale_m == pytest.approx(2.5, rel=1e-3)
    assert (
        len(maker.steps.stamps_s) == len(outcomes) - SmokySlamConfig().backend.scale.min_pairs + 1
    )
    # A turn that disagrees is refused on its own check (1 dof): the 0.2 rad jump's pair,
    # 0.2 / sqrt(0.003^2 + 3.2e-5) = 31 sigma off.
    maker, outcomes = _camera_scene(yaw_jump_at_s=3.1, kind="yaw")
    assert [i for i, (_, f) in enumerate(outcomes) if f is None] == [7]
    assert 0.2 / np.sqrt(radar_covariance[2, 2] + yaw_variance) > 30


def _long_turn_maker() -> CameraFactorMaker:
    """A yaw-factor maker with a long turn every 2 s (sigma 1 deg)."""
    config = SmokySlamConfig()
    return CameraFactorMaker(
        np.eye(4),
        get_camera_gate(config.backend.camera_gate),
        get_scale_estimator(config.backend.scale),
        covariance_scale=1.0,
        consistency_chi2=3.0,
        kind="yaw",
        yaw_variance_scale=64.0,
        long_turn_s=2.0,
        long_turn_sigma_rad=np.radians(1.0),
    )


def _feed_long_turns(maker: CameraFactorMaker, lost_at_s: float | None = None) -> list:
    """A camera turning at 0.2 rad/s for 6 s at 15 Hz (the frame at ``lost_at_s`` lost) and
    keyframes every 0.4 s, in time order; returns (keyframe index, long turn) for each
    keyframe that made one."""
    turns, index = [], 0
    for t in np.arange(0.0, 6.0, 1 / 15):
        result = _camera_result(t, se2_exp(np.array([0.0, 0.0, 0.2]) * t))
        if lost_at_s is not None and abs(t - lost_at_s) < 1e-6:
            result = dataclasses.replace(result, status=TrackingStatus.LOST)
        maker.add(result)
        if t > 0.4 * (index + 1):  # the camera has passed the next keyframe
            index += 1
            turn = maker.long_turn(index, 0.4 * index)
            if turn is not None:
                turns.append((index, turn))
    return turns


def test_a_long_turn_holds_the_camera_s_turn_over_seconds_of_unbroken_tracking():
    turns = _feed_long_turns(_long_turn_maker())
    # Keyframe 1 (0.4 s) starts the first; one every 2 s (5 keyframes) of tracking after.
    assert [(t.old_index, i) for i, t in turns] == [(1, 6), (6, 11)]
    for _, turn in turns:
        assert turn.yaw_rad == pytest.approx(0.2 * 2.0, abs=1e-6)
        np.testing.assert_allclose(np.diag(turn.covariance), [1e4, 1e4, np.radians(1.0) ** 2])
    # A lost frame at 3 s (keyframe 7 at 2.8 s is before it) breaks the span: the next
    # keyframe seen tracked starts a new one, and no turn crosses the loss.
    turns = _feed_long_turns(_long_turn_maker(), lost_at_s=3.0)
    assert [(t.old_index, i) for i, t in turns] == [(1, 6), (8, 13)]
    # Off for whole-step camera factors, which hold the turn already.
    config = SmokySlamConfig()
    T_base_camera = np.eye(4)
    assert get_camera_factor_maker(config.backend, config.slam, T_base_camera)._long_turn_s == 20.0
    pose = get_camera_factor_maker(config.backend, config.slam, T_base_camera, kind="pose")
    assert pose._long_turn_s == 0.0


def _heading_after_a_biased_minute(long_turn_s: float, sigma_deg: float) -> tuple[float, float]:
    """60 s on an arc (0.5 m/s, 0.1 rad/s) with a gyro 0.15 deg/s off, radar steps that turn
    with it (the radar odometry integrates that gyro) and a bias estimate of 0 it holds
    firmly; a camera (15 Hz) that sees the true turns. Returns the last keyframe's heading
    error (deg) and the graph's bias (deg/s) with long turns every ``long_turn_s``."""
    slam = {"camera_long_turn_s": long_turn_s, "camera_long_turn_sigma_deg": sigma_deg}
    config = load_config(None, {"slam": slam})
    T_base_camera = np.eye(4)
    T_base_camera[:3, :3] = camera_from_planar(np.zeros(3))[:3, :3]
    T_base_camera[:3, 3] = [0.05, 0.0, 1.2]
    mount = planar_from_camera(T_base_camera)
    rate, bias = np.array([0.5, 0.0, 0.1]), np.radians(0.15)
    backend = SlamBackend(config, Primary("radar", np.zeros(3), 1.0), T_base_camera, False, True)
    # In time order, the IMU 50 ms ahead of the frames: 0 IMU, 1 radar, 2 camera.
    events = [(t - 0.05, 0, t) for t in np.arange(0.0, 60.0, 0.01)]
    events += [(t, 1, t) for t in np.arange(0.1, 59.0, 0.1)]
    events += [(t, 2, t) for t in np.arange(0.0, 60.0, 1 / 15)]
    pose = np.zeros(3)
    extra = {"gyro_bias_radps": 0.0, "gyro_bias_sigma_radps": np.radians(0.001)}
    health = OdometryHealth(inliers=30, fitness=0.02, lost=False, extra=extra)
    covariance = np.diag(np.square([0.01, 0.01, np.radians(0.2)]))
    for _, kind, t in sorted(events):
        if kind == 0:
            backend.add_imu(ImuSample(float(t), np.array([0.0, 0.0, rate[2] + bias]), np.zeros(3)))
        elif kind == 1:
            delta = se2_between(se2_exp(rate * (t - 0.1)), se2_exp(rate * t))
            delta[2] += bias * 0.1
            pose = se2_compose(pose, delta)
            backend.add_odometry(Odometry(float(t), pose, delta, covariance, health), SCAN_XY)
        else:
            camera = se2_compose(se2_exp(rate * t), mount)
            camera[:2] /= 2.5
            backend.add_camera(_camera_result(float(t), camera))
    last = backend.keyframe_stamps_s[-1] - backend.keyframe_stamps_s[0]
    error = wrap_angle(backend.keyframe_poses()[-1, 2] - rate[2] * last)
    return abs(np.degrees(error)), np.degrees(backend.gyro_bias_radps)


def test_long_turns_let_a_camera_that_keeps_its_heading_correct_a_shared_gyro_bias():
    # Radar and gyro agree on a bias that is wrong: the per-pair camera turns (weak, as
    # independent factors) barely move it; turns over 20 s do, the more the firmer.
    without, bias_without = _heading_after_a_biased_minute(0.0, 2.0)
    loose, bias_loose = _heading_after_a_biased_minute(20.0, 2.0)
    firm, bias_firm = _heading_after_a_biased_minute(20.0, 0.5)
    assert without > 6.0 and bias_without < 0.03  # 7.7 deg, 0.016 deg/s (true 0.15)
    assert 0.6 * without < loose < 0.85 * without  # 5.8 deg
    assert firm < 0.3 * without  # 1.6 deg
    assert bias_without < bias_loose < bias_firm
    assert bias_firm == pytest.approx(0.15, abs=0.06)  # 0.107


def test_image_noise_weighs_a_pose_factor_but_not_a_yaw_factor():
    # The camera's turn is as good at noise 0.4 as in clean air (docs/accuracy.md): a yaw
    # factor is weighed by tracking alone, so a noisy camera that tracks keeps full weight.
    _, clean = _camera_scene(kind="yaw")
    _, noisy = _camera_scene(noise=0.6, kind="yaw")  # quality weight 0.15, tracking 1
    for (_, factor), (_, reference) in zip(noisy, clean, strict=True):
        assert factor.weight == 1.0
        np.testing.assert_array_equal(factor.covariance, reference.covariance)
    _, noisy_pose = _camera_scene(noise=0.6)
    assert {round(f.weight, 6) for _, f in noisy_pose if f is not None} == {round(0.1 / 0.65, 6)}
    # A blinded camera (no quality left) is still gated, whatever the factor holds.
    maker, outcomes = _camera_scene(noise=0.75, kind="yaw")
    assert all(f is None for _, f in outcomes) and maker.outcomes["gated"] == len(outcomes)


def test_an_unknown_camera_factor_kind_is_one_clear_error():
    with pytest.raises(ConfigError, match="unknown camera factor kind 'roll'"):
        _camera_scene(kind="roll")


# ---------------------------------------------------------------- the pipeline on a log


@pytest.fixture(scope="module")
def runs(office_log, tmp_path_factory):
    config = load_config()
    root = tmp_path_factory.mktemp("runs")
    return {
        source: run_log(office_log, source, config, root / source) for source in ("radar", "fused")
    }


def test_fused_run_writes_every_output(runs):
    out = runs["fused"].out_dir
    for name in ("trajectory.tum", "trajectory_kitti.txt", "ground_truth.tum", "config.yaml"):
        assert (out / name).stat().st_size > 0
    for name in ("radar_sparse", "radar_dense", "visual", "fused"):
        assert {p.suffix for p in (out / "maps").glob(f"{name}.*")} >= {".pgm", ".yaml"}
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["odometry"]["source"] == "fused"
    assert metrics["duration_s"] == pytest.approx(30.0, abs=0.2)
    assert metrics["realtime_factor"] == pytest.approx(
        metrics["duration_s"] / metrics["wall_s"], rel=1e-9
    )
    assert set(metrics["maps"]) == {"radar_sparse", "radar_dense", "visual", "fused"}
    assert 0.5 <= metrics["fusion"]["trust_mean"] <= 1.0  # clean camera: t near t_clear
    assert metrics["upsample"]["refreshes"] >= 0  # in the background: see test_upsample
    assert 0.0 < metrics["maps"]["visual"]["occupied_precision"] <= 1.0
    for scores in metrics["maps"].values():  # the observed truth is scored too, same keys
        assert set(scores["observed"]) == set(scores) - {"observed"}
        # the walk saw fewer walls than the building has: recall of seen walls is higher
        assert scores["observed"]["occupied_recall"] > scores["occupied_recall"]
    factors = metrics["factors"]
    assert factors["radar"] == metrics["keyframes"] - 1 > 50
    assert factors["camera"] > 10
    assert factors["camera_long_turn"] == 1  # 30 s of tracking: one turn over 20 s
    assert metrics["trajectory"]["lost_frames"] == 0
    # Both steps of every pair with a metric camera step, against the true motion: the
    # radar's a few millimetres per step, the camera's (checked before the gate) larger.
    steps = metrics["step_errors"]
    # (a yaw factor needs no metric scale, so the first pairs have a factor and no step)
    assert 10 < steps["pairs"] <= metrics["keyframes"] - 1
    assert steps["radar"]["translation_rms_m"] < 0.02
    assert steps["radar"]["translation_rms_m"] < steps["camera"]["translation_rms_m"] < 0.2
    assert 0.0 < steps["radar"]["yaw_rms_deg"] < 1.0
    assert len(np.loadtxt(out / "trajectory_kitti.txt")) == metrics["trajectory"]["frames"]


def test_fused_is_not_worse_than_radar_alone_on_a_clean_log(runs):
    fused = runs["fused"].metrics["trajectory"]["ate_rmse_m"]
    radar = runs["radar"].metrics["trajectory"]["ate_rmse_m"]
    assert fused <= 1.1 * radar


class _BlindCamera:
    """A log reader whose images are black between ``start_s`` and ``end_s`` (the log's own
    stamps, from its start)."""

    def __init__(self, reader, start_s: float, end_s: float) -> None:
        self._reader, self._start_s, self._end_s = reader, start_s, end_s

    def __getattr__(self, name):
        return getattr(self._reader, name)

    def frames(self, streams=None):
        for frame in self._reader.frames(streams):
            if isinstance(frame, CameraFrame) and self._start_s <= frame.stamp_s < self._end_s:
                frame = dataclasses.replace(frame, image=np.zeros_like(frame.image))
            yield frame


def test_camera_factors_disappear_while_the_camera_is_blind(office_log, runs):
    config = load_config()
    reader = _BlindCamera(open_log(office_log, config), 10.0, 20.0)
    run = run_source(reader, "fused", config)
    stamps = run.keyframe_stamps_s
    blind = (stamps >= 10.0) & (stamps < 20.0)
    assert blind.sum() >= 15 and not run.keyframe_camera[blind].any()
    assert run.keyframe_camera[stamps < 10.0].sum() > 5
    assert run.keyframe_camera[stamps >= 20.0].sum() >= 3  # back, with a fresh scale
    assert run.camera_weight[(run.stamps_s > 10.2) & (run.stamps_s < 20.0)].max() == 0.0
    assert not run.lost.any()
    steps = np.linalg.norm(np.diff(run.poses_world_base[:, :2], axis=0), axis=1)
    assert steps.max() < 0.2  # the trajectory goes on through the blind segment
    blind_ate = evaluate_source(
        run, reader.ground_truth_trajectory(), "fused"
    ).trajectory.ate_rmse_m
    assert blind_ate <= 1.1 * runs["radar"].metrics["trajectory"]["ate_rmse_m"] + 0.02
