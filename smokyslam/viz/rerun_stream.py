"""Opening a Rerun stream (file and/or viewer) and the few archetypes every recording builds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from smokyslam.geometry import GridSpec, se2_from_matrix, se3_from_se2
from smokyslam.types import Extrinsics
from smokyslam.viz.viewer import require_display


def open_stream(path: Path | None, spawn: bool, blueprint: Any, application_id: str = "smokyslam"):
    """A RecordingStream saving to ``path`` (None: no file) and, with ``spawn``, streaming to a
    viewer started for it (ViewerError without a display). The blueprint goes with both."""
    import rerun as rr

    if spawn:
        require_display("--rerun-spawn")
    rec = rr.RecordingStream(application_id)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
    if path is not None and spawn:
        rec.spawn(connect=False, detach_process=True)
        rec.set_sinks(rr.GrpcSink(), rr.FileSink(str(path)), default_blueprint=blueprint)
    elif spawn:
        rec.spawn(default_blueprint=blueprint)
    else:
        rec.save(str(path), default_blueprint=blueprint)
    return rec


def transform(rr: Any, T: np.ndarray):
    """A Transform3D of a (4, 4) rigid transform (child to parent)."""
    T = np.asarray(T, dtype=float)
    return rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3])


def level_mount(extrinsics: Extrinsics) -> np.ndarray:
    """(4, 4) the levelled radar frame on base_link: the radar's position, its heading only
    (the frame the run's scans are levelled into)."""
    T = np.asarray(extrinsics.T_base_radar, dtype=float)
    return se3_from_se2(se2_from_matrix(T), float(T[2, 3]))


def path_3d(poses: np.ndarray, z_m: float = 0.0) -> np.ndarray:
    """(N, 3) points of (N, 3) planar poses at height ``z_m``."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    return np.column_stack([poses[:, :2], np.full(len(poses), z_m)])


def grid_map(rr: Any, rgba: np.ndarray, spec: GridSpec, z_m: float):
    """A GridMap of a (rows, cols, 4) uint8 picture over ``spec`` (row 0 at the lowest y, as
    nav_msgs/OccupancyGrid stores it), its lower-left corner at the grid's origin."""
    rows, cols = rgba.shape[:2]
    return rr.GridMap(
        data=np.ascontiguousarray(rgba).tobytes(),
        format=rr.components.ImageFormat(
            width=cols, height=rows, color_model="RGBA", channel_datatype="U8"
        ),
        cell_size=spec.resolution_m,
        translation=[spec.origin_xy_m[0], spec.origin_xy_m[1], z_m],
    )
