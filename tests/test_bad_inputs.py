"""Bad input never crashes a run and nothing computed is lost (issue 10).

Each case is a log crafted from a short simulated one (``crafted_logs.py``), run through the
real command line: the exit code, one clear line on stderr and no traceback, and what the run
kept (``metrics.json``, map files) are checked.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from crafted_logs import every_nth, float32_points, nan_field, point_cloud_fields, rewrite

from smokyslam.config import load_config


def smokyslam(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=600,
    )


def one_clear_error(out: subprocess.CompletedProcess, message: str) -> None:
    assert out.returncode == 1 and "Traceback" not in out.stderr, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines


def ran(out: subprocess.CompletedProcess) -> None:
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr


def metrics(folder: Path) -> dict:
    return json.loads((folder / "metrics.json").read_text())


@pytest.fixture(scope="module")
def corridor(tmp_path_factory) -> Path:
    """The 15 s corridor walk the crafted cases start from."""
    from smokyslam.sim.simulate import simulate

    path = tmp_path_factory.mktemp("bad") / "corridor15.mcap"
    simulate("corridor", 15.0, 1, path, load_config())
    return path


def crafted(corridor: Path, name: str, edit) -> Path:
    path = corridor.parent / f"{name}.mcap"
    return path if path.exists() else rewrite(corridor, path, edit)


def nth(topic: str, k: int, change):
    """An edit changing only the ``k``-th message of ``topic`` (from 1)."""
    seen = {"count": 0}

    def edit(msg_topic, msg, log_ns):
        if msg_topic == topic:
            seen["count"] += 1
            if seen["count"] == k:
                return change(msg)
        return msg

    return edit


# ---------------------------------------------------------------- non-finite values


def test_one_nan_gyro_sample_is_dropped_and_counted(corridor, tmp_path):
    log = crafted(
        corridor, "nan_gyro", nth("/imu", 700, lambda m: nan_field(m, "angular_velocity.z"))
    )
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path)
    ran(out)
    assert "1 IMU samples with NaN/inf values dropped" in out.stderr
    assert metrics(tmp_path)["log"]["imu_nonfinite"] == 1
    assert metrics(tmp_path)["trajectory"]["ate_rmse_m"] < 0.05


def test_one_nan_ground_truth_pose_leaves_the_metrics_whole(corridor, tmp_path):
    log = crafted(
        corridor,
        "nan_gt",
        nth("/ground_truth/pose", 300, lambda m: nan_field(m, "pose.position.x")),
    )
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path)
    ran(out)
    assert "ground-truth poses with NaN/inf values or malformed dropped" in out.stderr
    trajectory = metrics(tmp_path)["trajectory"]
    assert all(trajectory[key] is not None for key in ("ate_rmse_m", "drift_pct", "frames"))
    assert "ATE " in out.stdout


@pytest.mark.parametrize("quaternion", [(float("nan"), 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 0.0)])
def test_an_unusable_static_transform_is_one_clear_error(corridor, tmp_path, quaternion):
    def broken(msg):
        for stamped in msg.transforms:
            r = stamped.transform.rotation
            r.x, r.y, r.z, r.w = quaternion
        return msg

    name = "tf_nan" if np.isnan(quaternion[0]) else "tf_zero"
    log = crafted(corridor, name, every_nth("/tf_static", 1, broken))
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path / "run")
    one_clear_error(out, "/tf_static: the static transform base_link -> radar cannot be used")
    assert "run failed" in (tmp_path / "run" / "run.log").read_text()  # the error is kept


def test_all_nan_radar_scans_give_an_empty_map_not_a_crash(corridor, tmp_path):
    nan_x = every_nth("/ti_mmwave/radar_scan_pcl", 1, lambda m: float32_points(m, 0, np.nan))
    out = smokyslam(
        "run", crafted(corridor, "nan_radar", nan_x), "--odometry", "radar", "--out", tmp_path
    )
    ran(out)
    kept = metrics(tmp_path)
    assert kept["empty_maps"] == ["radar_sparse", "radar_dense"] and "maps" not in kept
    assert kept["trajectory"]["lost_frames"] == kept["trajectory"]["frames"] == 151
    assert (tmp_path / "trajectory.tum").is_file() and not (
        tmp_path / "maps/radar_sparse.pgm"
    ).exists()


def test_nan_velocities_leave_the_points_and_run_without_doppler(corridor, tmp_path):
    nan_v = every_nth("/ti_mmwave/radar_scan_pcl", 1, lambda m: float32_points(m, 4, np.nan))
    out = smokyslam(
        "run", crafted(corridor, "nan_v", nan_v), "--odometry", "radar", "--out", tmp_path
    )
    ran(out)
    kept = metrics(tmp_path)
    assert kept["log"]["radar_points_unknown_velocity"] > 5000
    # The points stay (the map is there), the run tracks on scan matching and the gyro:
    # measured 0.079 m (0.009 m with Doppler).
    assert "empty_maps" not in kept and kept["maps"]["radar_sparse"]["occupied_recall"] > 0.02
    assert kept["trajectory"]["ate_rmse_m"] < 0.15


def test_a_nan_map_resolution_leaves_the_map_out(corridor, tmp_path):
    def nan_resolution(msg):
        msg.info.resolution = float("nan")
        return msg

    log = crafted(corridor, "nan_map", every_nth("/ground_truth/map", 1, nan_resolution))
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path)
    ran(out)
    assert "ground-truth map at 0.00 s left out" in out.stderr
    assert "maps" not in metrics(tmp_path) and "trajectory" in metrics(tmp_path)


@pytest.mark.parametrize("smoke", ["1:0", "1:1"])
def test_losing_every_radar_return_is_a_result(corridor, tmp_path, smoke):
    out = smokyslam("run", corridor, "--odometry", "fused", "--smoke", smoke, "--out", tmp_path)
    ran(out)
    assert "radar_sparse" in metrics(tmp_path)["empty_maps"]
    assert smokyslam("map", corridor, "--smoke", smoke, "--out", tmp_path / "map").returncode == 0


def test_losing_every_radar_return_on_the_real_ti_bag(real_data_dir, tmp_path):
    bag = real_data_dir / "ti_mmwave_rospkg_demo.bag"
    ran(smokyslam("run", bag, "--odometry", "fused", "--radar-loss", "1", "--out", tmp_path))
    assert metrics(tmp_path)["empty_maps"] == ["radar_sparse", "radar_dense"]


# ---------------------------------------------------------------- sizes


def test_huge_scans_run_in_bounded_memory(corridor, tmp_path):
    counter = {"n": 0}

    def dense(topic, msg, log_ns):
        if topic == "/ti_mmwave/radar_scan_pcl":
            counter["n"] += 1
            if counter["n"] in (40, 90):
                n = 100_000 if counter["n"] == 40 else 20_000
                rng = np.random.default_rng(counter["n"])
                points = np.zeros((n, msg.point_step // 4), np.float32)
                r, a = rng.uniform(0.5, 10.0, n), rng.uniform(-1.0, 1.0, n)
                points[:, 0], points[:, 1] = r * np.cos(a), r * np.sin(a)
                msg.width, msg.row_step = n, n * msg.point_step
                msg.data = np.frombuffer(points.tobytes(), np.uint8)
        return msg

    log = crafted(corridor, "dense", dense)
    out = subprocess.run(
        ["/usr/bin/time", "-f", "peak %M KB", sys.executable, "-m", "smokyslam.cli", "run", log,
         "--odometry", "radar", "--out", tmp_path],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    peak_kb = int(out.stderr.rsplit("peak ", 1)[1].split()[0])
    assert peak_kb < 1024 * 1024  # under 1 GB for the whole run
    assert metrics(tmp_path)["odometry"]["thinned_scans"] == 2


def test_camera_images_of_the_wrong_size_are_skipped(corridor, tmp_path):
    def half(msg):
        msg.width //= 2
        msg.step //= 2
        msg.data = msg.data[: msg.height * msg.step]
        return msg

    def empty(msg):
        msg.width = msg.height = msg.step = 0
        msg.data = msg.data[:0]
        return msg

    resized = every_nth("/camera/image_raw", 40, half)
    for name, edit, kind in (
        ("half", resized, "images_resized"),
        ("empty", every_nth("/camera/image_raw", 40, empty), "images_empty"),
    ):
        out_dir = tmp_path / name
        out = smokyslam("run", crafted(corridor, f"img_{name}", edit), "--out", out_dir)
        ran(out)
        assert metrics(out_dir)["log"][kind] == 6  # every 40th of 226 images
        assert "visual" in metrics(out_dir)["maps"]


# ---------------------------------------------------------------- paths and configs


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "{log}", "--out", "{file}"], "exists and is not a folder"),
        (["run", "{log}", "--out", "/proc/smokyslam/x"], "cannot write there"),
        (["run", "{log}", "--out", "{tmp}/r", "--rerun", "{tmp}"], "--rerun"),
        (["simulate", "--out", "{file}/x.mcap"], "exists and is not a folder"),
        (["map", "{log}", "--out", "{file}"], "exists and is not a folder"),
        (["compare", "{log}", "--out", "{file}"], "exists and is not a folder"),
        (["evaluate", "{map}", "--truth", "{log}", "--out", "{tmp}"], "is a folder"),
        (["dump-config", "-c", "{binary}"], "not a text (UTF-8) YAML file"),
        (["dump-config", "-c", "{infinite}"], "'mapping.resolution_m': Input should be a finite"),
        (["dump-config", "-c", "{thresholds}"], "must be above free_thresh"),
    ],
)
def test_bad_paths_and_configs_are_one_clear_line_before_any_work(
    corridor, tmp_path, args, message
):
    file = tmp_path / "a_file"
    file.write_text("in the way")
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe\x00binary")
    (tmp_path / "infinite.yaml").write_text("mapping:\n  resolution_m: .inf\n")
    (tmp_path / "thresholds.yaml").write_text("mapping:\n  occupied_thresh: 0.1\n")
    paths = {"log": corridor, "file": file, "tmp": tmp_path, "map": tmp_path / "m.yaml"}
    paths |= {name: tmp_path / f"{name}.yaml" for name in ("binary", "infinite", "thresholds")}
    one_clear_error(smokyslam(*[a.format(**paths) for a in args]), message)


def test_evaluating_a_map_of_another_place_is_an_error(corridor, tmp_path):
    import yaml

    ran(smokyslam("map", corridor, "--out", tmp_path / "map"))
    maps = tmp_path / "map" / "maps"
    meta = yaml.safe_load((maps / "radar_sparse.yaml").read_text())
    for name, change in (("far", {"origin": [1e6, 0.0, 0.0]}), ("tiny", {"resolution": 1e-9})):
        (maps / f"{name}.yaml").write_text(yaml.safe_dump({**meta, **change}))
        out = smokyslam("evaluate", maps / f"{name}.yaml", "--truth", corridor)
        one_clear_error(out, "does not overlap the ground truth")


# ---------------------------------------------------------------- silent wrong answers


def test_a_cloud_without_velocity_warns_and_tracks_on_scan_matching(office_log, tmp_path):
    log = rewrite(
        office_log,
        tmp_path / "no_velocity.mcap",
        every_nth("/ti_mmwave/radar_scan_pcl", 1, lambda m: point_cloud_fields(m, "velocity")),
    )
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path / "run")
    ran(out)
    assert "radar odometry runs without Doppler" in out.stderr
    # Measured: 0.092 m without Doppler (0.907 m coasting on zero velocity), 0.046 m with it.
    assert metrics(tmp_path / "run")["trajectory"]["ate_rmse_m"] < 0.15


@pytest.mark.parametrize(
    ("name", "shift_ns"), [("backwards", -5_000_000_000), ("gap", 3600 * 10**9)]
)
def test_log_time_jumps_are_reported_and_survived(corridor, tmp_path, name, shift_ns):
    start = {}

    def shifted(topic, msg, log_ns):
        start.setdefault("ns", log_ns)
        return (msg, log_ns + shift_ns) if log_ns - start["ns"] > 7e9 else msg

    out = smokyslam(
        "run", crafted(corridor, f"time_{name}", shifted), "--odometry", "radar", "--out", tmp_path
    )
    ran(out)
    words = "header stamps run" if name == "backwards" else "log time jumps 3600.1 s at 7.00 s"
    assert words in out.stderr
    assert metrics(tmp_path)["trajectory"]["ate_rmse_m"] < 0.05  # the clean log: 0.009 m


def test_carmen_logs_with_an_odd_first_line_and_absurd_lines(tmp_path):
    from radar_scenes import carmen_poses, write_carmen_log

    from smokyslam.frontends.readers.carmen import CarmenReader

    path = write_carmen_log(tmp_path / "room.log", carmen_poses(30), malformed=False)
    lines = path.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("FLASER"))
    absurd = "FLASER 180 " + " ".join(["1e9"] * 180) + " 0 0 0 0 0 0 1.0 host 1.0"
    lines.insert(first, "FLASER 90 " + " ".join(["1.0"] * 90) + " 0 0 0 0 0 0 0 host 0")
    lines.insert(first + 20, absurd)
    lines.insert(first + 40, absurd.replace(" 0 0 0 0 0 0 1.0", " 40 40 0 40 40 0 1.0"))
    (tmp_path / "odd.log").write_text("\n".join(lines) + "\n")
    reader = CarmenReader(tmp_path / "odd.log", load_config())
    assert len(reader.stamps_s) == 30 and reader.beams.bearings_rad.size == 180
    clean = smokyslam("run", path, "--odometry", "radar", "--out", tmp_path / "clean")
    odd = smokyslam("run", tmp_path / "odd.log", "--odometry", "radar", "--out", tmp_path / "odd")
    ran(clean), ran(odd)
    assert metrics(tmp_path / "odd")["trajectory"]["ate_rmse_m"] == pytest.approx(
        metrics(tmp_path / "clean")["trajectory"]["ate_rmse_m"], abs=1e-6
    )


def test_a_failed_run_leaves_its_error_in_run_log(tmp_path):
    bad = tmp_path / "bad.yaml"
    log = tmp_path / "empty.mcap"
    from smokyslam.config import TopicsConfig
    from smokyslam.sim.recorder import LogWriter

    with LogWriter(log, TopicsConfig()):
        pass
    bad.write_text("topics:\n  radar: [/nothing]\n")
    out = smokyslam("run", log, "--odometry", "radar", "--out", tmp_path / "run", "-c", bad)
    assert out.returncode == 1
    text = (tmp_path / "run" / "run.log").read_text()
    assert "run failed" in text and "no radar topic" in text
