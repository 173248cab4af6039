"""Fusion from the command line: paper-table on a short simulation, and fuse on its maps."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smokyslam.config import FusionConfig
from smokyslam.geometry import GridSpec
from smokyslam.mapio import UNKNOWN, load_map, save_map

T_CLEAR = FusionConfig().trust_model.t_clear
"""A clear camera's trust index t."""
CLEAR_TOLERANCE = 0.1 * (1.0 - T_CLEAR)
"""How near a clear camera's measured t must be to ``T_CLEAR``: a tenth of its way to 1."""

pytest.importorskip("torch")


def smokyslam(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)], capture_output=True, text=True
    )


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    """paper-table on a 40 s office walk (radar, camera, truth)."""
    folder = tmp_path_factory.mktemp("table")
    log = folder / "office.mcap"
    out = smokyslam(
        "simulate", "--world", "office", "--seed", "3", "--duration", "40", "--out", log
    )
    assert out.returncode == 0, out.stderr
    out = smokyslam("paper-table", log, "--out", folder / "table", "--rerun", folder / "t.rrd")
    assert out.returncode == 0, out.stderr
    return folder / "table"


def test_paper_table_refuses_a_log_without_a_camera_before_any_run(tmp_path):
    log = tmp_path / "radar.mcap"
    args = ("--world", "office", "--seed", "3", "--duration", "3", "--sensors", "radar,imu")
    assert smokyslam("simulate", *args, "--out", log).returncode == 0
    out = smokyslam("paper-table", log, "--out", tmp_path / "table")
    assert out.returncode == 1
    assert out.stderr.strip().splitlines()[-1].startswith(f"error: {log}: no camera_image topic")
    assert "Traceback" not in out.stderr and not (tmp_path / "table" / "runs").exists()


def test_paper_table_records_its_runs_and_maps(table):
    from test_rerun_recorder import rows_per_entity

    recorded = rows_per_entity(table.parent / "t.rrd")
    for source in ("fused", "camera"):
        for level in ("r0-c0", "r0.1-c0.2", "r0.2-c0.4"):
            assert f"/world/trajectory/{source}-{level}" in recorded
    written = sorted(p.stem for p in (table / "maps").glob("map_*.yaml"))
    pictures = sorted(e.split("/")[-1] for e in recorded if e.startswith("/maps/"))
    assert pictures == sorted(f"map_{int(name[4:]):02d}" for name in written)
    assert len(pictures) >= 6


def test_paper_table_writes_all_twelve_rows_and_maps(table):
    with (table / "table.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == [
        "map_index", "name", "error_index", "occupied_f1", "paper_error_index",
    ]  # fmt: skip
    assert [int(r["map_index"]) for r in rows] == list(range(1, 13))
    assert [float(r["paper_error_index"]) for r in rows][:3] == [0.476, 0.497, 0.543]
    for row in rows:
        assert row["error_index"], f"map {row['map_index']} is missing"
        assert 0.0 <= float(row["error_index"]) <= 1.0
        assert (table / f"maps/map_{row['map_index']}.yaml").is_file()
    error = {int(r["map_index"]): float(r["error_index"]) for r in rows}
    # Up-sampling helps at every level (the paper: 0.39 x).
    for level in range(3):
        assert error[4 + level] < 0.6 * error[1 + level]
    text = (table / "table.md").read_text()
    assert "observed" in text and "trust t" in text
    assert (table / "maps.png").stat().st_size > 10_000


def test_the_trust_rises_with_the_smoke_of_the_table(table):
    trusts = []
    for level in ("r0-c0", "r0.1-c0.2", "r0.2-c0.4"):
        metrics = json.loads((table / f"runs/camera-{level}/metrics.json").read_text())
        trusts.append(metrics["fusion"]["trust_run"])
    assert trusts[0] < trusts[1] < trusts[2] <= 1.0, trusts


def test_a_fused_run_writes_its_fused_map_and_trust(table):
    run = table / "runs/fused-r0-c0"
    metrics = json.loads((run / "metrics.json").read_text())
    assert {"radar_sparse", "radar_dense", "visual", "fused"} <= set(metrics["maps"])
    assert metrics["fusion"]["rule"] == "linear"
    assert metrics["fusion"]["trust_mean"] == pytest.approx(T_CLEAR, abs=CLEAR_TOLERANCE)
    assert (run / "maps/fused.yaml").is_file() and (run / "maps/visual.trust.npz").is_file()


def test_fuse_command_with_measured_and_forced_trust(table, tmp_path):
    run = table / "runs/fused-r0-c0"
    radar, visual = run / "maps/radar_dense.yaml", run / "maps/visual.yaml"
    out = smokyslam("fuse", radar, visual, "--no-register", "--out", tmp_path / "auto")
    assert out.returncode == 0, out.stderr
    measured = json.loads((tmp_path / "auto/metrics.json").read_text())["fusion"]
    assert load_map(tmp_path / "auto/maps/fused.yaml").cells.shape[0] > 10
    forced = smokyslam(
        "fuse", radar, visual, "--no-register", "--trust", "0.9", "--rule", "log-odds",
        "--out", tmp_path / "forced",
    )  # fmt: skip
    assert forced.returncode == 0, forced.stderr
    summary = json.loads((tmp_path / "forced/metrics.json").read_text())["fusion"]
    assert summary["trust_mean"] == pytest.approx(0.9) and summary["rule"] == "log-odds"
    assert measured["trust_mean"] == pytest.approx(T_CLEAR, abs=CLEAR_TOLERANCE)  # a clear camera


def test_fuse_registers_the_camera_only_map(table, tmp_path):
    radar = table / "runs/fused-r0-c0/maps/radar_sparse.yaml"
    visual = table / "runs/camera-r0-c0/maps/visual_unaligned.yaml"
    out = smokyslam("fuse", radar, visual, "--out", tmp_path)
    assert out.returncode == 0, out.stderr
    record = json.loads((tmp_path / "homography.json").read_text())
    assert record["confident"] and np.shape(record["H"]) == (3, 3)


def test_bad_fusion_input_is_one_clear_line(table, tmp_path):
    blank = save_map(
        tmp_path / "blank.yaml",
        np.full((20, 20), UNKNOWN, np.int8),
        GridSpec((0, 0), 0.1, (20, 20)),
    )
    radar = table / "runs/fused-r0-c0/maps/radar_dense.yaml"
    no_trust = table / "runs/fused-r0-c0/maps/radar_sparse.yaml"  # no trust file beside it
    cases = [
        (["fuse", radar, blank, "--trust", "0.5"], "no known cell"),
        (["fuse", radar, radar, "--trust", "1.5"], "[0, 1]"),
        (["fuse", radar, radar, "--trust", "lots"], "--trust"),
        (["fuse", radar, no_trust, "--no-register"], "no measured trust"),
        (["fuse", radar, radar, "--trust", "0.5", "--rule", "max"], "rule"),
    ]
    for k, (args, message) in enumerate(cases):
        out = smokyslam(*args, "--out", tmp_path / f"out{k}")
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 1 and len(lines) == 1, out.stderr
        assert lines[0].startswith("error: ") and message in lines[0], out.stderr
