"""Training pairs for the up-sampler: sparse radar maps and the observed truth of the walk.

Each world (a procedural office, warehouse or corridor, by seed) is simulated without the
camera (radar, IMU, truth), with a walk of random length. From the one log come two pairs,
each at its own random radar loss:

- the sparse map stitched on the true poses (the mapping half alone);
- the sparse map stitched on radar odometry's poses and rigidly aligned onto the truth, as
  ``run`` writes it, so the model also learns the misalignment of real estimates.

Both are resampled onto the world's grid beside its observed truth (``/ground_truth/
map_observed``). Training and validation use world seeds below :data:`EVALUATION_SEEDS`;
seeds from there up are kept for evaluation and refused here.

Each world's pairs are cached as one ``.npz`` in the cache folder, so an interrupted or
repeated training run does not simulate a world twice.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.config.upsample import UpsamplerTrainingConfig
from smokyslam.errors import ConfigError
from smokyslam.mapio import UNKNOWN

PAIRS_VERSION = 1
"""Bumped whenever :func:`world_pairs` changes what it makes (invalidates cached pairs)."""

EVALUATION_SEEDS = 10_000
"""World seeds from here up are for evaluation only: never trained on."""

VALIDATION_FIRST_SEED = 5_000
"""Validation worlds are seeds 5000, 5001, ...; training worlds 0, 1, ..."""


@dataclass
class MapPair:
    """A sparse radar map and its observed truth, (rows, cols) int8 trinary, same grid."""

    sparse: np.ndarray
    truth: np.ndarray
    name: str


def training_seeds(config: UpsamplerTrainingConfig) -> tuple[list[int], list[int]]:
    """(training world seeds, validation world seeds), all below :data:`EVALUATION_SEEDS`."""
    train = list(range(config.worlds))
    first = VALIDATION_FIRST_SEED
    validation = list(range(first, first + config.validation_worlds))
    if train and train[-1] >= VALIDATION_FIRST_SEED:
        raise ConfigError(f"at most {VALIDATION_FIRST_SEED} training worlds")
    if validation[-1] >= EVALUATION_SEEDS:
        raise ConfigError(f"validation worlds must stay below seed {EVALUATION_SEEDS}")
    return train, validation


def world_pairs(seed: int, config: SmokySlamConfig) -> list[MapPair]:
    """The two pairs of world ``seed`` (see the module docstring)."""
    from smokyslam.backends.keyframes import get_keyframe_gate
    from smokyslam.frontends.readers.registry import open_log
    from smokyslam.mapping.build import build_radar_map
    from smokyslam.mapping.grid import resample_nearest
    from smokyslam.pipelines.run import evaluate_source, run_source
    from smokyslam.sim.simulate import simulate
    from smokyslam.sim.worlds import WORLD_NAMES
    from smokyslam.smoke import SmokeEmulator

    if seed >= EVALUATION_SEEDS:
        raise ConfigError(f"world seed {seed} is kept for evaluation (>= {EVALUATION_SEEDS})")
    training = config.upsample.training
    rng = np.random.default_rng([seed, 11])
    kind = WORLD_NAMES[seed % len(WORLD_NAMES)]
    duration_s = float(rng.uniform(*training.walk_s))
    losses = rng.uniform(*training.radar_loss, size=2)
    with tempfile.TemporaryDirectory(prefix="smokyslam-pairs-") as folder:
        log = Path(folder) / f"{kind}-{seed}.mcap"
        simulate(kind, duration_s, seed, log, config, sensors=frozenset({"radar", "imu"}))
        reader = open_log(log, config)
        truth_map = reader.observed_ground_truth_map()
        trajectory = reader.ground_truth_trajectory()
        on_truth = _with_loss(config, losses[0])
        frames = (SmokeEmulator(on_truth.smoke).apply(f) for f in reader.frames(("radar",)))
        gate = get_keyframe_gate(config.keyframes)
        grid = build_radar_map(frames, trajectory, reader.extrinsics(), config.mapping, gate)
        pairs = [(grid, f"{kind}-{seed} true poses, loss {losses[0]:.2f}")]
        estimated = _with_loss(config, losses[1])
        estimate = run_source(reader, "radar", estimated)
        evaluation = evaluate_source(estimate, trajectory, "radar")
        rendered = estimate.maps.render(evaluation.pose_truth_map)["radar_sparse"]
        pairs.append((rendered, f"{kind}-{seed} radar odometry, loss {losses[1]:.2f}"))
    spec = truth_map.spec
    return [
        MapPair(resample_nearest(g.to_cells(), g.spec, spec, UNKNOWN), truth_map.cells, name)
        for g, name in pairs
    ]


def _with_loss(config: SmokySlamConfig, radar_loss: float) -> SmokySlamConfig:
    """``config`` at ``radar_loss``, with no up-sampling of its own (only the sparse map)."""
    smoke = config.smoke.model_copy(update={"radar_loss": float(radar_loss)})
    upsample = config.upsample.model_copy(update={"method": "none"})
    return config.model_copy(update={"smoke": smoke, "upsample": upsample})


def save_pairs(path: Path, pairs: Sequence[MapPair]) -> None:
    arrays = {}
    for i, pair in enumerate(pairs):
        arrays[f"sparse_{i}"], arrays[f"truth_{i}"] = pair.sparse, pair.truth
    partial = path.with_name(path.name + ".partial.npz")
    np.savez_compressed(partial, names=np.array([p.name for p in pairs]), **arrays)
    os.replace(partial, path)


def load_pairs(path: Path) -> list[MapPair]:
    with np.load(path, allow_pickle=False) as data:
        names = [str(n) for n in data["names"]]
        return [MapPair(data[f"sparse_{i}"], data[f"truth_{i}"], n) for i, n in enumerate(names)]


def _cached_world(seed: int, config: SmokySlamConfig, cache: Path) -> tuple[int, Path]:
    path = cache / f"world-{seed:05d}.npz"
    if not path.is_file():
        save_pairs(path, world_pairs(seed, config))
    return seed, path


def _init_worker(parent_pid: int) -> None:
    from smokyslam.pipelines.worker_process import start_worker_process

    start_worker_process(parent_pid)
    logging.getLogger("smokyslam").setLevel(logging.ERROR)  # e.g. short walks: not news here


def cache_folder(root: Path, config: SmokySlamConfig) -> Path:
    """``root/<fingerprint>``: pairs made under another config (simulator, mapping, odometry,
    walks, losses) never mix with these."""
    used = config.model_dump(
        mode="json",
        include={"simulation", "rig", "radar_odometry", "keyframes", "mapping", "backend", "slam"},
    )
    training = config.upsample.training
    used["pairs"] = [training.walk_s, training.radar_loss, PAIRS_VERSION]
    digest = hashlib.sha256(json.dumps(used, sort_keys=True).encode()).hexdigest()[:12]
    return root / digest


def build_pairs(
    seeds: Sequence[int],
    config: SmokySlamConfig,
    cache: Path,
    jobs: int,
    on_world: Callable[[int], None] | None = None,
) -> list[MapPair]:
    """Every pair of the worlds ``seeds``, simulated in ``jobs`` processes (cached in
    ``cache``), in seed order whatever order they finish in."""
    cache = cache_folder(cache, config)
    cache.mkdir(parents=True, exist_ok=True)
    paths: dict[int, Path] = {}
    todo = [s for s in seeds if not (cache / f"world-{s:05d}.npz").is_file()]
    for seed in seeds:
        if seed not in todo:
            paths[seed] = cache / f"world-{seed:05d}.npz"
            if on_world:
                on_world(len(paths))
    if todo and jobs > 1:
        from smokyslam.pipelines.worker_process import worker_context

        context = worker_context()  # the run's workers' start: Ctrl-C left to this process
        with ProcessPoolExecutor(
            min(jobs, len(todo)), context, initializer=_init_worker, initargs=(os.getpid(),)
        ) as pool:
            futures = [pool.submit(_cached_world, s, config, cache) for s in todo]
            try:
                for future in as_completed(futures):
                    seed, path = future.result()
                    paths[seed] = path
                    if on_world:
                        on_world(len(paths))
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
    else:
        for seed in todo:
            paths[seed] = _cached_world(seed, config, cache)[1]
            if on_world:
                on_world(len(paths))
    return [pair for seed in seeds for pair in load_pairs(paths[seed])]
