"""The gyro bias fitted from scan yaw against the age of the map points matched."""

from __future__ import annotations

import json

import numpy as np
import pytest

from smokyslam.config import load_config
from smokyslam.frontends.radar.local_map import LocalMap
from smokyslam.frontends.radar.map_age_bias import MapAge, MapAgeBias, scan_yaw
from smokyslam.frontends.readers.registry import open_log
from smokyslam.pipelines.run import run_log
from smokyslam.sim.simulate import simulate
from smokyslam.types import ImuSample

BIAS = 0.003  # rad/s


def test_scan_yaw_takes_the_prior_s_share_out():
    # Prior variance 4, scan variance 1, scan 0.5 from the prior: the fused yaw moves 0.4.
    scan = scan_yaw(4.0, 0.8, 0.4)
    assert scan.innovation_rad == pytest.approx(0.5)
    assert scan.variance_rad2 == pytest.approx(1.0)
    assert scan_yaw(4.0, 4.0, 0.1) is None  # the scan added nothing
    assert scan_yaw(4.0, 0.0, 0.1) is None


def _fit(ages_s: np.ndarray, noise_rad: np.ndarray, ready_sigma_radps: float) -> MapAgeBias:
    fit = MapAgeBias(decorrelation_s=1.0, ready_sigma_radps=ready_sigma_radps)
    scan = scan_yaw(1e-4, 0.5e-4, 0.0)  # scan variance 1e-4 rad^2
    for k, (age_s, noise) in enumerate(zip(ages_s, noise_rad, strict=True)):
        stamp_s = 10.0 + 0.1 * k
        # The map was inserted when the raw gyro had drifted less by the bias times its age.
        offset_now = 0.02 - BIAS * stamp_s + noise
        matched = MapAge(stamp_s - age_s, 0.02 - BIAS * (stamp_s - age_s))
        fit.add(stamp_s, offset_now, scan, 0.1, matched)
    return fit


def test_the_fit_finds_the_bias_from_the_age_of_the_matched_map():
    rng = np.random.default_rng(0)
    ages = rng.uniform(0.5, 6.0, 2000)
    fit = _fit(ages, rng.normal(0.0, 0.01, 2000), ready_sigma_radps=1e-3)
    assert fit.bias_radps == pytest.approx(BIAS, rel=0.05)
    assert fit.sigma_radps < 1e-3
    # Until the fit is sure enough, it offers nothing.
    short = _fit(ages[:5], np.zeros(5), ready_sigma_radps=1e-3)
    assert short.estimate_radps == pytest.approx(BIAS) and short.bias_radps is None


def test_young_matches_and_frames_without_gyro_do_not_count():
    fit = _fit(np.array([0.01, 0.04]), np.zeros(2), ready_sigma_radps=1.0)
    assert fit.estimate_radps is None and fit.sigma_radps == np.inf
    gyro_less = MapAgeBias(1.0, 1.0)
    gyro_less.add(5.0, np.nan, scan_yaw(1e-4, 0.5e-4, 0.0), 0.1, MapAge(1.0, 0.0))
    assert gyro_less.estimate_radps is None


def test_map_lines_carry_the_stamp_and_heading_offset_of_their_points():
    local = LocalMap(radius_m=20.0, voxel_m=0.2, points_per_voxel=4, neighbors=4)
    wall_a = np.column_stack([np.linspace(0.0, 4.0, 21), np.full(21, 2.0)])
    wall_b = np.column_stack([np.full(21, 6.0), np.linspace(-2.0, 2.0, 21)])
    local.insert(wall_a, np.zeros(2), stamp_s=1.0, heading_offset_rad=0.01)
    local.insert(wall_b, np.zeros(2), stamp_s=3.0, heading_offset_rad=-0.02)
    lines = local.lines_at(np.array([[2.0, 2.05], [5.95, 0.0]]), max_distance_m=0.5)
    assert lines.matched.all()
    np.testing.assert_allclose(lines.stamps_s, [1.0, 3.0])
    np.testing.assert_allclose(lines.heading_offsets_rad, [0.01, -0.02])
    # Points of full voxels (4 points each) are dropped with their stamps and offsets.
    for stamp_s in (5.0, 6.0, 7.0, 8.0):
        local.insert(wall_a, np.zeros(2), stamp_s=stamp_s, heading_offset_rad=stamp_s)
    assert len(local.stamps_s) == len(local.heading_offsets_rad) == len(local) == 5 * 21
    assert not (local.stamps_s == 8.0).any()
    np.testing.assert_array_equal(
        local.heading_offsets_rad[local.stamps_s >= 5.0], local.stamps_s[local.stamps_s >= 5.0]
    )


def test_a_long_warehouse_walk_finds_more_of_a_large_gyro_bias(tmp_path):
    """40 s of warehouse with a gyro bias of about 0.35 deg/s: the heading filter alone finds
    a third of it; with the map-age fit the run finds most of it, and its path is better."""
    config = load_config()
    imu = config.simulation.imu.model_copy(update={"gyro_bias_radps": 0.01})
    simulation = config.simulation.model_copy(update={"imu": imu})
    log = tmp_path / "warehouse.mcap"
    simulate(
        "warehouse",
        40.0,
        3,
        log,
        config.model_copy(update={"simulation": simulation}),
        sensors=frozenset({"radar", "imu"}),
    )
    scores = {}
    for below in (None, 0.029):
        odometry = config.radar_odometry.model_copy(update={"map_age_bias_below_degps": below})
        out = tmp_path / f"run_{below}"
        run_log(log, "radar", config.model_copy(update={"radar_odometry": odometry}), out)
        scores[below] = json.loads((out / "metrics.json").read_text())
    filter_only, with_fit = scores[None], scores[0.029]
    true_degps = with_fit["gyro_bias"]["true_degps"]
    assert true_degps > 0.3
    assert abs(filter_only["gyro_bias"]["residual_degps"]) > 0.5 * true_degps
    assert abs(with_fit["gyro_bias"]["residual_degps"]) < 0.2 * true_degps
    ate = {k: v["trajectory"]["ate_rmse_m"] for k, v in scores.items()}
    assert ate[0.029] < 0.85 * ate[None]


def test_the_real_handheld_bag_s_bias_is_found_near_its_standstill_gyro(real_data_dir, tmp_path):
    """The TI bag is held still for its first 8 s (Doppler speed 0): the gyro's mean there is
    its bias, -0.43 deg/s. The heading filter alone ends at -0.18; with the fit at -0.37; the
    fused graph, with the gyro's turns and that fit as its bias prior (sigma floored at 0.05
    deg/s), at -0.30 (without the prior: -0.06, the radar steps alone cannot tell the bias
    from their own drift)."""
    bag = real_data_dir / "ti_mmwave_rospkg_demo.bag"
    calibration = real_data_dir / "ti_mmwave_rospkg_demo.calib.yaml"
    config = load_config(overrides={"rig": {"calibration": str(calibration)}})
    samples = [f for f in open_log(bag, config).frames(("imu",)) if isinstance(f, ImuSample)]
    stamps = np.array([s.stamp_s for s in samples])
    still = stamps < stamps[0] + 7.0
    standstill_degps = float(np.degrees(np.mean([s.gyro_radps[2] for s in samples[: still.sum()]])))
    assert -0.5 < standstill_degps < -0.35
    estimates = {}
    for below in (None, 0.029):
        odometry = config.radar_odometry.model_copy(update={"map_age_bias_below_degps": below})
        out = tmp_path / f"run_{below}"
        run_log(bag, "radar", config.model_copy(update={"radar_odometry": odometry}), out)
        estimates[below] = json.loads((out / "metrics.json").read_text())["odometry"][
            "gyro_bias_degps"
        ]
    assert abs(estimates[0.029] - standstill_degps) < 0.1
    # the fused graph's bias, held to the gyro's turns, radar steps and that estimate
    run_log(bag, "fused", config, tmp_path / "fused")
    gyro = json.loads((tmp_path / "fused" / "metrics.json").read_text())["odometry"]
    assert abs(gyro["graph_gyro_bias_degps"] - standstill_degps) < 0.15
    assert abs(estimates[None] - standstill_degps) > 0.2
