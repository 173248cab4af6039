"""How well a localization track follows the ground truth, and how it converged.

Read apart from the filter, after the run: the truth is interpolated at each frame's stamp,
in the map's frame (no alignment: a localizer must be right in the map it was given).
Converged: the first frame from which every later frame is within ``converged_m`` and
``converged_deg`` of the truth.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from smokyslam.config import LocalizeConfig
from smokyslam.geometry import interpolate_se2, wrap_angle
from smokyslam.types import GroundTruthTrajectory


def track_errors(
    stamps_s: np.ndarray, poses_map_base: np.ndarray, truth: GroundTruthTrajectory
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(inside, position error m, |yaw error| deg) per frame; ``inside``: frames within the
    truth's time span (the errors are NaN elsewhere)."""
    stamps_s = np.asarray(stamps_s, dtype=float)
    inside = (stamps_s >= truth.stamps_s[0]) & (stamps_s <= truth.stamps_s[-1])
    position = np.full(len(stamps_s), np.nan)
    yaw = np.full(len(stamps_s), np.nan)
    if inside.any():
        true = interpolate_se2(truth.stamps_s, truth.poses_world_base, stamps_s[inside])
        position[inside] = np.hypot(*(poses_map_base[inside, :2] - true[:, :2]).T)
        yaw[inside] = np.degrees(np.abs(wrap_angle(poses_map_base[inside, 2] - true[:, 2])))
    return inside, position, yaw


def _stats(position_m: np.ndarray, yaw_deg: np.ndarray) -> dict[str, float | None]:
    if len(position_m) == 0:
        return {"position_rmse_m": None, "position_max_m": None, "yaw_median_deg": None}
    return {
        "position_rmse_m": float(np.sqrt(np.mean(position_m**2))),
        "position_max_m": float(position_m.max()),
        "yaw_median_deg": float(np.median(yaw_deg)),
    }


def localization_metrics(
    stamps_s: np.ndarray,
    poses_map_base: np.ndarray,
    particles: np.ndarray,
    truth: GroundTruthTrajectory | None,
    config: LocalizeConfig,
) -> dict[str, Any]:
    """``metrics.json``'s ``localization``: particle counts always; with ground truth the
    errors over all frames (``all``), after ``settle_s`` (``after_settle``) and after
    convergence (``after_convergence``), ``converged`` and ``converge_time_s`` (from the
    first frame)."""
    stamps_s = np.asarray(stamps_s, dtype=float)
    metrics: dict[str, Any] = {
        "frames": len(stamps_s),
        "particles": {
            "mean": float(np.mean(particles)) if len(particles) else None,
            "min": int(np.min(particles)) if len(particles) else None,
            "max": int(np.max(particles)) if len(particles) else None,
            "final": int(particles[-1]) if len(particles) else None,
        },
    }
    if truth is None or len(stamps_s) == 0:
        return metrics
    inside, position, yaw = track_errors(stamps_s, poses_map_base, truth)
    if not inside.any():
        return metrics
    since_s = stamps_s - stamps_s[0]
    good = inside & (position <= config.converged_m) & (yaw <= config.converged_deg)
    # converged from k on: every later frame (with truth) is good
    bad_after = np.flip(np.cumsum(np.flip(inside & ~good)))
    converged_from = np.flatnonzero(good & (bad_after == 0))
    settled = inside & (since_s >= config.settle_s)
    metrics.update(
        {
            "all": _stats(position[inside], yaw[inside]),
            "after_settle": {
                "settle_s": config.settle_s,
                **_stats(position[settled], yaw[settled]),
            },
            "converged": bool(len(converged_from)),
            "converge_time_s": float(since_s[converged_from[0]]) if len(converged_from) else None,
        }
    )
    if len(converged_from):
        after = inside & (np.arange(len(stamps_s)) >= converged_from[0])
        metrics["after_convergence"] = _stats(position[after], yaw[after])
    return metrics
