"""How precise each odometry source is per keyframe step, against the true motion.

A fused run measures every keyframe pair twice, by the radar and (when it tracks and has a
metric scale) by the camera. Comparing both steps with the true relative motion of the same
pair shows what each source could bring to the graph, before the consistency check decides
which camera steps join: ``metrics.json`` ``step_errors``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smokyslam.geometry import interpolate_se2, se2_between
from smokyslam.types import GroundTruthTrajectory, StepPairs


def step_errors(
    pairs: StepPairs | None, truth: GroundTruthTrajectory | None
) -> dict[str, Any] | None:
    """``{"pairs": M, "radar": {...}, "camera": {...}}``, each source with
    ``translation_rms_m`` (of the end point's error), ``yaw_rms_deg`` and
    ``step_length_rms_pct`` (length error over true length, pairs of at least 5 cm), over the
    pairs inside the truth's time span; None without pairs or truth, or none inside it."""
    if pairs is None or truth is None or len(truth) < 2:
        return None
    stamps = np.asarray(pairs.stamps_s, dtype=float).reshape(-1, 2)
    inside = (stamps[:, 0] >= truth.stamps_s[0]) & (stamps[:, 1] <= truth.stamps_s[-1])
    if not inside.any():
        return None
    start = interpolate_se2(truth.stamps_s, truth.poses_world_base, stamps[inside, 0])
    end = interpolate_se2(truth.stamps_s, truth.poses_world_base, stamps[inside, 1])
    true_step = se2_between(start, end)
    out: dict[str, Any] = {"pairs": int(inside.sum())}
    for name, steps in (("radar", pairs.radar), ("camera", pairs.camera)):
        out[name] = _errors(np.asarray(steps, dtype=float)[inside], true_step)
    return out


def _errors(steps: np.ndarray, true_step: np.ndarray) -> dict[str, float | None]:
    error = se2_between(true_step, steps)
    true_length = np.linalg.norm(true_step[:, :2], axis=1)
    moving = true_length >= 0.05
    length_error = np.linalg.norm(steps[moving, :2], axis=1) / true_length[moving] - 1.0
    return {
        "translation_rms_m": float(np.sqrt(np.mean(np.sum(error[:, :2] ** 2, axis=1)))),
        "yaw_rms_deg": float(np.degrees(np.sqrt(np.mean(error[:, 2] ** 2)))),
        "step_length_rms_pct": (
            float(100.0 * np.sqrt(np.mean(length_error**2))) if moving.any() else None
        ),
    }
