"""Odometry sources: which stages of the one run loop each switches on.

| source | radar frontend | camera | loop closures | gyro factors | trajectory of |
| --- | --- | --- | --- | --- | --- |
| ``radar`` | scan matching | off | off | off | radar |
| ``dead-reckoning`` | Doppler + gyro | off | off | off | radar |
| ``camera`` | off | carries the trajectory | off | off | camera |
| ``fused`` | scan matching | factors | ``slam.loop_closures`` | ``slam.gyro_factors`` | radar |

Every source runs the same backend (keyframe gate, iSAM2 graph); with no camera factors, no
loop closures and no gyro factors its graph is a chain that reproduces the odometry exactly.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal

import numpy as np

from smokyslam.backends.slam import Primary, SlamBackend
from smokyslam.config import SmokySlamConfig
from smokyslam.errors import ConfigError, TopicError
from smokyslam.frontends.camera.metric import MetricCameraSteps
from smokyslam.frontends.camera.pose import planar_from_camera
from smokyslam.frontends.radar.frontend import RadarKind, get_radar_frontend
from smokyslam.frontends.readers.base import LogReader
from smokyslam.fusion.fuser import MapFuser, get_trust_model
from smokyslam.mapping.online import OnlineMaps
from smokyslam.pipelines.camera_stage import CameraStage
from smokyslam.pipelines.stages import Stages
from smokyslam.smoke import SmokeEmulator
from smokyslam.upsample.online import DenseRefresher
from smokyslam.viz.recorder import Recorder

logger = logging.getLogger(__name__)

MIN_CAMERA_HEIGHT_M = 0.05
"""A camera mounted lower than this (or a log without its mounting) gives no metric scale."""


@dataclass(frozen=True)
class Source:
    """radar: the radar frontend, None for none. camera: ``factors`` (camera factors between
    radar keyframes, when the log has a camera) or ``trajectory`` (the camera carries it).
    loop_closures: radar submap loop closures. requires: streams the log must have.
    gyro: the gyro's turns join the graph (``slam.gyro_factors``)."""

    radar: RadarKind | None
    camera: Literal["factors", "trajectory"] | None
    loop_closures: bool
    requires: tuple[str, ...]
    gyro: bool = False

    @property
    def camera_only(self) -> bool:
        return self.camera == "trajectory"


SOURCES: dict[str, Source] = {
    "radar": Source("scan-matching", None, False, ("radar",)),
    "dead-reckoning": Source("dead-reckoning", None, False, ("radar",)),
    "camera": Source(None, "trajectory", False, ("camera_image",)),
    "fused": Source("scan-matching", "factors", True, ("radar",), gyro=True),
}


def get_source(name: str) -> Source:
    """The registered source ``name``; ConfigError naming the choices otherwise."""
    if name not in SOURCES:
        raise ConfigError(f"unknown odometry source '{name}': choose from {', '.join(SOURCES)}")
    return SOURCES[name]


def build_stages(
    source: Source, reader: LogReader, config: SmokySlamConfig, recorder: Recorder
) -> Stages:
    """The stages ``source`` switches on, set up for ``reader``'s log and ``config``."""
    extrinsics = reader.extrinsics()
    smoke = SmokeEmulator(config.smoke)
    radar = None
    if source.radar is not None:
        radar = get_radar_frontend(source.radar, config.radar_odometry, extrinsics.T_base_radar)
    intrinsics = reader.camera_intrinsics()
    camera_factors = source.camera == "factors" and config.slam.camera_factors
    use_camera = source.camera_only or (camera_factors and intrinsics is not None)
    if source.camera_only and intrinsics is None:
        raise TopicError(f"{reader.path}: the log has no camera_info, needed for the camera")
    if source.camera_only:
        primary = Primary("camera", planar_from_camera(extrinsics.T_base_camera), 1.0)
    else:
        primary = Primary("radar", radar.pose_base_radar, config.slam.radar_covariance_scale)
    backend = SlamBackend(
        config,
        primary,
        extrinsics.T_base_camera if use_camera and not source.camera_only else None,
        loop_closures=source.loop_closures and config.slam.loop_closures,
        gyro_factors=source.gyro and config.slam.gyro_factors,
    )
    visual_map = use_camera and (source.camera_only or config.slam.visual_map)
    camera = None
    if use_camera:  # before the up-sampler starts loading torch, which slows a worker's start
        camera = CameraStage(
            intrinsics,
            config.camera_odometry,
            _camera_height_m(extrinsics.T_base_camera),
            smoke,
            stride=1 if source.camera_only else config.slam.camera_stride,
            worker=config.slam.camera_process and not source.camera_only,
            keep_views=recorder.keeps_camera_views,
        )
    dense = None
    try:
        if radar is not None and config.upsample.method != "none":
            dense = DenseRefresher(config.upsample)  # loads the up-sampler in the background
        maps = OnlineMaps(
            config.mapping,
            backend,
            radar.pose_base_radar if radar is not None else None,
            extrinsics.T_base_camera if visual_map else None,
            dense,
            MapFuser(config.fusion),
        )
    except BaseException:  # the loop and the run stop the workers; without them, stop them here
        if camera is not None:
            camera.shutdown()
        if dense is not None:
            dense.close()
        raise
    return Stages(
        smoke=smoke,
        radar=radar,
        camera=camera,
        camera_steps=MetricCameraSteps() if source.camera_only else None,
        backend=backend,
        maps=maps,
        recorder=recorder,
        visual_map=visual_map,
        trust=get_trust_model(config.fusion),
    )


def _camera_height_m(T_base_camera: np.ndarray) -> float | None:
    height_m = float(np.asarray(T_base_camera)[2, 3])
    if height_m < MIN_CAMERA_HEIGHT_M:
        logger.warning("camera height %.2f m on base_link: no metric camera scale", height_m)
        return None
    return height_m
