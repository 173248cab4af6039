"""Trajectory files: TUM (``stamp x y z qx qy qz qw``) and KITTI (3x4 matrix rows).

Planar poses ``[x_m, y_m, yaw_rad]`` are lifted to z = 0 (or a given height); quaternions go
through :mod:`smokyslam.geometry` and are written in the files' ``xyzw`` order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from smokyslam.errors import TrajectoryFileError
from smokyslam.geometry import (
    quat_wxyz_from_xyzw,
    quat_wxyz_from_yaw,
    quat_xyzw_from_wxyz,
    se3_from_se2,
    yaw_from_quat_wxyz,
)


def write_tum(path: Path | str, stamps_s: np.ndarray, poses: np.ndarray, z_m: float = 0.0) -> Path:
    """Write (N,) stamps and (N, 3) planar poses as a TUM trajectory file."""
    path = Path(path)
    stamps = np.asarray(stamps_s, dtype=float).reshape(-1)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if len(stamps) != len(poses):
        raise TrajectoryFileError(f"{path}: {len(stamps)} stamps for {len(poses)} poses")
    q_xyzw = quat_xyzw_from_wxyz(quat_wxyz_from_yaw(poses[:, 2]))
    rows = np.column_stack([stamps, poses[:, :2], np.full(len(poses), z_m), q_xyzw])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, rows, fmt="%.9f", header="timestamp x y z qx qy qz qw")
    return path


def read_tum(path: Path | str) -> tuple[np.ndarray, np.ndarray]:
    """(N,) stamps and (N, 3) planar poses (yaw from the quaternion) of a TUM file."""
    path = Path(path)
    if not path.is_file():
        raise TrajectoryFileError(f"{path}: no such trajectory file")
    try:
        rows = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as exc:
        raise TrajectoryFileError(f"{path}: not a TUM trajectory ({exc})") from None
    if rows.size == 0:
        return np.zeros(0), np.zeros((0, 3))
    if rows.shape[1] != 8:
        raise TrajectoryFileError(f"{path}: TUM rows need 8 columns, found {rows.shape[1]}")
    yaw = yaw_from_quat_wxyz(quat_wxyz_from_xyzw(rows[:, 4:8]))
    return rows[:, 0], np.column_stack([rows[:, 1:3], yaw])


def write_kitti(path: Path | str, poses: np.ndarray, z_m: float = 0.0) -> Path:
    """Write (N, 3) planar poses as KITTI rows: the 12 numbers of each 3x4 ``[R | t]``."""
    path = Path(path)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    rows = np.array([se3_from_se2(pose, z_m)[:3, :].reshape(-1) for pose in poses])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, rows.reshape(-1, 12), fmt="%.9e")
    return path
