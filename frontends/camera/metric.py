"""Camera odometry as metric steps of the camera body, for runs the camera carries alone.

Each tracked result becomes an :class:`Odometry` in metres: the pose scaled by the result's
``metres_per_unit`` (the camera's height over the first map's floor depth below it), the step
since the previous frame, and the reported covariance in metres. The floor holds every map to
the first map's units, so one scale serves the whole run; results that arrive before the
floor is found wait until it is (the first frames are the two-view start), so no step is
ever in mixed units. A log that ends before any floor was seen is handed out in odometry
units (``metric`` stays False).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.geometry import se2_between
from smokyslam.types import Odometry, OdometryHealth

logger = logging.getLogger(__name__)

COASTING_SIGMAS = np.array([0.5, 0.5, 0.5])
"""Step sigmas (m, m, rad) of a frame the camera did not measure: its pose only coasts on the
motion model (the odometry's own report, ``LOST_VARIANCE``, is a placeholder, not a fit)."""


@dataclass(frozen=True)
class CameraStep:
    """One camera frame: the odometry result and its metric step."""

    result: CameraOdometryResult
    odometry: Odometry


class MetricCameraSteps:
    """One verb per camera frame, :meth:`add`; :meth:`flush` at the end of the log."""

    def __init__(self) -> None:
        self._waiting: list[CameraOdometryResult] = []
        self._previous_m: np.ndarray | None = None
        self.metres_per_unit: float | None = None
        """The scale every step so far was handed out with (None while waiting)."""
        self.metric = False
        """Whether that scale came from the floor (False: odometry units)."""

    def add(self, result: CameraOdometryResult) -> list[CameraStep]:
        """The steps ready after ``result``: none while the scale is unknown, then every
        waiting one at once."""
        self._waiting.append(result)
        if self.metres_per_unit is None:
            if result.metres_per_unit is None:
                return []
            self.metres_per_unit, self.metric = result.metres_per_unit, True
        return self._release()

    def flush(self) -> list[CameraStep]:
        """Whatever still waits: the log ended before the floor was found (odometry units)."""
        if self._waiting and self.metres_per_unit is None:
            logger.warning("camera odometry never found the floor: trajectory in its own units")
            self.metres_per_unit = 1.0
        return self._release()

    def _release(self) -> list[CameraStep]:
        steps = [CameraStep(result, self._step(result)) for result in self._waiting]
        self._waiting = []
        return steps

    def _step(self, result: CameraOdometryResult) -> Odometry:
        scale = self.metres_per_unit
        pose_m = np.asarray(result.pose_world_camera, dtype=float) * [scale, scale, 1.0]
        delta = np.zeros(3) if self._previous_m is None else se2_between(self._previous_m, pose_m)
        self._previous_m = pose_m
        scales = np.array([scale, scale, 1.0])
        health = OdometryHealth(
            inliers=result.health.inliers,
            fitness=result.health.residual_rms_px,
            lost=result.lost,
        )
        if result.lost:
            covariance = np.diag(COASTING_SIGMAS**2)
        else:
            covariance = np.asarray(result.covariance, dtype=float) * np.outer(scales, scales)
        return Odometry(result.stamp_s, pose_m, delta, covariance, health)
