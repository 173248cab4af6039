"""What one run is made of and what it returns: the stages the run loop drives
(:class:`Stages`, switched on per source in ``sources.py``) and its estimate
(:class:`RunEstimate`, written out by ``run_outputs.py``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from smokyslam.backends.slam import SlamBackend
from smokyslam.evaluation.gyro_bias import GyroTally
from smokyslam.frontends.camera.metric import MetricCameraSteps
from smokyslam.frontends.radar.frontend import RadarFrontend
from smokyslam.fusion.trust import TrustModel
from smokyslam.localize.stage import LocalizationTrack, Localizer
from smokyslam.mapping.online import OnlineMaps
from smokyslam.pipelines.camera_stage import CameraStage
from smokyslam.pipelines.health import RunHealth
from smokyslam.smoke import SmokeEmulator
from smokyslam.types import StepPairs
from smokyslam.viz.recorder import Recorder


@dataclass
class Stages:
    """The stages of one run. ``radar``: the radar frontend (None: no radar). ``camera``: the
    camera stage (None: no camera). ``camera_steps``: set when the camera carries the
    trajectory (camera-only); otherwise camera results feed the backend's camera factors.
    ``visual_map``: camera keyframes feed the visual map. ``trust``: the camera's trust from
    its measured smoke, per visual keyframe. ``localizer``: Monte Carlo localization in a
    saved map, fed every radar frame (None: no localization)."""

    smoke: SmokeEmulator
    radar: RadarFrontend | None
    camera: CameraStage | None
    camera_steps: MetricCameraSteps | None
    backend: SlamBackend
    maps: OnlineMaps
    recorder: Recorder
    visual_map: bool
    trust: TrustModel
    localizer: Localizer | None = None

    @property
    def streams(self) -> tuple[str, ...]:
        """The sensor streams these stages use (the reader decodes nothing else)."""
        streams = ("radar", "imu") if self.radar is not None else ()
        if self.camera is not None:
            streams += ("camera_image",)
            if self.smoke.needs_depth:  # haze needs each pixel's depth
                streams += ("camera_depth",)
        return streams


@dataclass
class RunEstimate:
    """What the loop estimated, in its own map frame (first keyframe at the origin).

    stamps_s (N,), poses_world_base (N, 3), lost (N,), camera_weight (N,): one per primary
    frame (the camera's gate weight there). keyframe_stamps_s (K,), keyframe_camera (K,): one
    per keyframe (a camera factor ends there). frames_per_s: frames over the stages' busy
    time. maps: the online maps, to snapshot or render in any
    frame. graph: the backend's numbers (factors, keyframes, camera pairs, stage seconds), as
    ``metrics.json`` holds them. extra: the source's own numbers (``odometry`` in metrics).
    health: the odometry's and the camera's health over time. localization: the localizer's
    track, in the saved map's frame (None without a localizer). step_pairs: the radar and
    camera steps of the keyframe pairs (None without camera factors), for evaluation. gyro:
    the gyro's yaw rate integrated over the run (None without IMU samples), for evaluation.
    """

    stamps_s: np.ndarray
    poses_world_base: np.ndarray
    lost: np.ndarray
    camera_weight: np.ndarray
    keyframe_stamps_s: np.ndarray
    keyframe_camera: np.ndarray
    frames_per_s: float
    maps: OnlineMaps
    graph: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    health: RunHealth = field(default_factory=RunHealth)
    localization: LocalizationTrack | None = None
    step_pairs: StepPairs | None = None
    gyro: GyroTally | None = None
    interrupted: bool = False
    failure: str | None = None
    """Why a stage stopped the run part-way (None: it read every frame or was stopped)."""
