"""A lidar point cloud as ground truth: its wall band flattened onto the map's grid."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from smokyslam.config import SmokySlamConfig
from smokyslam.mapio import save_map
from smokyslam.pipelines.evaluate_map import evaluate_map_file
from smokyslam.sim.world import box_world

o3d = pytest.importorskip("open3d")


def _write_room_cloud(path: Path, world, rng) -> None:
    """Walls of ``world`` sampled densely from floor to 2.5 m, plus a floor and a ceiling."""
    iy, ix = np.nonzero(world.occupied)
    centres = world.spec.centres_of(np.column_stack([ix, iy]))
    walls = np.repeat(centres, 20, axis=0) + rng.uniform(-0.04, 0.04, (20 * len(centres), 2))
    wall_z = rng.uniform(0.0, 2.5, len(walls))
    x0, x1, y0, y1 = world.spec.extent_m
    floor_xy = rng.uniform([x0 + 0.1, y0 + 0.1], [x1 - 0.1, y1 - 0.1], (20000, 2))
    floor = np.column_stack([floor_xy, np.where(np.arange(20000) % 2, 0.0, 2.5)])
    points = np.vstack([np.column_stack([walls, wall_z]), floor])
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    assert o3d.io.write_point_cloud(str(path), cloud)


@pytest.fixture()
def room(tmp_path):
    world = box_world(6.0, 4.0)
    cells = world.ground_truth_cells()
    map_yaml = save_map(tmp_path / "walls.yaml", cells, world.spec)
    rng = np.random.default_rng(0)
    for suffix in ("ply", "pcd"):
        _write_room_cloud(tmp_path / f"room.{suffix}", world, rng)
    return tmp_path, map_yaml, world


@pytest.mark.parametrize("suffix", ["ply", "pcd"])
def test_a_cloud_of_the_same_walls_scores_the_map_near_perfect(room, suffix):
    folder, map_yaml, _ = room
    scores = evaluate_map_file(
        map_yaml, folder / f"room.{suffix}", SmokySlamConfig(), z_band=(0.2, 2.0)
    )
    assert scores["error_index"] < 0.01
    assert scores["occupied_f1"] > 0.99 and scores["occupied_iou"] > 0.95


def test_without_a_band_floor_and_ceiling_count_as_walls(room):
    folder, map_yaml, _ = room
    scores = evaluate_map_file(map_yaml, folder / "room.ply", SmokySlamConfig())
    assert scores["error_index"] > 0.5 and scores["occupied_precision"] == pytest.approx(1.0)


def test_a_shifted_map_scores_worse(room, tmp_path):
    folder, _, world = room
    cells = np.roll(world.ground_truth_cells(), 3, axis=1)  # 0.3 m off
    shifted = save_map(tmp_path / "shifted.yaml", cells, world.spec)
    scores = evaluate_map_file(shifted, folder / "room.ply", SmokySlamConfig(), (0.2, 2.0))
    assert scores["error_index"] > 0.03 and scores["occupied_f1"] < 0.8


@pytest.mark.parametrize(
    ("truth", "band", "message"),
    [
        ("room.ply", "5:6", "no points in the z-band 5..6 m"),
        ("room.ply", "2:1", "--z-band needs finite LO < HI"),
        ("room.ply", "low:high", "--z-band must be LO:HI"),
        ("junk.ply", "0.2:2", "no readable points"),
        ("missing.pcd", "0.2:2", "no such point cloud"),
    ],
)
def test_bad_clouds_get_one_clear_line(room, truth, band, message):
    folder, map_yaml, _ = room
    (folder / "junk.ply").write_bytes(b"ply\nformat ascii 1.0\ngarbage\n")
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "smokyslam.cli",
            "evaluate",
            str(map_yaml),
            "--truth",
            str(folder / truth),
            "--z-band",
            band,
            "--out",
            str(folder / "m.json"),
        ],
        capture_output=True,
        text=True,
    )
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 1 and "Traceback" not in out.stderr
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], out.stderr


def test_the_cli_writes_the_cloud_scores(room):
    folder, map_yaml, _ = room
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "smokyslam.cli",
            "evaluate",
            str(map_yaml),
            "--truth",
            str(folder / "room.pcd"),
            "--z-band",
            "0.2:2.0",
            "--out",
            str(folder / "m.json"),
        ],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    assert json.loads((folder / "m.json").read_text())["occupied_f1"] > 0.99
