"""Commands over map fusion: register one saved map onto another."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from smokyslam.cli.options import (
    ConfigOption,
    OverwriteOption,
    RerunOption,
    RerunSpawnOption,
    check_rerun,
    echo_recording,
)
from smokyslam.config import load_config
from smokyslam.outputs import writable_folder


def register(
    source: Annotated[Path, typer.Argument(help="The map_server map YAML to move.")],
    destination: Annotated[Path, typer.Argument(help="The map_server map YAML to move it onto.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Register SOURCE onto DESTINATION by a homography (homography.json, maps/warped.*,
    overlay.png in --out)."""
    cfg = load_config(config)
    writable_folder(out)
    from smokyslam.pipelines.register_maps import register_map_files

    result = register_map_files(source, destination, out, cfg, overwrite=overwrite)
    reg = result.registration
    verdict = "confident" if reg.confident else "NOT confident: do not apply it"
    typer.echo(
        f"wrote {result.out_dir}/homography.json: confidence {reg.confidence:.2f} ({verdict}), "
        f"overlap {reg.overlap:.2f}, rms residual {reg.rms_residual:.3f} "
        f"({result.wall_s:.2f} s)"
    )


def _trust_value(text: str) -> str | float:
    """``auto`` or a number in [0, 1] (one clear line otherwise)."""
    from smokyslam.errors import ConfigError

    if text.strip().lower() == "auto":
        return "auto"
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"--trust must be 'auto' or a number in [0, 1], got '{text}'") from None
    if not 0.0 <= value <= 1.0:
        raise ConfigError(f"--trust must lie in [0, 1], got {value:g}")
    return value


def fuse(
    radar: Annotated[Path, typer.Argument(help="The radar map YAML (e.g. maps/radar_dense).")],
    visual: Annotated[Path, typer.Argument(help="The visual map YAML (e.g. maps/visual).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    trust: Annotated[
        str,
        typer.Option(
            help="auto: the trust the run measured (VISUAL.trust.npz beside the visual map); "
            "a number in [0, 1] forces the radar's trust t."
        ),
    ] = "auto",
    rule: Annotated[
        str | None, typer.Option(help="linear (the paper's eq. 3) or log-odds; default config.")
    ] = None,
    register: Annotated[
        bool,
        typer.Option(
            help="Register the visual map onto the radar map first (--no-register: both maps "
            "already share a frame)."
        ),
    ] = True,
    truth: Annotated[
        Path | None,
        typer.Option(help="Also score the maps: a log with a map, a map YAML or a cloud."),
    ] = None,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Fuse a radar map and a visual map by the trust index t: fused = t radar + (1-t) visual
    (maps/fused.* in --out)."""
    fusion: dict[str, object] = {"trust": _trust_value(trust)}
    if rule is not None:
        fusion["rule"] = rule
    cfg = load_config(config, {"fusion": fusion})
    writable_folder(out)
    from smokyslam.pipelines.fuse_maps import fuse_map_files

    result = fuse_map_files(radar, visual, out, cfg, register, truth, overwrite=overwrite)
    for name, scores in result.metrics.get("maps", {}).items():
        typer.echo(
            f"{name}: error_index {scores['error_index']:.3f}, F1 {scores['occupied_f1']:.3f}"
        )
    summary = result.metrics["fusion"]
    typer.echo(
        f"wrote {result.out_dir}/maps/fused.yaml ({summary['rule']}, mean trust index "
        f"{summary['trust_mean']:.2f})"
    )


def paper_table(
    log: Annotated[Path, typer.Argument(help="A log with ground truth (e.g. a simulation).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    jobs: Annotated[
        int | None,
        typer.Option("--jobs", "-j", min=1, help="Parallel runs (default: 2, or 1 on one core)."),
    ] = None,
    rerun: RerunOption = None,
    rerun_spawn: RerunSpawnOption = False,
    overwrite: OverwriteOption = False,
    config: ConfigOption = None,
) -> None:
    """Reproduce the paper's Table I: sparse, up-sampled, visual and fused maps at three smoke
    levels (table.csv, table.md, maps/map_<i>.*, maps.png, runs/ in --out)."""
    cfg = load_config(config)
    writable_folder(out)
    check_rerun(rerun, rerun_spawn)
    from smokyslam.pipelines.paper_table import LEVELS
    from smokyslam.pipelines.paper_table import paper_table as run_paper_table
    from smokyslam.progress import progress_bar

    total = 2 * len(LEVELS)
    with progress_bar(f"Table I: {total} runs", total, unit="items") as update:
        result = run_paper_table(
            log,
            cfg,
            out,
            jobs,
            on_progress=update,
            overwrite=overwrite,
            rerun_path=rerun,
            rerun_spawn=rerun_spawn,
        )
    typer.echo((result.out_dir / "table.md").read_text(), nl=False)
    typer.echo(f"wrote {result.out_dir}/table.csv ({result.wall_s:.1f} s)")
    echo_recording(rerun)
