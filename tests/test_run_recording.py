"""``smokyslam run LOG --rerun DIR/run.rrd --out DIR``: the recording, the plots and the
trajectory files, checked from outside (rerun's reader and CLI, evo, the log's own stamps)."""

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_rerun_recorder import has_blueprint, rows_per_entity

from smokyslam.config import load_config

BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def xdg(tmp_path_factory):
    """rerun and evo write settings under ~ unless pointed elsewhere."""
    home = tmp_path_factory.mktemp("home")
    return {
        **os.environ,
        "XDG_CONFIG_HOME": str(home),
        "XDG_DATA_HOME": str(home),
        "HOME": str(home),
    }


@pytest.fixture(scope="module")
def fused_run(office_log, tmp_path_factory, xdg):
    out_dir = tmp_path_factory.mktemp("fused")
    args = ["run", office_log, "--odometry", "fused", "--rerun", out_dir / "run.rrd"]
    out = subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args), "--out", str(out_dir)],
        capture_output=True,
        text=True,
        env=xdg,
    )
    assert out.returncode == 0, out.stderr
    assert f"smokyslam view {out_dir / 'run.rrd'}" in out.stdout
    return out_dir


def test_the_recording_holds_every_stage(fused_run, office_log):
    rows = rows_per_entity(fused_run / "run.rrd")
    metrics = json.loads((fused_run / "metrics.json").read_text())
    frames = metrics["trajectory"]["frames"]
    assert frames == 301
    assert rows["/world/map/rig/radar/points"] == frames  # one cloud per radar frame
    assert rows["/world/map/rig"] == frames
    # One image per tracked camera frame: every camera_stride-th of the log's 451.
    stride = load_config().slam.camera_stride
    tracked = math.ceil(451 / stride)
    assert rows["/world/map/rig/camera/image"] == tracked + 1  # and the static pinhole
    assert rows["/camera/clean"] == tracked and rows["/trust/t"] == tracked
    assert rows["/world/map/trajectory/fused"] >= 30  # the path grows once a second
    for name in ("radar_sparse", "visual", "fused"):
        assert rows[f"/world/map/maps/{name}"] >= 2, name  # grid maps grow over the run
    assert rows["/error/fused/position_m"] == frames
    assert {"/world/ground_truth/map", "/world/ground_truth/path", "/health/radar_inliers"} <= set(
        rows
    )
    assert has_blueprint(fused_run / "run.rrd")


def test_rerun_rrd_stats_lists_the_contract_entities(fused_run, xdg):
    out = subprocess.run(
        [str(BIN / "rerun"), "rrd", "stats", str(fused_run / "run.rrd")],
        capture_output=True,
        text=True,
        env=xdg,
    )
    assert out.returncode == 0, out.stderr
    entities = [line.split(":")[0] for line in out.stdout.splitlines() if line.startswith("/")]
    for word in ("radar", "camera", "trajectory", "map"):
        assert any(word in entity for entity in entities), word


def test_the_plots_are_in_the_run_folder(fused_run):
    for name in ("trajectory.png", "error.png", "health.png", "maps/fused_vs_truth.png"):
        assert (fused_run / name).stat().st_size > 20_000, name


def test_trajectory_stamps_are_the_logs_radar_header_stamps(fused_run, office_log):
    from rosbags.highlevel import AnyReader

    header_s = []
    with AnyReader([office_log]) as reader:
        radar = [c for c in reader.connections if c.topic == "/ti_mmwave/radar_scan_pcl"]
        for connection, _, raw in reader.messages(connections=radar):
            stamp = reader.deserialize(raw, connection.msgtype).header.stamp
            header_s.append(stamp.sec + 1e-9 * stamp.nanosec)
    stamps = np.loadtxt(fused_run / "trajectory.tum")[:, 0]
    assert header_s[0] > 1e9  # seconds since the epoch, as TUM files are
    np.testing.assert_allclose(stamps, header_s, rtol=0, atol=1e-6)
    truth = np.loadtxt(fused_run / "ground_truth.tum")[:, 0]
    assert truth[0] == pytest.approx(header_s[0], abs=1e-6)


def test_evo_ape_agrees_with_metrics_within_a_millimetre(fused_run, xdg):
    out = subprocess.run(
        [str(BIN / "evo_ape"), "tum", "ground_truth.tum", "trajectory.tum", "-a"],
        capture_output=True,
        text=True,
        cwd=fused_run,
        env=xdg,
    )
    assert out.returncode == 0, out.stderr
    rmse = float(re.search(r"rmse\s+([0-9.]+)", out.stdout).group(1))
    metrics = json.loads((fused_run / "metrics.json").read_text())
    assert rmse == pytest.approx(metrics["trajectory"]["ate_rmse_m"], abs=1e-3)
