"""The run's map frame placed on the ground truth while the run goes, for the error so far.

The map frame is the first keyframe's base_link (at the origin). Until the run's alignment is
known (after the loop), it is anchored at the true pose of the first frame; the error so far
is the distance of each estimate, so placed, from the true pose at its stamp. Only the
recorder uses this: no estimator sees the truth.
"""

from __future__ import annotations

import numpy as np

from smokyslam.geometry import interpolate_se2, se2_compose, se3_from_se2
from smokyslam.types import GroundTruthTrajectory


class TruthAnchor:
    """``start(stamp_s)`` once (the first frame), then ``error_m(stamp_s, pose_map_base)``."""

    def __init__(self, truth: GroundTruthTrajectory) -> None:
        self._stamps_s = np.asarray(truth.stamps_s, dtype=float)
        self._poses = np.asarray(truth.poses_world_base, dtype=float)
        self._T_world_map: np.ndarray | None = None

    def start(self, stamp_s: float) -> np.ndarray:
        """(4, 4) T_world_map: the true pose at the first frame's stamp."""
        self._T_world_map = interpolate_se2(self._stamps_s, self._poses, stamp_s)
        return se3_from_se2(self._T_world_map)

    def error_m(self, stamp_s: float, pose_map_base: np.ndarray) -> float:
        """Metres between the anchored estimate and the truth at ``stamp_s`` (NaN outside the
        truth's span or before :meth:`start`)."""
        if self._T_world_map is None or not (self._stamps_s[0] <= stamp_s <= self._stamps_s[-1]):
            return float("nan")
        estimate = se2_compose(self._T_world_map, np.asarray(pose_map_base, dtype=float))
        x_m = np.interp(stamp_s, self._stamps_s, self._poses[:, 0])
        y_m = np.interp(stamp_s, self._stamps_s, self._poses[:, 1])
        return float(np.hypot(estimate[0] - x_m, estimate[1] - y_m))
