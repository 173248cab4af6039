"""``smokyslam compare``: level parsing, the run folders, the table and plots, failed runs."""

import csv
import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from test_rerun_recorder import rows_per_entity

from smokyslam.config import load_config
from smokyslam.errors import (
    ConfigError,
    EstimationError,
    LogError,
    OutputError,
    RunInterruptedError,
)
from smokyslam.evaluation.compare_plot import run_paths
from smokyslam.evaluation.compare_table import CompareRow, RunStatus
from smokyslam.evaluation.trajectory_io import write_tum
from smokyslam.pipelines import jobs as jobs_module
from smokyslam.pipelines.compare import compare, parse_smoke_levels, parse_sources
from smokyslam.pipelines.jobs import CompareJob, run_job, run_jobs
from smokyslam.pipelines.run import run_log
from smokyslam.smoke import SmokeLevel

HEADER = [
    "source",
    "radar_loss",
    "camera_noise",
    "haze",
    "ate_rmse_m",
    "ate_alignment",
    "drift_pct",
    "lost_frames",
    "realtime_factor",
    "map",
    "map_error_index",
    "map_f1",
    "ate_sim2_rmse_m",
    "status",
    "error",
]


def test_smoke_levels_keep_the_numbers_as_typed():
    levels = parse_smoke_levels("0:0, 0.1:0.2,0.2:0.40")
    assert [level.label for level in levels] == ["r0-c0", "r0.1-c0.2", "r0.2-c0.40"]
    assert [(lv.radar_loss, lv.camera_noise, lv.haze) for lv in levels] == [
        (0.0, 0.0, 0.0),
        (0.1, 0.2, 0.0),
        (0.2, 0.4, 0.0),
    ]


def test_levels_take_haze_in_the_smoke_notation_too():
    levels = parse_smoke_levels("0:0,0.1:0.2:0.5,0.1:0.2")
    assert [level.label for level in levels] == ["r0-c0", "r0.1-c0.2-h0.5", "r0.1-c0.2"]
    # --haze crosses the levels given without a haze of their own
    crossed = parse_smoke_levels("0:0,0.1:0.2:0.5", "0.3")
    assert [level.label for level in crossed] == ["r0-c0", "r0.1-c0.2-h0.5", "r0-c0-h0.3"]


def test_haze_values_add_hazy_copies_of_every_smoke_level():
    levels = parse_smoke_levels("0:0,0.2:0.4", "0,0.5")  # 0 is the haze-free run
    assert [level.label for level in levels] == [
        "r0-c0",
        "r0.2-c0.4",
        "r0-c0-h0.5",
        "r0.2-c0.4-h0.5",
    ]
    config = load_config(None, {"smoke": {"airlight": 150.0, "haze": 0.3}})
    hazy = levels[3].apply(config).smoke
    assert (hazy.radar_loss, hazy.camera_noise, hazy.haze, hazy.airlight) == (0.2, 0.4, 0.5, 150.0)
    assert levels[0].apply(config).smoke.haze == 0.0
    assert config.smoke.haze == 0.3  # the base config is left alone


@pytest.mark.parametrize(
    ("smoke", "haze", "message"),
    [
        ("0.1", None, "radar_loss:camera_noise"),
        ("0:0:0:0", None, "radar_loss:camera_noise"),
        ("0:0:x", None, "haze in '0:0:x' is not a number"),
        ("a:b", None, "radar_loss in 'a:b' is not a number"),
        ("-1:0", None, "radar_loss in '-1:0' must be between 0 and 1"),
        ("2:0", None, "radar_loss in '2:0' must be between 0 and 1"),
        ("0:1.5", None, "camera_noise in '0:1.5' must be between 0 and 1"),
        ("nan:0", None, "must be between 0 and 1"),
        ("1e-1:0", None, "plain decimal"),
        ("0:0,,0.1:0.2", None, "empty items"),
        ("", None, "empty items"),
        ("0:0,0.0:0", None, "r0.0-c0 repeats r0-c0"),
        ("0:0", "-0.5", "haze in '-0.5' must be 0 or more"),
        ("0:0", "thick", "haze in 'thick' is not a number"),
        ("0:0", "0.5,0.50", "repeats"),
    ],
)
def test_bad_smoke_and_haze_items_are_config_errors(smoke, haze, message):
    with pytest.raises(ConfigError, match=message):
        parse_smoke_levels(smoke, haze)


def test_sources_must_be_registered_and_distinct():
    assert parse_sources("radar, dead-reckoning") == ["radar", "dead-reckoning"]
    with pytest.raises(ConfigError, match="unknown odometry source 'lidar': choose from radar"):
        parse_sources("radar,lidar")
    with pytest.raises(ConfigError, match="twice"):
        parse_sources("radar,radar")


def test_the_main_map_is_visual_for_camera_and_fused_before_radar_otherwise():
    maps = {name: {"error_index": 0.1, "occupied_f1": 0.5} for name in ("radar_sparse", "fused")}
    level = SmokeLevel("0", "0")
    assert (
        CompareRow("fused", level, Path("x"), RunStatus.OK, metrics={"maps": maps}).main_map()
        == "fused"
    )
    camera_maps = {"visual": maps["fused"], "radar_sparse": maps["fused"]}
    camera = CompareRow("camera", level, Path("x"), RunStatus.OK, metrics={"maps": camera_maps})
    assert camera.main_map() == "visual"
    assert CompareRow("radar", level, Path("x"), RunStatus.FAILED, "boom").main_map() is None


def _coloured_pixels(png: Path, rgb: tuple[int, int, int]) -> int:
    image = cv2.imread(str(png))[:, :, ::-1].astype(int)
    return int(np.count_nonzero(np.abs(image - np.array(rgb)).max(axis=2) <= 30))


def test_compare_writes_every_file_and_reports_a_failed_run(office_log, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    out = tmp_path / "cmp"
    # A file where one run's folder must go: that run fails inside its worker process.
    (out / "runs").mkdir(parents=True)
    (out / "runs" / "dead-reckoning-r0.1-c0.2").write_text("in the way")
    config = load_config()
    calls = []
    result = compare(
        office_log,
        ["radar", "dead-reckoning"],
        parse_smoke_levels("0:0,0.1:0.2"),
        config,
        out,
        workers=2,
        on_progress=lambda done, total, status="": calls.append((done, total)),
        rerun_path=out / "compare.rrd",
    )
    assert sorted(p.name for p in (out / "runs").iterdir()) == [
        "dead-reckoning-r0-c0",
        "dead-reckoning-r0.1-c0.2",
        "radar-r0-c0",
        "radar-r0.1-c0.2",
    ]
    assert calls[-1] == (4, 4) and len(calls) == 4
    assert [(r.source, r.level.label, r.status) for r in result.rows] == [
        ("radar", "r0-c0", "ok"),
        ("dead-reckoning", "r0-c0", "ok"),
        ("radar", "r0.1-c0.2", "ok"),
        ("dead-reckoning", "r0.1-c0.2", "failed"),
    ]
    # Raised and caught in the worker: the message names the folder that was in the way.
    assert result.failed[0].error.endswith("dead-reckoning-r0.1-c0.2: exists and is not a folder")

    with result.csv_path.open() as stream:
        table = list(csv.reader(stream))
    assert table[0] == HEADER
    rows = [dict(zip(HEADER, values, strict=True)) for values in table[1:]]
    assert len(rows) == 4
    for row, run in zip(rows[:3], result.rows[:3], strict=True):
        metrics = json.loads((run.run_dir / "metrics.json").read_text())
        trajectory, radar_map = metrics["trajectory"], metrics["maps"]["radar_sparse"]
        assert float(row["ate_rmse_m"]) == trajectory["ate_rmse_m"]
        assert float(row["drift_pct"]) == trajectory["drift_pct"]
        assert int(row["lost_frames"]) == trajectory["lost_frames"]
        assert float(row["realtime_factor"]) == metrics["realtime_factor"]
        assert float(row["map_error_index"]) == radar_map["error_index"]
        assert float(row["map_f1"]) == radar_map["occupied_f1"]
        assert (row["ate_alignment"], row["map"], row["status"]) == ("se2", "radar_sparse", "ok")
        assert 0.005 < trajectory["ate_rmse_m"] < 0.5
        smoke = load_config(run.run_dir / "config.yaml").smoke
        assert (smoke.radar_loss, smoke.camera_noise) == (
            run.level.radar_loss,
            run.level.camera_noise,
        )
    assert (rows[2]["radar_loss"], rows[2]["camera_noise"], rows[2]["haze"]) == ("0.1", "0.2", "0")
    # Dropping 10% of the radar returns changes radar odometry's answer.
    assert rows[0]["ate_rmse_m"] != rows[2]["ate_rmse_m"]
    failed = rows[3]
    assert failed["status"] == "failed" and "is not a folder" in failed["error"]
    assert failed["ate_rmse_m"] == "" and failed["map"] == ""

    markdown = result.markdown_path.read_text().splitlines()
    assert len(markdown) == 6 and markdown[0] == "| " + " | ".join(HEADER) + " |"
    assert "| failed | --out " in markdown[5]
    assert load_config(result.config_path) == config

    # Every finished run's path in one recording, side by side, with its error over time.
    recorded = rows_per_entity(out / "compare.rrd")
    for run in result.rows[:3]:
        name = run.run_dir.name
        assert recorded[f"/world/position/{name}"] == 301 + 1  # a point per frame, its style
        assert recorded[f"/error/{name}"] == 301 + 1
        assert f"/world/trajectory/{name}" in recorded
    assert not any("dead-reckoning-r0.1" in entity for entity in recorded)
    assert {"/world/ground_truth/map", "/world/ground_truth/path"} <= set(recorded)

    for png in (result.trajectories_png, result.ate_png):
        assert min(cv2.imread(str(png)).shape[:2]) >= 300
        assert _coloured_pixels(png, (214, 39, 40)) > 200  # radar, tab:red
        assert _coloured_pixels(png, (255, 127, 14)) > 100  # dead reckoning, tab:orange


def _failing_run(log_path, source, config, run_dir, **options):
    if source == "broken":
        raise EstimationError("the pose graph is degenerate")
    return {}["missing"]  # a bug, not a SmokySlamError


def test_a_run_that_raises_becomes_a_failed_row(office_log, tmp_path, monkeypatch):
    monkeypatch.setattr(jobs_module, "run_log", _failing_run)
    level = SmokeLevel("0.1", "0.2")
    job = CompareJob("broken", level, office_log, load_config(), tmp_path / "broken-r0.1-c0.2")
    row = run_job(job)
    assert (row.status, row.error, row.metrics) == ("failed", "the pose graph is degenerate", {})
    assert "EstimationError" in (job.run_dir / "error.log").read_text()
    # One worker runs the jobs here, in order; a bug that is no SmokySlamError is named by type.
    buggy = CompareJob("buggy", level, office_log, load_config(), tmp_path / "buggy-r0.1-c0.2")
    progress = []
    rows, interrupted = run_jobs(
        [buggy, job], 1, lambda done, total, status="": progress.append(status)
    )
    assert not interrupted
    assert [(r.source, r.error) for r in rows] == [
        ("buggy", "KeyError: 'missing'"),
        ("broken", "the pose graph is degenerate"),
    ]
    assert progress == ["buggy-r0.1-c0.2 failed", "broken-r0.1-c0.2 failed"]


def test_a_missing_log_fails_before_any_run(tmp_path):
    with pytest.raises(LogError, match="log not found"):
        compare(
            tmp_path / "none.mcap",
            ["radar"],
            parse_smoke_levels("0:0"),
            load_config(),
            tmp_path / "out",
        )
    assert not (tmp_path / "out").exists()


def test_plots_read_the_paths_as_the_runs_wrote_them(tmp_path):
    stamps_s = np.linspace(0.0, 10.0, 50)
    gt = np.column_stack([np.cos(stamps_s / 3), np.sin(stamps_s / 2), stamps_s / 5]) * 4.0
    estimate = gt + np.array([0.05, -0.02, 0.0])  # in the ground-truth frame, as runs write
    write_tum(tmp_path / "ground_truth.tum", stamps_s, gt)
    write_tum(tmp_path / "trajectory.tum", stamps_s, estimate)
    row = CompareRow("camera", SmokeLevel("0", "0"), tmp_path, RunStatus.OK)
    poses, truth = run_paths(row)
    np.testing.assert_allclose(poses[:, :2], estimate[:, :2], atol=1e-6)
    np.testing.assert_allclose(truth[:, :2], gt[:, :2], atol=1e-6)
    (tmp_path / "ground_truth.tum").unlink()
    assert run_paths(row)[1] is None


def test_a_finished_comparison_is_not_overwritten_by_accident(office_log, tmp_path):
    out = tmp_path / "cmp"
    out.mkdir()
    (out / "compare.csv").write_text("source\n")
    (out / "notes.txt").write_text("mine")
    levels = parse_smoke_levels("0:0")
    with pytest.raises(OutputError, match="--overwrite"):
        compare(office_log, ["dead-reckoning"], levels, load_config(), out, workers=1)
    result = compare(
        office_log, ["dead-reckoning"], levels, load_config(), out, workers=1, overwrite=True
    )
    assert [row.status for row in result.rows] == ["ok"]
    assert (out / "notes.txt").read_text() == "mine"  # only the comparison's own files go


def test_compare_runs_on_an_existing_dask_scheduler(office_log, tmp_path):
    from dask.distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster,
        Client(cluster) as client,
    ):
        result = compare(
            office_log,
            ["dead-reckoning"],
            parse_smoke_levels("0:0"),
            load_config(),
            tmp_path / "cmp",
            scheduler=cluster.scheduler_address,
        )
        prefixes = client.run_on_scheduler(
            lambda dask_scheduler: list(dask_scheduler.task_prefixes)
        )
    assert [(r.source, r.status) for r in result.rows] == [("dead-reckoning", "ok")]
    assert 0.005 < result.rows[0].metrics["trajectory"]["ate_rmse_m"] < 0.5
    assert prefixes == ["run-dead-reckoning"]  # the run was a task of that cluster


def test_a_stopped_run_keeps_what_it_computed(office_log, tmp_path):
    asked = []

    def should_stop() -> bool:  # what a batch's StopFlag answers once its Event is set
        asked.append(True)
        return len(asked) > 400

    with pytest.raises(RunInterruptedError):
        run_log(office_log, "radar", load_config(), tmp_path / "radar", should_stop=should_stop)
    metrics = json.loads((tmp_path / "radar" / "metrics.json").read_text())
    assert metrics["interrupted"] is True and 0 < metrics["trajectory"]["frames"] < 301
    assert len(np.loadtxt(tmp_path / "radar" / "trajectory.tum")) == metrics["trajectory"]["frames"]


def _flag_seen(name: str) -> tuple[bool, bool]:
    """In a task: the batch's flag before and after the Event is set (from inside)."""
    from dask.distributed import Event

    from smokyslam.pipelines.executor import StopFlag

    flag = StopFlag(name)
    before = flag()
    Event(name).set()
    time.sleep(0.3)  # the flag asks the scheduler at most every 0.2 s
    return before, flag()


def test_a_batch_s_stop_flag_reaches_its_tasks_and_queued_jobs_do_not_start(office_log, tmp_path):
    from dask.distributed import Client, LocalCluster

    from smokyslam.pipelines.executor import new_stop_name

    stop = new_stop_name()
    job = CompareJob("radar", SmokeLevel("0", "0"), office_log, load_config(), tmp_path / "r", stop)
    with (
        LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster,
        Client(cluster) as client,
    ):
        seen = client.submit(_flag_seen, stop, pure=False).result(timeout=30)
        never = client.submit(run_job, job, pure=False).result(timeout=30)
    assert seen == (False, True)
    assert (never.status, never.error) == ("interrupted", "not run")
    assert not job.run_dir.exists()
