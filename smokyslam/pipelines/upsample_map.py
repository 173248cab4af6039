"""``smokyslam upsample``: a saved sparse map made dense, optionally scored against a truth."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import UpsamplerError
from smokyslam.mapio import UNKNOWN, load_map
from smokyslam.outputs import OutputFolder
from smokyslam.upsample.infer import DENSE_MAP, DenseMap, get_upsampler, upsample


@dataclass
class UpsampleResult:
    dense: DenseMap
    metrics: dict[str, Any]
    out_dir: Path


def upsample_map_file(
    map_yaml: Path | str,
    out_dir: Path | str,
    config: SmokySlamConfig,
    method: str | None = None,
    truth_path: Path | str | None = None,
    overwrite: bool = False,
) -> UpsampleResult:
    """Write ``maps/radar_dense.*`` of the map at ``map_yaml`` into ``out_dir``; with
    ``truth_path`` (a log, a map or a cloud, as ``evaluate`` takes) score both maps."""
    from smokyslam.evaluation.map_metrics import map_scores
    from smokyslam.pipelines.evaluate_map import load_truth

    upsampler = get_upsampler(config.upsample, method)
    sparse = load_map(map_yaml)
    if not (sparse.cells != UNKNOWN).any():
        raise UpsamplerError(f"{map_yaml}: the map has no known cell to up-sample")
    truths = load_truth(truth_path, config, sparse) if truth_path is not None else None
    with OutputFolder(out_dir, overwrite=overwrite) as out:
        out.write_config(config)
        started = time.perf_counter()
        dense = upsample(upsampler, sparse.cells, sparse.spec)
        wall_s = time.perf_counter() - started
        truth = truths[0] if truths else None
        out.write_map(DENSE_MAP, dense.cells, dense.spec, truth)
        metrics: dict[str, Any] = {
            "upsample": {"method": dense.method, "input": str(map_yaml), "wall_s": wall_s}
        }
        if truths is not None:
            metrics["maps"] = {
                "radar_sparse": map_scores(sparse.cells, sparse.spec, *truths),
                DENSE_MAP: map_scores(dense.cells, dense.spec, *truths),
            }
        out.update_metrics(metrics)
        return UpsampleResult(dense, metrics, out.root)
