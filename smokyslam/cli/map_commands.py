"""Commands over the up-sampler: upsample a saved map, train the model."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from smokyslam.cli.options import ConfigOption, OverwriteOption
from smokyslam.config import load_config
from smokyslam.outputs import writable_file

MethodOption = Annotated[
    str | None,
    typer.Option(help="gan (the trained model) or classical (closing); default from config."),
]


def upsample(
    map_yaml: Annotated[Path, typer.Argument(help="A sparse map_server map YAML.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    method: MethodOption = None,
    truth: Annotated[
        Path | None,
        typer.Option(help="Also score both maps: a log with a map, a map YAML or a cloud."),
    ] = None,
    weights: Annotated[
        Path | None, typer.Option(help="Weights file (default: the shipped weights).")
    ] = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Up-sample a sparse radar map into a dense one (maps/radar_dense.* in --out)."""
    overrides = {"upsample": {"weights": str(weights)}} if weights else None
    cfg = load_config(config, overrides)
    from smokyslam.pipelines.upsample_map import upsample_map_file

    result = upsample_map_file(map_yaml, out, cfg, method, truth, overwrite=overwrite)
    for name, scores in result.metrics.get("maps", {}).items():
        keys = ("error_index", "occupied_f1")
        typer.echo(f"{name}: " + ", ".join(f"{k} {scores[k]:.3f}" for k in keys))
    wall_s = result.metrics["upsample"]["wall_s"]
    typer.echo(
        f"wrote {result.out_dir}/maps/radar_dense.yaml ({result.dense.method}, "
        f"{result.dense.values.shape[1]}x{result.dense.values.shape[0]} cells, {wall_s:.2f} s)"
    )


def train_upsampler(
    out: Annotated[Path, typer.Option("--out", "-o", help="Weights file to write (.pt).")],
    worlds: Annotated[int | None, typer.Option(min=1, help="Training worlds.")] = None,
    epochs: Annotated[int | None, typer.Option(min=1, help="Epochs.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of initialisation and sampling.")] = 0,
    device: Annotated[str, typer.Option(help="cpu or cuda.")] = "cpu",
    resume: Annotated[
        bool, typer.Option(help="Continue from the checkpoint beside --out.")
    ] = False,
    data: Annotated[
        Path | None,
        typer.Option(help="Folder caching the simulated training pairs (default: beside --out)."),
    ] = None,
    config: ConfigOption = None,
) -> None:
    """Train the up-sampler on simulated worlds (seeds < 10000) and write its weights."""
    from smokyslam.errors import ConfigError

    if out.suffix != ".pt":
        raise ConfigError(f"--out must end in .pt, got '{out.name}'")
    writable_file(out, "--out")
    training = {
        key: value for key, value in (("worlds", worlds), ("epochs", epochs)) if value is not None
    }
    cfg = load_config(config, {"upsample": {"training": training}})
    from smokyslam.progress import progress_bar
    from smokyslam.upsample.train import UpsamplerTrainer

    command = shlex.join(["smokyslam", *sys.argv[1:]])
    trainer = UpsamplerTrainer(cfg, out, seed, device, command, data)
    total = cfg.upsample.training.epochs * cfg.upsample.training.steps_per_epoch
    with progress_bar("training the up-sampler", total, unit="items") as update:
        result = trainer.train(resume, on_progress=lambda done, n, status: update(done, n, status))
    scores = result.calibrated
    typer.echo(
        f"wrote {result.weights_path}: the last of {len(result.history)} epochs, "
        f"validation error index {scores['val_error_index']:.3f} "
        f"(sparse {scores['val_sparse_error_index']:.3f}), occupied F1 "
        f"{scores['val_occupied_f1']:.3f} (sparse {scores['val_sparse_occupied_f1']:.3f}); "
        f"{result.wall_s / 60:.1f} min of training"
    )
