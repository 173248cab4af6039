"""Up-sampling from the command line: upsample, map --upsample, train-upsampler."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from smokyslam.geometry import GridSpec
from smokyslam.mapio import UNKNOWN, load_map, save_map

pytest.importorskip("torch")

FIVE = {"error_index", "occupied_precision", "occupied_recall", "occupied_f1", "occupied_iou"}


def smokyslam(*args, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)],
        capture_output=True,
        text=True,
        **kwargs,
    )


@pytest.fixture(scope="module")
def unseen_log(tmp_path_factory) -> Path:
    """A 40 s radar-only walk through a world never trained on (seed >= 10000)."""
    path = tmp_path_factory.mktemp("unseen") / "office10007.mcap"
    out = smokyslam(
        "simulate", "--world", "office", "--seed", "10007", "--duration", "40",
        "--sensors", "radar,imu", "--out", path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    return path


@pytest.fixture(scope="module")
def mapped(unseen_log, tmp_path_factory) -> Path:
    out_dir = tmp_path_factory.mktemp("mapped") / "map"
    out = smokyslam("map", unseen_log, "--upsample", "--out", out_dir)
    assert out.returncode == 0, out.stderr
    return out_dir


def test_map_upsample_writes_the_dense_map_beside_the_sparse_one(mapped):
    for name in ("radar_sparse", "radar_dense"):
        assert (mapped / f"maps/{name}.pgm").is_file() and (mapped / f"maps/{name}.yaml").is_file()
    maps = json.loads((mapped / "metrics.json").read_text())["maps"]
    for name in ("radar_sparse", "radar_dense"):
        assert set(maps[name]) == FIVE | {"observed"} and set(maps[name]["observed"]) == FIVE
    sparse, dense = maps["radar_sparse"]["observed"], maps["radar_dense"]["observed"]
    # On a world it never saw, up-sampling halves the error index (the paper: 0.39 x;
    # measured 0.26 x) and finds walls better than the sparse map (occupied F1 measured 0.60
    # against 0.52; 0.57 with the weights shipped before stop 56).
    assert dense["error_index"] <= 0.5 * sparse["error_index"]
    assert dense["occupied_f1"] > sparse["occupied_f1"]


def test_upsample_command_gan_beats_classical(mapped, unseen_log, tmp_path):
    sparse_yaml = mapped / "maps/radar_sparse.yaml"
    scores = {}
    for method in ("gan", "classical"):
        out_dir = tmp_path / method
        out = smokyslam(
            "upsample", sparse_yaml, "--method", method, "--truth", unseen_log, "--out", out_dir
        )
        assert out.returncode == 0, out.stderr
        assert "radar_dense.yaml" in out.stdout
        metrics = json.loads((out_dir / "metrics.json").read_text())
        assert metrics["upsample"]["method"] == method
        # The dense grid: the sparse map's known cells and 48 cells (extend_cells) around.
        sparse_map, dense_map = load_map(sparse_yaml), load_map(out_dir / "maps/radar_dense.yaml")
        rows, cols = np.nonzero(sparse_map.cells != UNKNOWN)
        corner = sparse_map.spec.centres_of(np.array([[cols.min() - 48, rows.min() - 48]]))[0]
        np.testing.assert_allclose(dense_map.spec.centres_of(np.array([[0, 0]]))[0], corner)
        assert dense_map.cells.shape == (np.ptp(rows) + 97, np.ptp(cols) + 97)
        scores[method] = metrics["maps"]["radar_dense"]["observed"]
        sparse = metrics["maps"]["radar_sparse"]["observed"]
    assert scores["classical"]["error_index"] < sparse["error_index"]
    assert scores["gan"]["error_index"] < 0.8 * scores["classical"]["error_index"]
    # F1: measured 0.60 (GAN), 0.53 (classical), 0.52 (sparse); see above.
    assert scores["gan"]["occupied_f1"] > scores["classical"]["occupied_f1"]
    # The map up-sampled from the file equals the one map --upsample wrote.
    from_file = load_map(tmp_path / "gan/maps/radar_dense.yaml").cells
    assert np.array_equal(from_file, load_map(mapped / "maps/radar_dense.yaml").cells)


def test_bad_upsample_input_is_one_clear_line(tmp_path):
    blank = save_map(
        tmp_path / "blank.yaml",
        np.full((20, 20), UNKNOWN, dtype=np.int8),
        GridSpec((0.0, 0.0), 0.1, (20, 20)),
    )
    (tmp_path / "junk.pt").write_bytes(b"not torch at all")
    cases = [
        (["upsample", blank, "--out", tmp_path / "a"], "no known cell"),
        (["upsample", blank, "--method", "bicubic", "--out", tmp_path / "b"], "bicubic"),
    ]
    sparse = np.zeros((20, 20), dtype=np.int8)
    good = save_map(tmp_path / "room.yaml", sparse, GridSpec((0.0, 0.0), 0.1, (20, 20)))
    cases.append(
        (["upsample", good, "--weights", tmp_path / "junk.pt", "--out", tmp_path / "c"], "junk.pt")
    )
    for args, message in cases:
        out = smokyslam(*args)
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 1 and len(lines) == 1, out.stderr
        assert lines[0].startswith("error: ") and message in lines[0], out.stderr


TINY = {
    "upsample": {
        "training": {
            "worlds": 2,
            "validation_worlds": 1,
            "epochs": 2,
            "steps_per_epoch": 2,
            "batch": 2,
            "crop_cells": 48,
            "walk_s": [15.0, 18.0],
            "jobs": 1,
            "model": {"base_channels": 4, "depth": 2, "max_channels": 8},
        }
    }
}


@pytest.fixture(scope="module")
def pairs(tmp_path_factory) -> Path:
    """One training-pair cache for the module's trainings (pairs are cached by config)."""
    return tmp_path_factory.mktemp("pairs")


def _train(
    tmp_path: Path, pairs: Path, name: str, *extra: str, epochs: int = 2
) -> subprocess.CompletedProcess:
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(TINY))
    return smokyslam(
        "train-upsampler", "--out", tmp_path / name, "--config", config, "--data", pairs,
        "--epochs", str(epochs), *extra,
    )  # fmt: skip


def test_training_writes_its_outputs_and_resumes_to_the_same_weights(tmp_path, pairs):
    import torch

    straight = _train(tmp_path, pairs, "straight.pt")
    assert straight.returncode == 0, straight.stderr
    for suffix in (".pt", ".config.yaml", ".history.json", ".loss.png", ".ckpt"):
        assert (tmp_path / f"straight{suffix}").stat().st_size > 0, suffix
    record = json.loads((tmp_path / "straight.history.json").read_text())
    assert [h["epoch"] for h in record["history"]] == [1, 2]
    assert all(0.0 <= h["val_error_index"] <= 1.0 for h in record["history"])
    assert record["command"].startswith("smokyslam train-upsampler --out")
    assert "the last of 2 epochs" in straight.stdout
    # The weights written are the last epoch's averaged generator, as checkpointed.
    last = torch.load(tmp_path / "straight.ckpt", weights_only=False)["average"]
    written = torch.load(tmp_path / "straight.pt", weights_only=True)["state_dict"]
    assert written.keys() == last.keys() and all(torch.equal(written[k], last[k]) for k in last)
    # One epoch, then a resumed second: the same weights as two straight epochs.
    assert _train(tmp_path, pairs, "halves.pt", epochs=1).returncode == 0
    resumed = _train(tmp_path, pairs, "halves.pt", "--resume")
    assert resumed.returncode == 0, resumed.stderr
    a = torch.load(tmp_path / "straight.pt", weights_only=True)["state_dict"]
    b = torch.load(tmp_path / "halves.pt", weights_only=True)["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_training_refuses_evaluation_seeds_and_a_foreign_checkpoint(tmp_path, pairs):
    out = smokyslam("train-upsampler", "--out", tmp_path / "w.pt", "--worlds", "6000")
    assert out.returncode == 1 and "at most 5000 training worlds" in out.stderr
    (tmp_path / "w.ckpt").write_bytes(b"garbage")
    out = _train(tmp_path, pairs, "w.pt", "--resume")
    assert out.returncode == 1 and "unreadable checkpoint" in out.stderr, out.stderr


def test_ctrl_c_leaves_the_last_checkpoint_intact(tmp_path, pairs):
    config = tmp_path / "tiny.yaml"
    slow = {"upsample": {"training": {**TINY["upsample"]["training"], "steps_per_epoch": 400}}}
    config.write_text(yaml.safe_dump(slow))
    args = ["train-upsampler", "--out", tmp_path / "w.pt", "--config", config,
            "--data", pairs, "--epochs", "3"]  # fmt: skip
    process = subprocess.Popen(
        [sys.executable, "-m", "smokyslam.cli", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    checkpoint = tmp_path / "w.ckpt"
    deadline = time.monotonic() + 240
    while not checkpoint.exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert checkpoint.exists(), "no checkpoint after the first epoch"
    before = checkpoint.read_bytes()
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert "interrupted: the checkpoint of epoch 1" in stderr and "Traceback" not in stderr
    assert checkpoint.read_bytes() == before
    assert not (tmp_path / "w.pt").exists()
