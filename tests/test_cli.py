"""The command line: contracts checked from outside, and one clear line for bad input."""

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from sim_scenes import write_robot_floorplan

from smokyslam.config import load_config
from smokyslam.frontends.readers.registry import open_log

REPO = Path(__file__).resolve().parents[1]


def smokyslam(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
    )


def test_version_and_help_on_every_command():
    out = smokyslam("--version")
    assert out.returncode == 0 and out.stdout.startswith("smokyslam ")
    commands = [
        "simulate",
        "info",
        "run",
        "compare",
        "map",
        "evaluate",
        "bench",
        "demo",
        "dump-config",
        "view",
        "paper-table",
        "upsample",
        "register",
        "fuse",
    ]
    for command in commands:
        assert smokyslam(command, "--help").returncode == 0, command


def test_info_reports_topics_types_counts_and_duration(office_log):
    out = smokyslam("info", office_log)
    assert out.returncode == 0, out.stderr
    lines = {line.split()[0]: line.split() for line in out.stdout.splitlines() if line[:1] == "/"}
    assert lines["/ti_mmwave/radar_scan_pcl"][1:3] == ["sensor_msgs/msg/PointCloud2", "301"]
    assert lines["/camera/image_raw"][1:3] == ["sensor_msgs/msg/Image", "451"]
    assert float(lines["/imu"][3]) == pytest.approx(100.0, rel=0.02)
    assert float(lines["/ground_truth/pose"][3]) == pytest.approx(50.0, rel=0.02)
    assert lines["/ground_truth/map"][1:3] == ["nav_msgs/msg/OccupancyGrid", "1"]
    assert "/tf_static" in lines and "/camera/camera_info" in lines
    assert "duration: 30.0" in out.stdout


def test_info_on_the_real_ti_bag(real_data_dir):
    out = smokyslam("info", real_data_dir / "ti_mmwave_rospkg_demo.bag")
    assert out.returncode == 0, out.stderr
    assert any(
        line.startswith("/ti_mmwave/radar_scan_pcl") and " 412 " in line
        for line in out.stdout.splitlines()
    )


def _independent_error_index(map_yaml: Path, truth_cells: np.ndarray, truth_spec) -> float:
    """Eq. 2 from the files alone: PGM pixels -> 1 / 0 / 0.5, sampled at truth cell centres."""
    meta = yaml.safe_load(map_yaml.read_text())
    pixels = cv2.imread(str(map_yaml.parent / meta["image"]), cv2.IMREAD_GRAYSCALE)
    occupancy = (255.0 - pixels) / 255.0
    value = np.full(pixels.shape, 0.5)
    value[occupancy > meta["occupied_thresh"]] = 1.0
    value[occupancy < meta["free_thresh"]] = 0.0
    rows, cols = truth_cells.shape
    iy, ix = np.mgrid[0:rows, 0:cols]
    x = truth_spec.origin_xy_m[0] + (ix + 0.5) * truth_spec.resolution_m
    y = truth_spec.origin_xy_m[1] + (iy + 0.5) * truth_spec.resolution_m
    col = np.floor((x - meta["origin"][0]) / meta["resolution"]).astype(int)
    row_from_bottom = np.floor((y - meta["origin"][1]) / meta["resolution"]).astype(int)
    row = pixels.shape[0] - 1 - row_from_bottom
    inside = (col >= 0) & (col < pixels.shape[1]) & (row >= 0) & (row < pixels.shape[0])
    estimate = np.full(truth_cells.shape, 0.5)
    estimate[inside] = value[row[inside], col[inside]]
    truth = np.where(truth_cells == 100, 1.0, 0.0)
    known = truth_cells != -1
    return float(np.mean((truth[known] - estimate[known]) ** 2))


def test_map_contract_and_error_index_rising_with_radar_loss(office_log, tmp_path):
    reader = open_log(office_log, load_config())
    truth, observed = reader.ground_truth_map(), reader.observed_ground_truth_map()
    # A 30 s walk sees part of the building: the observed truth knows less than the full one.
    assert 0.2 < (observed.cells != -1).sum() / (truth.cells != -1).sum() < 0.9
    scores = []
    for loss in ("0", "0.1", "0.2"):
        out_dir = tmp_path / f"map-{loss}"
        out = smokyslam(
            "map", office_log, "--poses", "ground-truth", "--radar-loss", loss, "--out", out_dir
        )
        assert out.returncode == 0, out.stderr
        for name in ("maps/radar_sparse.pgm", "maps/radar_sparse.yaml", "config.yaml"):
            assert (out_dir / name).is_file(), name
        assert load_config(out_dir / "config.yaml").smoke.radar_loss == float(loss)
        sparse = json.loads((out_dir / "metrics.json").read_text())["maps"]["radar_sparse"]
        five = {
            "error_index",
            "occupied_precision",
            "occupied_recall",
            "occupied_f1",
            "occupied_iou",
        }
        assert set(sparse) == five | {"observed"} and set(sparse["observed"]) == five
        for got, true_map in ((sparse, truth), (sparse["observed"], observed)):
            independent = _independent_error_index(
                out_dir / "maps/radar_sparse.yaml", true_map.cells, true_map.spec
            )
            assert got["error_index"] == pytest.approx(independent, abs=0.02)
        scores.append(sparse)
    assert scores[0]["error_index"] < 0.35
    assert scores[0]["occupied_precision"] >= 0.6
    assert scores[0]["error_index"] < scores[1]["error_index"] < scores[2]["error_index"]


def test_evaluate_scores_a_saved_map_against_log_and_map_truth(office_log, tmp_path):
    out_dir = tmp_path / "map"
    assert smokyslam("map", office_log, "--out", out_dir).returncode == 0
    expected = json.loads((out_dir / "metrics.json").read_text())["maps"]["radar_sparse"]
    map_yaml = out_dir / "maps/radar_sparse.yaml"
    out = smokyslam("evaluate", map_yaml, "--truth", office_log, "--out", tmp_path / "m.json")
    assert out.returncode == 0, out.stderr
    scored = json.loads((tmp_path / "m.json").read_text())
    assert scored.pop("observed") == pytest.approx(expected.pop("observed"))
    assert scored == pytest.approx(expected)
    assert "observed truth:" in out.stdout
    # A map scored against itself is perfect on its known cells.
    self_scores = smokyslam("evaluate", map_yaml, "--truth", map_yaml, "--out", tmp_path / "s.json")
    assert self_scores.returncode == 0, self_scores.stderr
    assert json.loads((tmp_path / "s.json").read_text())["occupied_f1"] == pytest.approx(1.0)


def test_a_floor_plan_as_truth_has_the_walls_it_implies(tmp_path):
    """A plan that draws no walls scores a radar map of a walk through it by the edge of its
    free space, as the log's own truth does. Measured: occupied F1 0.48 against the plan (0.66
    against the log, on its coarser grid); 0.09 with the plan's unknown taken as unobserved."""
    plan = write_robot_floorplan(tmp_path / "bare.yaml", walls=False)
    walk = tmp_path / "walk.mcap"
    out = smokyslam("simulate", "--world", plan, "--seed", "3", "--duration", "30",
                    "--sensors", "radar,imu", "--out", walk)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert smokyslam("map", walk, "--out", tmp_path / "m").returncode == 0
    unobserved = tmp_path / "unobserved.yaml"
    unobserved.write_text(plan.read_text() + "unknown: unobserved\n")
    f1 = {}
    for truth in (walk, plan, unobserved):
        scored = tmp_path / f"{truth.stem}.json"
        args = ("evaluate", tmp_path / "m/maps/radar_sparse.yaml", "--truth", truth, "--out")
        assert smokyslam(*args, scored).returncode == 0
        f1[truth.stem] = json.loads(scored.read_text())["occupied_f1"]
    assert f1["bare"] > 0.35 and f1["walk"] > 0.5
    assert f1["unobserved"] < 0.2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["info", "{tmp}/missing.mcap"], "not found"),
        (["info", "{tmp}/notes.bag"], "not a ROS1 bag"),
        (["info", "{tmp}/stub.mcap"], "truncated or corrupt"),
        (["map", "{tmp}/nomap.bag", "--out", "{tmp}/o"], "ground_truth_pose"),
        (["dump-config", "--config", "{tmp}/bad.yaml"], "unknown config key 'smoke.radar_los'"),
        (["simulate", "--world", "castle", "--out", "{tmp}/x.mcap"], "castle"),
        (["evaluate", "{tmp}/broken.yaml", "--truth", "{tmp}/broken.yaml"], "map image not found"),
    ],
)
def test_bad_input_gets_one_clear_line_and_exit_1(args, message, tmp_path, office_log):
    (tmp_path / "notes.bag").write_text("these are not radar data\n")
    data = office_log.read_bytes()
    (tmp_path / "stub.mcap").write_bytes(data[:300])
    (tmp_path / "bad.yaml").write_text("smoke:\n  radar_los: 0.1\n")
    (tmp_path / "broken.yaml").write_text("image: gone.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    _radar_only_bag(tmp_path / "nomap.bag")
    out = smokyslam(*[a.format(tmp=tmp_path) for a in args])
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], out.stderr


def _radar_only_bag(path: Path) -> None:
    from smokyslam.config import TopicsConfig
    from smokyslam.sim.recorder import LogWriter
    from smokyslam.types import RadarScan

    with LogWriter(path, TopicsConfig()) as writer:
        for i in range(3):
            points = np.array([[2.0, 0.1 * i, 0.0]])
            writer.write_radar(RadarScan(0.1 * i, points, np.ones(1), np.zeros(1)))


def test_simulate_a_floor_plan_and_a_ros1_bag(tmp_path):
    from smokyslam.geometry import GridSpec
    from smokyslam.mapio import save_map

    cells = np.zeros((80, 120), dtype=np.int8)
    cells[[0, -1], :] = 100
    cells[:, [0, -1]] = 100
    cells[:, 60] = 100
    cells[35:45, 60] = 0  # a 1 m doorway between two rooms
    plan = save_map(tmp_path / "plan.yaml", cells, GridSpec((0.0, 0.0), 0.1, cells.shape))
    log = tmp_path / "plan.bag"
    out = smokyslam("simulate", "--world", plan, "--duration", "10", "--seed", "1", "--out", log)
    assert out.returncode == 0, out.stderr
    reader = open_log(log, load_config())
    truth = reader.ground_truth_map()
    assert truth.cells.shape[0] >= 80 and truth.cells.shape[1] >= 120
    assert reader.summary().format.startswith("ROS1")
    counts = {s.topic: s.count for s in reader.summary().streams}
    assert counts["/ti_mmwave/radar_scan_pcl"] == 101
    # Without the camera: the same radar, no images, the same truths.
    fast = tmp_path / "fast.bag"
    args = ("--world", plan, "--duration", "10", "--seed", "1", "--out", fast)
    assert smokyslam("simulate", *args, "--sensors", "radar,imu").returncode == 0
    quick = open_log(fast, load_config())
    assert "/camera/image_raw" not in {s.topic for s in quick.summary().streams}
    scans = [f for f in reader.frames(("radar",))]
    assert all(
        np.array_equal(a.points_xyz_m, b.points_xyz_m)
        for a, b in zip(scans, quick.frames(("radar",)), strict=True)
    )
    assert np.array_equal(
        quick.observed_ground_truth_map().cells, reader.observed_ground_truth_map().cells
    )


def test_ti_bag_runs_radar_only_with_its_calibration(real_data_dir, tmp_path):
    """No ground truth: the trajectory is written; with the calibration applied, scan matching
    and the Doppler/gyro dead reckoning agree (measured 0.08 m apart; 0.86 m without it)."""
    from smokyslam.evaluation.trajectory_io import read_tum
    from smokyslam.evaluation.trajectory_metrics import evaluate_trajectory

    bag = real_data_dir / "ti_mmwave_rospkg_demo.bag"
    calibration = real_data_dir / "ti_mmwave_rospkg_demo.calib.yaml"
    poses = {}
    for source in ("radar", "dead-reckoning"):
        out_dir = tmp_path / source
        args = ("run", bag, "--odometry", source, "--calibration", calibration, "--out", out_dir)
        out = smokyslam(*args)
        assert out.returncode == 0, out.stderr
        assert not (out_dir / "ground_truth.tum").exists()
        config = yaml.safe_load((out_dir / "config.yaml").read_text())
        assert config["rig"]["calibration"] == str(calibration.resolve())
        poses[source] = read_tum(out_dir / "trajectory.tum")
    stamps, radar = poses["radar"]
    assert len(stamps) == 412
    agreement = evaluate_trajectory(stamps, radar, *poses["dead-reckoning"], alignment="se2")
    assert agreement.ate_rmse_m < 0.3


def test_smoke_notation_equals_the_single_options(office_log, tmp_path):
    runs = {}
    for name, smoke in (
        ("notation", ["--smoke", "0.1:0.2:0.5"]),
        ("aliases", ["--radar-loss", "0.1", "--camera-noise", "0.2", "--haze", "0.5"]),
    ):
        out_dir = tmp_path / name
        out = smokyslam("run", office_log, "--odometry", "radar", *smoke, "--out", out_dir)
        assert out.returncode == 0, out.stderr
        runs[name] = out_dir
    smoke = load_config(runs["notation"] / "config.yaml").smoke
    assert (smoke.radar_loss, smoke.camera_noise, smoke.haze) == (0.1, 0.2, 0.5)
    assert load_config(runs["aliases"] / "config.yaml") == load_config(
        runs["notation"] / "config.yaml"
    )
    trajectories = [(d / "trajectory.tum").read_text() for d in runs.values()]
    assert trajectories[0] == trajectories[1]
    info = smokyslam("info", office_log, "--smoke", "0.1:0.2:0.5")
    assert info.returncode == 0 and "smoke at replay: 0.1:0.2:0.5" in info.stdout


def test_a_folder_holding_a_run_is_refused_without_overwrite(office_log, tmp_path):
    out_dir = tmp_path / "run"
    first = smokyslam("run", office_log, "--odometry", "camera", "--out", out_dir)
    assert first.returncode == 0, first.stderr
    assert (out_dir / "maps/visual.pgm").is_file()
    (out_dir / "notes.txt").write_text("mine")
    again = smokyslam("run", office_log, "--odometry", "dead-reckoning", "--out", out_dir)
    assert again.returncode == 1 and "Traceback" not in again.stderr
    lines = again.stderr.strip().splitlines()
    assert len(lines) == 1 and "holds an earlier run" in lines[0] and "--overwrite" in lines[0]
    replaced = smokyslam(
        "run", office_log, "--odometry", "dead-reckoning", "--out", out_dir, "--overwrite"
    )
    assert replaced.returncode == 0, replaced.stderr
    metrics = json.loads((out_dir / "metrics.json").read_text())
    assert metrics["odometry"]["source"] == "dead-reckoning" and set(metrics["maps"]) == {
        "radar_sparse",
        "radar_dense",
    }
    assert not (out_dir / "maps/visual.pgm").exists()  # nothing of the camera run survives
    assert (out_dir / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--smoke", "0.1:0.2", "--radar-loss", "0.1"], "not both"),
        (["--smoke", "0.1"], "radar_loss:camera_noise[:haze]"),
        (["--smoke", "0.1:2"], "camera_noise in '0.1:2' must be between 0 and 1"),
    ],
)
def test_bad_smoke_options_are_one_clear_line(office_log, tmp_path, args, message):
    out = smokyslam("run", office_log, *args, "--out", tmp_path / "x")
    assert out.returncode == 1 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], out.stderr
    assert not (tmp_path / "x").exists()
