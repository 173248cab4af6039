"""The gyro's true yaw-rate bias over a run, scored against ground truth, beside the estimate.

Radar odometry predicts each frame's turn from the gyro less its bias estimate
(``frontends/radar/motion_prior.py``), so on a long walk the heading drifts by whatever bias
is left. Evaluation measures the bias the gyro really had, without the estimator: the gyro's
integrated yaw rate over the IMU's span, less the true turn over that span, per second. The
rate is integrated by the estimator's own :class:`GyroIntegrator`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smokyslam.frontends.radar.motion_prior import GyroIntegrator
from smokyslam.types import GroundTruthTrajectory, ImuSample

SPAN_SLACK_S = 0.1
"""The IMU's span may reach this far past the ground truth's and still be scored."""


@dataclass
class GyroTally:
    """The gyro's yaw rate integrated over a run: one verb per IMU sample, :meth:`add`.

    start_s, end_s: stamps of the first and latest sample (None before the first).
    yaw_rad: gyro z integrated from ``start_s`` to ``end_s``.
    """

    start_s: float | None = None
    end_s: float | None = None
    yaw_rad: float = 0.0
    samples: int = 0
    _integrator: GyroIntegrator = field(default_factory=GyroIntegrator, repr=False)

    def add(self, sample: ImuSample) -> None:
        stamp_s = float(sample.stamp_s)
        if self.start_s is None:
            self.start_s = stamp_s  # the first sample's rate is held over no time
        self.yaw_rad += self._integrator.integrate([sample], self.start_s) or 0.0
        self.end_s = stamp_s
        self.samples += 1


def gyro_bias_metrics(
    tally: GyroTally,
    truth: GroundTruthTrajectory | None,
    estimated_degps: float | None,
    graph_degps: float | None = None,
) -> dict[str, Any] | None:
    """``metrics.json`` ``gyro_bias``, or None without ground truth over the IMU's span.

    true_degps: the gyro's mean yaw rate less the true one. estimated_degps: the radar
    odometry's final estimate, as given (None when it estimates none). residual_degps: true less
    estimated (the whole bias when none is estimated): the rate the heading drifts at where
    scan matching does not hold it. graph_degps (with gyro factors): the pose graph's bias at
    the last keyframe, the one its heading was held to.
    """
    if tally.samples < 2 or truth is None or len(truth) < 2:
        return None
    start_s, end_s = float(tally.start_s), float(tally.end_s)
    stamps = truth.stamps_s
    if start_s < stamps[0] - SPAN_SLACK_S or end_s > stamps[-1] + SPAN_SLACK_S:
        return None
    duration_s = end_s - start_s
    if duration_s <= 0.0:
        return None
    true_yaw = np.unwrap(truth.poses_world_base[:, 2])
    true_turn = float(np.interp(end_s, stamps, true_yaw) - np.interp(start_s, stamps, true_yaw))
    true_degps = float(np.degrees((tally.yaw_rad - true_turn) / duration_s))
    metrics = {
        "true_degps": true_degps,
        "estimated_degps": estimated_degps,
        "residual_degps": true_degps - (estimated_degps or 0.0),
    }
    if graph_degps is not None:
        metrics["graph_degps"] = graph_degps
    return metrics
