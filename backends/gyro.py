"""The gyro's turn between keyframes, as factors that hold the graph's heading to it.

Per keyframe pair the gyro's turn, less its bias, is off by 0.06-0.09 deg RMS, against the
radar step's 0.17-0.26 deg and the camera's 0.30-0.47 deg; over 30 pairs by 0.04-0.24 deg
against 0.33-1.13 and 0.73-3.09 (simulated 120 s walks, the bias fitted in hindsight;
docs/accuracy.md). Its one weakness is the bias. The graph holds it as a variable, one per
span of keyframes (``slam.gyro_bias_span_s``), each walking slowly from the one before
(``PoseGraph.add_gyro_turn``), with the radar odometry's running estimate as a prior that is
replaced at every keyframe (``PoseGraph.hold_gyro_bias``): alone, the graph's bias follows
the radar's heading drift, since the radar steps claim independent errors.

A factor holds ``yaw_j - yaw_i = turn - b * dt`` (1 dof): ``turn`` the raw gyro integral
between the two keyframe stamps, ``b`` the bias of the span (rad/s, a 1-vector), and ``dt``
the time between them.
"""

from __future__ import annotations

import bisect
import math

import gtsam
import numpy as np

from smokyslam.types import ImuSample

KEEP_S = 60.0
"""Seconds of gyro history kept: the backend takes keyframes a few frames behind the reader."""

MAX_GAP_S = 0.5
"""A turn over a gap between gyro samples longer than this is not measured (None)."""


class GyroTurns:
    """The raw gyro z integral over time; ``turn`` between two stamps. One verb: ``add``.

    A sample's rate is held over the interval since the previous sample, as the radar
    odometry integrates it; between samples the integral is interpolated linearly. A stamp
    up to :data:`MAX_GAP_S` past the latest sample is reached by holding its rate: a log may
    store a radar scan before the IMU samples of the same instant.
    """

    def __init__(self) -> None:
        self._stamps_s: list[float] = []
        self._yaw_rad: list[float] = []
        self._gaps_s: list[float] = []  # time since the previous sample, per sample
        self._rate_radps = 0.0  # the latest sample's

    def add(self, sample: ImuSample) -> None:
        """Take one IMU sample (time order; out-of-order samples are dropped)."""
        stamp_s = float(sample.stamp_s)
        if self._stamps_s and stamp_s <= self._stamps_s[-1]:
            return
        gap_s = stamp_s - self._stamps_s[-1] if self._stamps_s else 0.0
        yaw = self._yaw_rad[-1] + float(sample.gyro_radps[2]) * gap_s if self._yaw_rad else 0.0
        self._stamps_s.append(stamp_s)
        self._yaw_rad.append(yaw)
        self._gaps_s.append(gap_s)
        self._rate_radps = float(sample.gyro_radps[2])
        if stamp_s - self._stamps_s[0] > 2 * KEEP_S:  # forget in batches: cheap per sample
            first = bisect.bisect_left(self._stamps_s, stamp_s - KEEP_S)
            del self._stamps_s[:first], self._yaw_rad[:first], self._gaps_s[:first]

    def turn(self, start_s: float, end_s: float) -> float | None:
        """The raw integral (rad) from ``start_s`` to ``end_s``; None where the samples do not
        cover both stamps, or leave a gap longer than :data:`MAX_GAP_S` between them."""
        stamps = self._stamps_s
        if not stamps or stamps[0] > start_s or end_s > stamps[-1] + MAX_GAP_S:
            return None
        first = bisect.bisect_left(stamps, start_s)
        last = bisect.bisect_left(stamps, end_s)
        if max(self._gaps_s[max(first, 1) : last + 1], default=0.0) > MAX_GAP_S:
            return None
        return self._at(end_s, last) - self._at(start_s, first)

    def _at(self, stamp_s: float, index: int) -> float:
        """The integral at ``stamp_s``, with ``stamps[index - 1] < stamp_s <= stamps[index]``
        (``index`` one past the end: beyond the latest sample, at its rate)."""
        if index == len(self._stamps_s):
            return self._yaw_rad[-1] + self._rate_radps * (stamp_s - self._stamps_s[-1])
        t1, y1 = self._stamps_s[index], self._yaw_rad[index]
        if index == 0 or stamp_s >= t1:
            return y1
        t0, y0 = self._stamps_s[index - 1], self._yaw_rad[index - 1]
        return y0 + (y1 - y0) * (stamp_s - t0) / (t1 - t0)


_YAW_I = np.array([[0.0, 0.0, -1.0]])
_YAW_J = np.array([[0.0, 0.0, 1.0]])
"""The turn's Jacobians in the two poses: Pose2's tangent theta adds to its heading."""


def gyro_turn_factor(
    keys: tuple[int, int, int],
    linearization_point: gtsam.Values,
    turn_rad: float,
    dt_s: float,
    sigma_rad: float,
) -> gtsam.LinearContainerFactor:
    """The factor ``yaw_j - yaw_i = turn_rad - b * dt_s`` on ``keys`` (pose i, pose j: Pose2;
    the bias: a 1-vector, rad/s), with a turn sigma of ``sigma_rad``.

    The error is linear in the two headings and the bias, and a Pose2's tangent theta adds
    to its heading, so a linear factor at ``linearization_point`` (values of the three keys)
    holds it exactly wherever the poses move: gtsam's container measures them from that point.
    It costs what a native factor does (a Python factor made the fused run 25 % slower).
    """
    pose_i, pose_j, bias = keys
    point = linearization_point
    turn = point.atPose2(pose_j).theta() - point.atPose2(pose_i).theta()
    residual = math.remainder(turn - turn_rad + point.atVector(bias)[0] * dt_s, math.tau)
    noise = gtsam.noiseModel.Isotropic.Sigma(1, sigma_rad)
    linear = gtsam.JacobianFactor(
        pose_i, _YAW_I, pose_j, _YAW_J, bias, np.array([[dt_s]]), np.array([-residual]), noise
    )
    return gtsam.LinearContainerFactor(linear, point)
