"""``smokyslam run``: one odometry source over one log, with every output a run leaves.

The table of contents of :func:`run_log`: claim the output folder and write the effective
config; open the log; run the one loop with the source's stages; evaluate against the log's
ground truth (read apart, after the loop); write the trajectory, the maps and the metrics in
the ground-truth frame; finish the recording.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import RunFailedError, RunInterruptedError
from smokyslam.evaluation.run_evaluation import RunEvaluation, evaluate_estimate
from smokyslam.evaluation.step_errors import step_errors
from smokyslam.frontends.readers.base import LogReader
from smokyslam.frontends.readers.registry import config_for_log, open_log
from smokyslam.outputs import OutputFolder
from smokyslam.pipelines.loop import RunLoop
from smokyslam.pipelines.run_outputs import (
    record_results,
    write_figures,
    write_maps,
    write_trajectory,
)
from smokyslam.pipelines.sources import SOURCES, build_stages, get_source
from smokyslam.pipelines.stages import RunEstimate
from smokyslam.pipelines.worker_process import DeferredCtrlC
from smokyslam.types import GroundTruthMap, GroundTruthTrajectory
from smokyslam.viz.recorder import NullRecorder, Recorder, RecordingSetup, open_recorder

logger = logging.getLogger(__name__)

__all__ = ["SOURCES", "RunResult", "evaluate_source", "run_log", "run_reader", "run_source"]

ProgressCallback = Callable[[float, str], None]


@dataclass
class RunResult:
    """A finished run: its folder, its metrics (as in metrics.json) and the estimate."""

    source: str
    out_dir: Path
    metrics: dict[str, Any]
    estimate: RunEstimate


def run_source(
    reader: LogReader,
    source: str,
    config: SmokySlamConfig,
    on_progress: ProgressCallback | None = None,
    recorder: Recorder | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> RunEstimate:
    """The one run loop of ``source`` over an open log, with no files: the estimate, in its
    own map frame. The reader's ground truth is never touched. ``should_stop``: see
    :class:`RunLoop`."""
    stages = build_stages(get_source(source), reader, config, recorder or NullRecorder())
    try:
        return RunLoop(stages, on_progress, should_stop).run(reader.frames(stages.streams))
    except BaseException:  # no estimate to finish the dense map of: stop its up-sampler
        if stages.maps.dense is not None:
            stages.maps.dense.close()
        raise


def evaluate_source(
    estimate: RunEstimate, truth: GroundTruthTrajectory | None, source: str
) -> RunEvaluation:
    """``estimate`` of ``source`` aligned onto and scored against the ground truth."""
    return evaluate_estimate(
        estimate.stamps_s,
        estimate.poses_world_base,
        estimate.lost,
        truth,
        get_source(source).camera_only,
    )


def _recording_setup(
    reader: LogReader,
    source: str,
    truth: GroundTruthTrajectory | None,
    gt_map: GroundTruthMap | None,
) -> RecordingSetup:
    """What the recorder shows before the first frame (the truth only to the recorder)."""
    return RecordingSetup(
        source,
        reader.extrinsics(),
        reader.camera_intrinsics(),
        reader.log_time_s,
        truth,
        gt_map,
    )


@contextlib.contextmanager
def _dense_closed(estimate: RunEstimate) -> Iterator[None]:
    try:
        yield
    finally:
        if estimate.maps.dense is not None:
            estimate.maps.dense.close()


def run_log(
    log_path: Path | str,
    source: str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    on_progress: ProgressCallback | None = None,
    rerun_path: Path | str | None = None,
    overwrite: bool = False,
    rerun_spawn: bool = False,
    should_stop: Callable[[], bool] | None = None,
) -> RunResult:
    """Run ``source`` over the log at ``log_path`` and write its outputs into ``out_dir``.

    on_progress: (stamp_s, health text) as frames are processed. rerun_path: also write a
    Rerun recording (``.rrd``) there, as the run goes; rerun_spawn: stream it to a viewer.
    overwrite: replace an earlier run's outputs in ``out_dir`` (otherwise such a folder is
    refused). should_stop: asked before each frame; True stops the run as Ctrl-C does.
    """
    spec = get_source(source)
    config = config_for_log(log_path, config)
    return run_reader(
        lambda: open_log(log_path, config, require=spec.requires),
        source,
        config,
        out_dir,
        on_progress,
        rerun_path,
        overwrite,
        rerun_spawn,
        should_stop,
    )


def run_reader(
    open_reader: Callable[[], LogReader],
    source: str,
    config: SmokySlamConfig,
    out_dir: Path | str,
    on_progress: ProgressCallback | None = None,
    rerun_path: Path | str | None = None,
    overwrite: bool = False,
    rerun_spawn: bool = False,
    should_stop: Callable[[], bool] | None = None,
) -> RunResult:
    """:func:`run_log` over the reader ``open_reader()`` returns (a log, or live sensors),
    opened once the output folder is claimed."""
    spec = get_source(source)
    started = time.perf_counter()
    with OutputFolder(out_dir, overwrite=overwrite) as out, out.interrupt_kept():
        out.write_config(config)
        reader = open_reader()
        truth, gt_map = reader.ground_truth_trajectory(), reader.ground_truth_map()
        recorder = open_recorder(rerun_path, config.recording, rerun_spawn)
        recorder.start(_recording_setup(reader, source, truth, gt_map))
        estimate = run_source(reader, source, config, on_progress, recorder, should_stop)
        if estimate.interrupted:  # marked first: a stop may cut the writing short
            out.update_metrics({"interrupted": True})
        if estimate.failure:
            out.update_metrics({"failed": estimate.failure})
        # Written whole on a first Ctrl-C (no wait on the up-sampler cut short); a second
        # one stops the writing, keeping what was written.
        with _dense_closed(estimate), DeferredCtrlC():
            evaluation = evaluate_source(estimate, truth, source)
            if (errors := step_errors(estimate.step_pairs, truth)) is not None:
                out.update_metrics({"step_errors": errors})
            write_trajectory(out, source, estimate, evaluation, truth, reader)
            observed = reader.observed_ground_truth_map()
            write_maps(out, source, estimate, evaluation, gt_map, observed, spec.camera_only)
            if (dense := estimate.maps.dense) is not None:
                out.update_metrics({"upsample": dense.stats()})
                if estimate.failure is None and dense.failure is not None:
                    estimate.failure = f"no dense map: {dense.failure}"
                    out.update_metrics({"failed": estimate.failure})
            record_results(recorder, estimate, evaluation)
            if problems := reader.problems():
                out.update_metrics({"log": problems})
            write_figures(out, source, estimate, evaluation, truth, gt_map)
        wall_s = time.perf_counter() - started
        duration_s = reader.summary().duration_s
        metrics = out.update_metrics(
            {
                "wall_s": wall_s,
                "duration_s": duration_s,
                "realtime_factor": duration_s / wall_s if wall_s > 0 else None,
            }
        )
    logger.info("%s run on %s: %.1f s of log in %.1f s", source, reader.path, duration_s, wall_s)
    if estimate.interrupted:
        raise RunInterruptedError(out.root)
    if estimate.failure:
        raise RunFailedError(estimate.failure, out.root)
    return RunResult(source, out.root, metrics, estimate)
