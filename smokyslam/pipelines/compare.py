"""``smokyslam compare``: odometry sources crossed with smoke levels, run in parallel on Dask.

Levels. Each ``--smoke`` item is ``R:C[:H]`` (radar loss : camera noise : haze, the notation
of every command; the paper pairs radar loss and camera noise). ``--haze`` values are crossed
with every smoke level, on top of the levels as given: ``--smoke 0:0,0.2:0.4 --haze 0.5``
gives four levels, ``r0-c0``, ``r0.2-c0.4``, ``r0-c0-h0.5`` and ``r0.2-c0.4-h0.5`` (the
levels as given first, then one block per haze value). A haze of ``0`` is the haze-free run
and adds nothing. A level sets ``smoke.radar_loss``, ``smoke.camera_noise`` and
``smoke.haze`` of the base config; the other smoke settings (airlight, seed) are kept.

Folders. Each (source, level) runs into ``DIR/runs/<source>-r<loss>-c<noise>[-h<haze>]/``
with the numbers spelled exactly as typed (``0.1:0.2`` gives ``radar-r0.1-c0.2``), holding the
standard ``smokyslam run`` outputs. A failed run also leaves ``error.log`` (its traceback).

Table. ``DIR/compare.csv`` and ``DIR/compare.md`` hold one row per run, level by level and
source by source in the order given (columns: ``evaluation/compare_table.py``).
``realtime_factor`` is measured while the runs share the cores: for a clean figure use one
worker or ``smokyslam run``. A folder holding an earlier comparison is refused unless
``overwrite`` is given, which removes its tables, plots and runs first.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig, write_config
from smokyslam.errors import ConfigError, RunInterruptedError, SmokySlamError
from smokyslam.evaluation.compare_table import CompareRow, write_tables
from smokyslam.outputs import claim_folder
from smokyslam.pipelines.jobs import CompareJob, default_workers, run_jobs
from smokyslam.pipelines.sources import get_source
from smokyslam.smoke import SmokeLevel, check_number, parse_smoke

logger = logging.getLogger(__name__)

ERROR_LOG = "error.log"
COMPARE_OUTPUTS = (
    "compare.csv",
    "compare.md",
    "trajectories.png",
    "ate_vs_smoke.png",
    "config.yaml",
    "runs",
)
"""What a comparison leaves in its folder; its tables mark a finished one."""

ProgressCallback = Callable[..., None]


def _items(text: str, option: str) -> list[str]:
    items = [item.strip() for item in text.split(",")]
    if not text.strip() or any(not item for item in items):
        raise ConfigError(f"{option} '{text}': expected a comma-separated list without empty items")
    return items


def parse_smoke_levels(smoke: str, haze: str | None = None) -> list[SmokeLevel]:
    """Levels from ``--smoke`` (``R:C[:H],...``) and ``--haze`` (``B,...``, 1/m, each 0 or
    more): every level as given, then again for each non-zero haze (on levels without one).

    Raises ConfigError for a malformed, out-of-range or repeated item.
    """
    given = [parse_smoke(item) for item in _items(smoke, "--smoke")]
    hazes = []
    if haze is not None:
        hazes = [check_number(h, "haze", h, None) for h in _items(haze, "--haze")]
        hazes = [h for h in hazes if float(h)]
    levels = given + [
        SmokeLevel(level.radar_loss_text, level.camera_noise_text, h)
        for h in hazes
        for level in given
        if not level.haze_text
    ]
    seen: dict[tuple[float, float, float], SmokeLevel] = {}
    for level in levels:
        key = (level.radar_loss, level.camera_noise, level.haze)
        if key in seen:
            raise ConfigError(f"smoke level {level.label} repeats {seen[key].label}")
        seen[key] = level
    return levels


def parse_sources(text: str) -> list[str]:
    """Registered odometry sources from a comma-separated list (ConfigError otherwise)."""
    sources = _items(text, "--sources")
    for source in sources:
        get_source(source)
    if len(set(sources)) != len(sources):
        raise ConfigError(f"--sources '{text}' names a source twice")
    return sources


@dataclass
class CompareResult:
    """A finished comparison: one row per run and the files written into ``out_dir``."""

    rows: list[CompareRow]
    out_dir: Path
    csv_path: Path
    markdown_path: Path
    trajectories_png: Path
    ate_png: Path
    config_path: Path
    wall_s: float

    @property
    def failed(self) -> list[CompareRow]:
        return [row for row in self.rows if not row.ok]


def compare(
    log_path: Path | str,
    sources: Sequence[str],
    levels: Sequence[SmokeLevel],
    config: SmokySlamConfig,
    out_dir: Path | str,
    workers: int | None = None,
    on_progress: ProgressCallback | None = None,
    overwrite: bool = False,
    rerun_path: Path | str | None = None,
    rerun_spawn: bool = False,
    scheduler: str | None = None,
) -> CompareResult:
    """Run every source at every level over the log; write the runs, the table and the plots.

    ``workers``: parallel runs, each a task on a LocalCluster of that many Dask worker
    processes (default :func:`default_workers`; 1 runs them here, in order), or on the
    existing cluster at ``scheduler`` (its workers must see the log and ``out_dir``, e.g. on a
    shared disk). Failed runs are rows
    with status ``failed``; only bad arguments (ConfigError), an unreadable log or an output
    folder holding an earlier comparison (without ``overwrite``) raise. Ctrl-C writes the
    table of the runs so far (the others ``interrupted``) and raises RunInterruptedError.
    ``rerun_path`` / ``rerun_spawn``: every run's path in one Rerun recording, written there
    and/or streamed to a viewer.
    """
    from smokyslam.evaluation.compare_plot import plot_ate_vs_smoke, plot_trajectories
    from smokyslam.frontends.readers.registry import log_format

    started = time.perf_counter()
    log_path, out_dir = Path(log_path), Path(out_dir)
    log_format(log_path)  # a missing or unknown log fails once, here, not in every run
    if not sources or not levels:
        raise ConfigError("compare needs at least one source and one smoke level")
    if workers is not None and workers < 1:
        raise ConfigError(f"--jobs must be 1 or more, got {workers}")
    claim_folder(out_dir, overwrite, COMPARE_OUTPUTS, markers=COMPARE_OUTPUTS[:2])
    jobs = make_jobs(log_path, sources, levels, config, out_dir)
    config_path = write_config(config, out_dir / "config.yaml")
    workers = workers or default_workers(len(jobs))
    where = scheduler or f"{workers} workers"
    logger.info("compare: %d runs on %s into %s", len(jobs), where, out_dir)
    rows, interrupted = run_jobs(jobs, workers, on_progress, scheduler)
    csv_path, markdown_path = write_tables(rows, out_dir)
    if interrupted:  # the table of what finished, marked; no plots
        raise RunInterruptedError(out_dir)
    gt_map = _ground_truth_map(log_path, config)
    if rerun_path is not None or rerun_spawn:
        record_rows(rows, gt_map, None if rerun_path is None else Path(rerun_path), rerun_spawn)
    return CompareResult(
        rows=rows,
        out_dir=out_dir,
        csv_path=csv_path,
        markdown_path=markdown_path,
        trajectories_png=plot_trajectories(out_dir / "trajectories.png", rows, gt_map),
        ate_png=plot_ate_vs_smoke(out_dir / "ate_vs_smoke.png", rows),
        config_path=config_path,
        wall_s=time.perf_counter() - started,
    )


def make_jobs(
    log_path: Path,
    sources: Sequence[str],
    levels: Sequence[SmokeLevel],
    config: SmokySlamConfig,
    out_dir: Path,
) -> list[CompareJob]:
    """One job per (level, source), level-major, each in ``out_dir/runs/<source>-<label>``."""
    return [
        CompareJob(
            source,
            level,
            log_path,
            level.apply(config),
            out_dir / "runs" / f"{source}-{level.label}",
        )
        for level in levels
        for source in sources
    ]


def record_rows(
    rows: Sequence[CompareRow], gt_map, path: Path | None, spawn: bool = False, maps=None
) -> Path | None:
    """One Rerun recording of every finished run's path (read from its ``trajectory.tum``)
    over the truth (the first ``ground_truth.tum``), and ``maps`` (name -> (cells, spec))."""
    from smokyslam.evaluation.trajectory_io import read_tum
    from smokyslam.viz.comparison import RecordedRun, record_runs

    runs, truth = [], None
    for row in rows:
        if not (row.ok and (row.run_dir / "trajectory.tum").is_file()):
            continue
        runs.append(
            RecordedRun(row.run_dir.name, row.source, *read_tum(row.run_dir / "trajectory.tum"))
        )
        if truth is None and (row.run_dir / "ground_truth.tum").is_file():
            truth = RecordedRun(
                "ground_truth", "ground_truth", *read_tum(row.run_dir / "ground_truth.tum")
            )
    return record_runs(path, runs, truth, gt_map, spawn, maps)


def _ground_truth_map(log_path: Path, config: SmokySlamConfig):
    """The log's true occupancy grid for the plots, or None (no map, or unreadable)."""
    from smokyslam.frontends.readers.registry import open_log

    try:
        return open_log(log_path, config).ground_truth_map()
    except SmokySlamError as exc:
        logger.warning("no ground-truth map for the plots: %s", exc)
        return None
