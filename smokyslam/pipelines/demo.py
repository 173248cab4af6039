"""``make demo``: simulate a smoky office, run SLAM on it, and say where everything went."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.compare_plot import plot_trajectories
from smokyslam.evaluation.compare_table import CompareRow, RunStatus
from smokyslam.evaluation.demo_summary import write_summary
from smokyslam.frontends.readers.registry import open_log
from smokyslam.outputs import claim_folder
from smokyslam.pipelines.run import SOURCES, RunResult, run_log
from smokyslam.pipelines.truth_mapping import run_truth_mapping
from smokyslam.sim.simulate import SimulationResult, simulate
from smokyslam.smoke import SmokeLevel, parse_smoke

DEMO_WORLD, DEMO_SEED = "office", 7
DEMO_SMOKE = parse_smoke("0.1:0.2")  # the paper's middle smoke level
DEMO_SOURCES = ("fused", "radar", "camera", "dead-reckoning")
DEMO_LOG = f"{DEMO_WORLD}.mcap"
DEMO_RECORDING = "run-fused/run.rrd"
DEMO_OUTPUTS = (
    DEMO_LOG,
    "map_ground_truth",
    *(f"run-{source}" for source in DEMO_SOURCES),
    "summary.md",
    "trajectories.png",
)


@dataclass
class DemoResult:
    simulation: SimulationResult
    mapping_dir: Path
    runs: list[RunResult]
    summary: Path
    recording: Path


def run_demo(
    out_dir: Path | str,
    config: SmokySlamConfig,
    duration_s: float = 60.0,
    on_step: Callable[[str], None] | None = None,
    smoke: SmokeLevel = DEMO_SMOKE,
    overwrite: bool = False,
) -> DemoResult:
    """Simulate, map on ground truth, run every available source under ``smoke`` (the fused
    run recorded for Rerun), then sum up: ``summary.md`` and ``trajectories.png``.

    A folder holding an earlier demo is refused unless ``overwrite``, which replaces it.
    """
    step = on_step or (lambda _message: None)
    out_dir = Path(out_dir)
    claim_folder(out_dir, overwrite, DEMO_OUTPUTS)
    out_dir.mkdir(parents=True, exist_ok=True)
    log_path = out_dir / DEMO_LOG
    step(f"simulating {duration_s:.0f} s of a smoky {DEMO_WORLD} -> {log_path}")
    simulation = simulate(DEMO_WORLD, duration_s, DEMO_SEED, log_path, config, overwrite=True)
    smoky = smoke.apply(config)
    step("radar map on ground-truth poses")
    mapping = run_truth_mapping(log_path, smoky, out_dir / "map_ground_truth")
    runs = []
    recording = out_dir / DEMO_RECORDING
    for source in (s for s in DEMO_SOURCES if s in SOURCES):
        step(f"{source} run under smoke {smoke.notation}")
        rerun = recording if source == "fused" else None
        runs.append(run_log(log_path, source, smoky, out_dir / f"run-{source}", rerun_path=rerun))
    step("summary")
    rows = [CompareRow(r.source, smoke, r.out_dir, RunStatus.OK, metrics=r.metrics) for r in runs]
    gt_map = open_log(log_path, config).ground_truth_map()
    plot_trajectories(out_dir / "trajectories.png", rows, gt_map)
    title = (
        f"smokyslam demo: {duration_s:.0f} s in a simulated {DEMO_WORLD} (seed {DEMO_SEED}), "
        f"smoke {smoke.notation} (radar loss : camera noise)"
    )
    summary = write_summary(
        out_dir / "summary.md",
        title,
        rows,
        mapping.metrics,
        recording if recording.is_file() else None,
    )
    return DemoResult(simulation, mapping.out_dir, runs, summary, recording)
