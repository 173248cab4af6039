"""``smokyslam compare``: odometry sources crossed with smoke levels, run in parallel processes.

Levels. Each ``--smoke`` item is ``radar_loss:camera_noise`` (the paper's paired levels).
``--haze`` values are crossed with every smoke level, on top of the haze-free runs:
``--smoke 0:0,0.2:0.4 --haze 0.5`` gives four levels, ``r0-c0``, ``r0.2-c0.4``, ``r0-c0-h0.5``
and ``r0.2-c0.4-h0.5`` (haze-free first, then one block per haze value). A haze of ``0`` is
the haze-free run and adds nothing. A level sets ``smoke.radar_loss``, ``smoke.camera_noise``
and ``smoke.haze`` of the base config; the other smoke settings (airlight, seed) are kept.

Folders. Each (source, level) runs into ``DIR/runs/<source>-r<loss>-c<noise>[-h<haze>]/``
with the numbers spelled exactly as typed (``0.1:0.2`` gives ``radar-r0.1-c0.2``), holding the
standard ``smokyslam run`` outputs. A failed run also leaves ``error.log`` (its traceback).

Table. ``DIR/compare.csv`` and ``DIR/compare.md`` hold one row per run, haze-free levels
first, then level by level and source by source in the order given. The ``map`` columns score
the run's main map: ``visual`` for camera runs, else ``fused`` when the run wrote one, else
``radar_sparse`` (the first of those present in its ``metrics.json``). ``realtime_factor`` is
measured while the runs share the cores: for a clean figure use one worker or ``smokyslam run``.
"""

from __future__ import annotations

import contextlib
import csv
import logging
import math
import multiprocessing
import os
import re
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig, write_config
from smokyslam.errors import ConfigError, SmokySlamError
from smokyslam.pipelines.run import SOURCES, run_log

logger = logging.getLogger(__name__)

COLUMNS = (
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
    "status",
    "error",
)
MAIN_MAPS = {"camera": ("visual", "fused", "radar_sparse")}
DEFAULT_MAIN_MAPS = ("fused", "radar_sparse", "visual")
# torch, gtsam and OpenCV keep threads and locks that a forked child inherits half-held.
START_METHOD = "spawn"
ERROR_LOG = "error.log"
_PLAIN_NUMBER = re.compile(r"\d+(\.\d*)?|\.\d+")

ProgressCallback = Callable[..., None]


@dataclass(frozen=True)
class SmokeLevel:
    """One smoke level, with each number kept as typed (``haze_text`` is "" when haze-free)."""

    radar_loss_text: str
    camera_noise_text: str
    haze_text: str = ""

    @property
    def radar_loss(self) -> float:
        return float(self.radar_loss_text)

    @property
    def camera_noise(self) -> float:
        return float(self.camera_noise_text)

    @property
    def haze(self) -> float:
        return float(self.haze_text) if self.haze_text else 0.0

    @property
    def smoke_label(self) -> str:
        """``r<loss>-c<noise>``, as typed."""
        return f"r{self.radar_loss_text}-c{self.camera_noise_text}"

    @property
    def label(self) -> str:
        """The folder suffix: ``r<loss>-c<noise>``, plus ``-h<haze>`` when hazy."""
        return self.smoke_label + (f"-h{self.haze_text}" if self.haze_text else "")

    def apply(self, config: SmokySlamConfig) -> SmokySlamConfig:
        """``config`` with this level's radar loss, camera noise and haze."""
        smoke = config.smoke.model_copy(
            update={
                "radar_loss": self.radar_loss,
                "camera_noise": self.camera_noise,
                "haze": self.haze,
            }
        )
        return config.model_copy(update={"smoke": smoke})


def _number(text: str, name: str, item: str, upper: float | None) -> str:
    """``text`` checked as a plain decimal in [0, upper]; returned unchanged (for names)."""
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{name} in '{item}' is not a number: '{text}'") from None
    bound = f"between 0 and {upper:g}" if upper is not None else "0 or more"
    if not math.isfinite(value) or value < 0 or (upper is not None and value > upper):
        raise ConfigError(f"{name} in '{item}' must be {bound}, got '{text}'")
    if not _PLAIN_NUMBER.fullmatch(text):
        raise ConfigError(f"{name} in '{item}': write a plain decimal such as 0.1, got '{text}'")
    return text


def _items(text: str, option: str) -> list[str]:
    items = [item.strip() for item in text.split(",")]
    if not text.strip() or any(not item for item in items):
        raise ConfigError(f"{option} '{text}': expected a comma-separated list without empty items")
    return items


def parse_smoke_levels(smoke: str, haze: str | None = None) -> list[SmokeLevel]:
    """Levels from ``--smoke`` (``loss:noise,...``, each in [0, 1]) and ``--haze`` (``B,...``,
    1/m, each 0 or more): every smoke level haze-free, then again for each non-zero haze.

    Raises ConfigError for a malformed, out-of-range or repeated item.
    """
    pairs = []
    for item in _items(smoke, "--smoke"):
        parts = [part.strip() for part in item.split(":")]
        if len(parts) != 2:
            raise ConfigError(
                f"--smoke item '{item}' must be radar_loss:camera_noise, e.g. 0.1:0.2"
            )
        pairs.append(
            (
                _number(parts[0], "radar_loss", item, 1.0),
                _number(parts[1], "camera_noise", item, 1.0),
            )
        )
    hazes = [""]
    if haze is not None:
        hazes += [
            h for h in (_number(h, "haze", h, None) for h in _items(haze, "--haze")) if float(h)
        ]
    levels = [SmokeLevel(loss, noise, h) for h in hazes for loss, noise in pairs]
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
        if source not in SOURCES:
            raise ConfigError(
                f"unknown odometry source '{source}': choose from {', '.join(SOURCES)}"
            )
    if len(set(sources)) != len(sources):
        raise ConfigError(f"--sources '{text}' names a source twice")
    return sources


class RunStatus(StrEnum):
    """How a run ended, as written in the table's ``status`` column."""

    OK = "ok"
    FAILED = "failed"


@dataclass(frozen=True)
class CompareJob:
    """One run: ``source`` over ``log_path`` with ``config`` (smoke level applied)."""

    source: str
    level: SmokeLevel
    log_path: Path
    config: SmokySlamConfig
    run_dir: Path


@dataclass
class CompareRow:
    """One finished (or failed) run: ``metrics`` as in its ``metrics.json``, empty on failure."""

    source: str
    level: SmokeLevel
    run_dir: Path
    status: RunStatus
    error: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status is RunStatus.OK

    def main_map(self) -> str | None:
        """The map this row scores (see the module docstring), or None without one."""
        maps = self.metrics.get("maps", {})
        return next((m for m in MAIN_MAPS.get(self.source, DEFAULT_MAIN_MAPS) if m in maps), None)

    def values(self) -> dict[str, Any]:
        """The row under :data:`COLUMNS`; None where there is no value."""
        trajectory = self.metrics.get("trajectory", {})
        name = self.main_map()
        scores = self.metrics["maps"][name] if name else {}
        return {
            "source": self.source,
            "radar_loss": self.level.radar_loss_text,
            "camera_noise": self.level.camera_noise_text,
            "haze": self.level.haze_text or "0",
            "ate_rmse_m": trajectory.get("ate_rmse_m"),
            "ate_alignment": trajectory.get("ate_alignment"),
            "drift_pct": trajectory.get("drift_pct"),
            "lost_frames": trajectory.get("lost_frames"),
            "realtime_factor": self.metrics.get("realtime_factor"),
            "map": name,
            "map_error_index": scores.get("error_index"),
            "map_f1": scores.get("occupied_f1"),
            "status": self.status.value,
            "error": self.error,
        }


def run_job(job: CompareJob) -> CompareRow:
    """Run one job (in a worker process); any exception becomes a failed row, never a raise."""
    try:
        if job.run_dir.is_dir():
            (job.run_dir / ERROR_LOG).unlink(missing_ok=True)  # left by an earlier failure
        result = run_log(job.log_path, job.source, job.config, job.run_dir)
    except Exception as exc:
        message = str(exc) if isinstance(exc, SmokySlamError) else f"{type(exc).__name__}: {exc}"
        # The folder itself may be what failed; the row carries the message either way.
        with contextlib.suppress(OSError):
            (job.run_dir / ERROR_LOG).write_text(traceback.format_exc())
        return CompareRow(job.source, job.level, job.run_dir, RunStatus.FAILED, message)
    return CompareRow(job.source, job.level, job.run_dir, RunStatus.OK, metrics=result.metrics)


def default_workers(runs: int) -> int:
    """Parallel runs when not given: up to 2, at most one per core, never more than runs."""
    return max(1, min(os.cpu_count() or 1, 2, runs))


def run_jobs(
    jobs: Sequence[CompareJob], workers: int, on_progress: ProgressCallback | None = None
) -> list[CompareRow]:
    """Every job's row, in job order. ``workers`` > 1 runs them in that many spawned processes;
    1 runs them here, one after another. ``on_progress(done, total, status=...)`` per run."""
    rows: list[CompareRow | None] = [None] * len(jobs)

    def finished(index: int, row: CompareRow) -> None:
        rows[index] = row
        done = sum(r is not None for r in rows)
        if on_progress is not None:
            on_progress(done, len(jobs), status=f"{row.run_dir.name} {row.status.value}")

    if workers <= 1:
        for index, job in enumerate(jobs):
            finished(index, run_job(job))
        return rows  # type: ignore[return-value]
    context = multiprocessing.get_context(START_METHOD)
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = {pool.submit(run_job, job): index for index, job in enumerate(jobs)}
        try:
            for future in as_completed(futures):
                index = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # the worker process died (crash, out of memory)
                    job, message = jobs[index], f"{type(exc).__name__}: {exc}"
                    row = CompareRow(job.source, job.level, job.run_dir, RunStatus.FAILED, message)
                finished(index, row)
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    return rows  # type: ignore[return-value]


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
) -> CompareResult:
    """Run every source at every level over the log; write the runs, the table and the plots.

    ``workers``: parallel processes (default :func:`default_workers`). Failed runs are rows
    with status ``failed``; only bad arguments (ConfigError) or an unreadable log raise.
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
    jobs = make_jobs(log_path, sources, levels, config, out_dir)
    config_path = write_config(config, out_dir / "config.yaml")
    workers = workers or default_workers(len(jobs))
    logger.info("compare: %d runs on %d workers into %s", len(jobs), workers, out_dir)
    rows = run_jobs(jobs, workers, on_progress)
    csv_path, markdown_path = write_tables(rows, out_dir)
    gt_map = _ground_truth_map(log_path, config)
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


def _csv_value(value: Any) -> str:
    return "" if value is None else repr(value) if isinstance(value, float) else str(value)


def _markdown_value(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 100 else f"{value:.1f}"
    return str(value).replace("|", "\\|").replace("\n", " ")


def write_tables(rows: Sequence[CompareRow], out_dir: Path) -> tuple[Path, Path]:
    """``compare.csv`` (full precision, empty where missing) and ``compare.md`` (3 decimals)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, markdown_path = out_dir / "compare.csv", out_dir / "compare.md"
    values = [row.values() for row in rows]
    with csv_path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(COLUMNS)
        writer.writerows([_csv_value(v[c]) for c in COLUMNS] for v in values)
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_markdown_value(v[c]) for c in COLUMNS) + " |" for v in values]
    markdown_path.write_text("\n".join(lines) + "\n")
    return csv_path, markdown_path


def _ground_truth_map(log_path: Path, config: SmokySlamConfig):
    """The log's true occupancy grid for the plots, or None (no map, or unreadable)."""
    from smokyslam.frontends.readers.registry import open_log

    try:
        return open_log(log_path, config).ground_truth_map()
    except SmokySlamError as exc:
        logger.warning("no ground-truth map for the plots: %s", exc)
        return None
