"""``smokyslam sweep`` on a 2-worker Dask LocalCluster: rows, restarts, failures, bad files."""

import csv
import subprocess
import sys

import pytest

from smokyslam.config import load_config
from smokyslam.errors import ConfigError
from smokyslam.pipelines.sweep import sweep
from smokyslam.sweep.spec import load_sweep

TINY = """
worlds:
  - {kind: corridor, seeds: [1, 2], duration_s: 8, sensors: [radar, imu]}
smoke: ["0:0", "0.2:0.4"]
sources: [radar, dead-reckoning]
"""


def read_rows(out):
    with (out / "sweep.csv").open() as stream:
        return list(csv.DictReader(stream))


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sweep")
    (folder / "tiny.yaml").write_text(TINY)
    result = sweep(folder / "tiny.yaml", folder / "out", load_config(), workers=2)
    return folder, result


def test_a_tiny_sweep_on_two_workers_writes_a_row_per_run(swept):
    folder, result = swept
    out = folder / "out"
    rows = read_rows(out)
    assert len(rows) == 8 and result.skipped == 0 and not result.failed
    assert {(r["world"], r["seed"]) for r in rows} == {
        ("corridor-1-8s", "1"),
        ("corridor-2-8s", "2"),
    }
    assert {r["source"] for r in rows} == {"radar", "dead-reckoning"}
    assert {(r["radar_loss"], r["camera_noise"]) for r in rows} == {("0", "0"), ("0.2", "0.4")}
    for row in rows:
        assert row["status"] == "ok" and row["kind"] == "corridor" and row["config"] == "default"
        assert (out / row["log"]).is_file() and row["log"].startswith("logs/")
        assert (out / row["run_dir"] / "trajectory.tum").is_file()
        assert 0.0 < float(row["ate_rmse_m"]) < 0.2
    summary = (out / "summary.md").read_text()
    assert "## smoke r0.2-c0.4" in summary and "| corridor | default | radar | 2 |" in summary
    assert (out / "ate_by_source.png").is_file() and (out / "fused_vs_best.png").is_file()


def test_a_restarted_sweep_skips_finished_runs(swept):
    folder, first = swept
    again = sweep(folder / "tiny.yaml", folder / "out", load_config(), workers=2)
    assert again.skipped == 8 and len(again.rows) == 8
    assert [r.row.metrics["trajectory"] for r in again.rows] == [
        r.row.metrics["trajectory"] for r in first.rows
    ]


def test_a_failing_run_is_recorded_and_the_others_go_on(swept):
    folder, _ = swept
    (folder / "broken.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 8)
    (folder / "mixed.yaml").write_text(
        TINY.replace("seeds: [1, 2]", "seeds: [1]").replace(
            "worlds:\n", "worlds:\n  - {log: broken.mcap}\n"
        )
    )
    result = sweep(folder / "mixed.yaml", folder / "out", load_config(), workers=2)
    rows = read_rows(folder / "out")
    assert len(rows) == 8 and result.skipped == 4  # corridor-1's runs were finished
    broken = [r for r in rows if r["world"] == "broken"]
    assert len(broken) == 4 and len(result.failed) == 4
    assert all(r["status"].startswith("failed: ") and "broken.mcap" in r["status"] for r in broken)
    assert all(r["log"] == "../broken.mcap" for r in broken)
    assert all(r["status"] == "ok" for r in rows if r["world"] != "broken")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (TINY.replace("dead-reckoning", "sonar"), "unknown odometry source 'sonar'"),
        (TINY.replace("kind: corridor", "kind: castle"), "unknown world kind 'castle'"),
        ("worlds:\n  - {log: nowhere.mcap}\nsources: [radar]\n", "log not found: nowhere.mcap"),
        (TINY + "configs: {x: {smoke: {radar_los: 1}}}\n", "configs.x"),
        (TINY.replace("seeds", "seed"), "worlds.0.seed"),
        (TINY + "configs: {off: {}}\n", "config name False is not text"),
    ],
)
def test_bad_sweep_files_are_one_clear_line(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_sweep(path, load_config())
    out = subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", "sweep", str(path), "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
    )
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 1 and len(lines) == 1 and message in lines[0], out.stderr


def test_the_summary_gives_each_sources_step_precision_of_the_fused_runs(tmp_path):
    from smokyslam.evaluation.compare_table import CompareRow, RunStatus
    from smokyslam.smoke import parse_smoke
    from smokyslam.sweep.results import SweepRow, write_summary
    from smokyslam.sweep.spec import World

    def fused(seed, radar_m, camera_m, used):
        metrics = {
            "trajectory": {"ate_rmse_m": 0.1},
            "camera_pairs": {"used": used, "inconsistent": 100 - used},
            "step_errors": {
                "pairs": 100,
                "radar": {"translation_rms_m": radar_m, "yaw_rms_deg": 0.2},
                "camera": {"translation_rms_m": camera_m, "yaw_rms_deg": 0.5},
            },
        }
        row = CompareRow("fused", parse_smoke("0.1:0.2"), tmp_path, RunStatus.OK, "", metrics)
        return SweepRow(World(f"office-{seed}", "office", seed), "default", row)

    rows = [fused(1, 0.005, 0.040, 30), fused(2, 0.007, 0.050, 20), fused(3, 0.006, 0.030, 40)]
    summary = write_summary(rows, tmp_path, "steps").read_text()
    assert "## Per-step precision of the fused runs' two sources" in summary
    assert "| r0.1-c0.2 | office | default | 3 | 6.00 | 40.00 | 0.20 | 0.50 | 30% |" in summary
