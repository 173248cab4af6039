"""Radar maps built after the fact: scans placed on given poses, stitched at keyframes.

Both builders stitch a scan only where the keyframe gate (``backends/keyframes.py``, the one
the pose graph uses) makes its frame a keyframe, judged on the poses given, so a map built
here on a run's final poses equals the run's online map (``mapping/online.py``).

- :func:`radar_map_on_poses`: one base_link pose per scan (e.g. a run's trajectory).
- :func:`build_radar_map`: every radar scan of a log at its ground-truth pose, linearly
  interpolated at the scan's stamp (:func:`smokyslam.geometry.interpolate_se2`); scans more
  than ``max_pose_gap_s`` outside the ground truth's span are dropped (and counted in the log).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Protocol

import numpy as np

from smokyslam.config import MappingConfig
from smokyslam.geometry import interpolate_se2, se2_between, se2_compose
from smokyslam.mapping.grid import OccupancyGrid
from smokyslam.mapping.radar_mapper import get_radar_mapper
from smokyslam.rig import level_scan
from smokyslam.types import Extrinsics, Frame, GroundTruthTrajectory, RadarScan

logger = logging.getLogger(__name__)


class Gate(Protocol):
    """The keyframe gate (``backends.keyframes.KeyframeGate``)."""

    def passes(self, delta: np.ndarray) -> bool: ...


def radar_map_on_poses(
    scans: Iterable[RadarScan],
    poses_world_base: np.ndarray,
    extrinsics: Extrinsics,
    config: MappingConfig,
    gate: Gate,
) -> OccupancyGrid:
    """The radar grid of (raw) scans at (N, 3) base_link poses, one per scan, stitched at the
    frames the gate makes keyframes (the first always is; empty scans count as frames)."""
    mapper = get_radar_mapper(config)
    last = None
    for scan, pose in zip(scans, np.asarray(poses_world_base, dtype=float), strict=True):
        if last is not None and not gate.passes(se2_between(last, pose)):
            continue
        last = pose
        levelled, pose_base_radar = level_scan(scan, extrinsics.T_base_radar)
        mapper.insert(levelled, se2_compose(pose, pose_base_radar))
    return mapper.grid


def build_radar_map(
    frames: Iterable[Frame],
    truth: GroundTruthTrajectory,
    extrinsics: Extrinsics,
    config: MappingConfig,
    gate: Gate,
) -> OccupancyGrid:
    """The radar grid of a log: every radar scan of ``frames`` (a reader's ``frames()``) at
    its ground-truth pose."""
    stamps = truth.stamps_s
    low, high = stamps[0] - config.max_pose_gap_s, stamps[-1] + config.max_pose_gap_s
    scans, dropped = [], 0
    for frame in frames:
        if not isinstance(frame, RadarScan):
            continue
        if low <= frame.stamp_s <= high:
            scans.append(frame)
        else:
            dropped += 1
    if dropped:
        logger.warning(
            "%d radar scans had no ground-truth pose within %.2f s and were dropped",
            dropped,
            config.max_pose_gap_s,
        )
    at = np.array([scan.stamp_s for scan in scans], dtype=float)
    poses = interpolate_se2(stamps, truth.poses_world_base, at).reshape(-1, 3)
    return radar_map_on_poses(scans, poses, extrinsics, config, gate)
