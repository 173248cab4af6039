"""Frames, units and conversions: the one place where they are defined.

Conventions
-----------
- World frame ``map``: x east, y north, z up; metres.
- ``base_link``: the carried rig at floor level, x forward, y left, z up.
- ``radar``: ti_mmwave_rospkg axes, x forward (boresight), y left, z up.
- ``camera``: optical axes, z forward, x right, y down.
- ``T_a_b`` is a 4x4 (or 3x3 in 2D) homogeneous transform mapping points in frame ``b``
  into frame ``a``: ``p_a = T_a_b @ p_b``.
- Planar poses are ``(x_m, y_m, yaw_rad)``; yaw is counter-clockwise from +x.
- Quaternions are ``quat_wxyz`` inside smokyslam. ROS messages and scipy use xyzw;
  convert only with :func:`quat_wxyz_from_xyzw` / :func:`quat_xyzw_from_wxyz`.
- Grids: arrays are indexed ``[iy, ix]`` with iy growing with world y; cell ``[0, 0]`` has
  its lower-left corner at ``origin_xy_m``. Image files flip rows (row 0 is the top).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


def wrap_angle(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(angle_rad) + np.pi) % (2.0 * np.pi) - np.pi


# ---------------------------------------------------------------- SE(2)


def rotation_2d(yaw_rad: float) -> np.ndarray:
    """(2, 2) rotation matrix of a planar yaw."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s], [s, c]])


def se2_matrix(x_m: float, y_m: float, yaw_rad: float) -> np.ndarray:
    """(3, 3) homogeneous matrix of a planar pose."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    return np.array([[c, -s, x_m], [s, c, y_m], [0.0, 0.0, 1.0]])


def se2_from_matrix(T: np.ndarray) -> np.ndarray:
    """Planar pose ``[x_m, y_m, yaw_rad]`` of a (3, 3) or (4, 4) transform (z, tilt dropped)."""
    T = np.asarray(T, dtype=float)
    t = T[:2, -1]
    return np.array([t[0], t[1], np.arctan2(T[1, 0], T[0, 0])])


def se2_compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose composition ``a * b`` of ``[x, y, yaw]`` arrays; broadcasts over leading axes."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def se2_inverse(a: np.ndarray) -> np.ndarray:
    """Inverse of ``[x, y, yaw]`` poses; broadcasts over leading axes."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = -(-s * a[..., 0] + c * a[..., 1])
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def se2_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Relative pose ``a^-1 * b``: ``b`` expressed in the frame of ``a``."""
    return se2_compose(se2_inverse(a), b)


def _se2_v_terms(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(t)/t`` and ``(1 - cos(t))/t`` of the SE(2) V matrix, with their series near 0."""
    small = np.abs(theta) < 1e-6
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, theta / 2.0, (1.0 - np.cos(safe)) / safe)
    return a, b


def se2_exp(twist: np.ndarray) -> np.ndarray:
    """Pose ``[x, y, yaw]`` reached by holding the body twist ``[dx, dy, dyaw]`` (metres and
    radians over the step; body-frame velocity times dt) constant: the SE(2) exponential.

    Broadcasts over leading axes.
    """
    twist = np.asarray(twist, dtype=float)
    a, b = _se2_v_terms(twist[..., 2])
    x = a * twist[..., 0] - b * twist[..., 1]
    y = b * twist[..., 0] + a * twist[..., 1]
    return np.stack([x, y, wrap_angle(twist[..., 2])], axis=-1)


def se2_log(pose: np.ndarray) -> np.ndarray:
    """Body twist ``[dx, dy, dyaw]`` whose :func:`se2_exp` is ``pose``; broadcasts."""
    pose = np.asarray(pose, dtype=float)
    theta = wrap_angle(pose[..., 2])
    a, b = _se2_v_terms(theta)
    det = a * a + b * b
    dx = (a * pose[..., 0] + b * pose[..., 1]) / det
    dy = (-b * pose[..., 0] + a * pose[..., 1]) / det
    return np.stack([dx, dy, theta], axis=-1)


def se2_adjoint(pose: np.ndarray) -> np.ndarray:
    """(3, 3) adjoint of a planar pose in tangent order ``[x, y, theta]``:
    ``pose * Exp(xi) = Exp(Ad @ xi) * pose``."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.array([[c, -s, pose[1]], [s, c, -pose[0]], [0.0, 0.0, 1.0]])


def se2_compose_with_covariance(
    delta_a: np.ndarray, cov_a: np.ndarray, delta_b: np.ndarray, cov_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``delta_a * delta_b`` and its (3, 3) tangent (right-perturbation) covariance, for
    independent steps: ``a Exp(xi_a) b Exp(xi_b) = (a b) Exp(Ad(b^-1) xi_a + xi_b)``."""
    adjoint = se2_adjoint(se2_inverse(delta_b))
    return se2_compose(delta_a, delta_b), adjoint @ cov_a @ adjoint.T + cov_b


def se2_conjugate(
    delta: np.ndarray, covariance: np.ndarray, pose_base_sensor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A sensor-frame relative pose and its tangent covariance expressed in base_link.

    ``D_base = M * D_sensor * M^-1`` with the mount ``M = pose_base_sensor``; a right
    perturbation ``xi`` of ``D_sensor`` becomes ``Ad(M) xi`` of ``D_base``.
    """
    adjoint = se2_adjoint(pose_base_sensor)
    moved = se2_compose(se2_compose(pose_base_sensor, delta), se2_inverse(pose_base_sensor))
    return moved, adjoint @ covariance @ adjoint.T


def transform_points_2d(pose: np.ndarray, points_xy: np.ndarray) -> np.ndarray:
    """Map (N, 2) points through the planar pose ``[x, y, yaw]`` (child frame -> parent frame)."""
    points_xy = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    return points_xy @ rotation_2d(pose[2]).T + np.asarray(pose[:2], dtype=float)


def first_per_voxel(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """Ascending indices of the first of the (N, D) ``points`` in each cubic voxel of side
    ``voxel_m`` (metres); all indices when ``voxel_m`` <= 0."""
    points = np.asarray(points, dtype=float)
    if voxel_m <= 0.0 or len(points) == 0:
        return np.arange(len(points))
    cells = np.floor(points / voxel_m).astype(np.int64)
    return np.sort(np.unique(cells, axis=0, return_index=True)[1])


def line_fit_2d(
    neighbours_xy: np.ndarray, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lines fitted by 2D PCA to N sets of k points, (N, k, 2), each point weighted by (N, k)
    ``weights`` (1 or 0 to leave a neighbour out; None: all 1). Returns (centroids (N, 2),
    unit normals (N, 2) across each set's major axis, smaller and larger eigenvalues (N,) of
    its scatter matrix, the summed squared spread across and along the line), in closed form."""
    if weights is None:
        weights = np.ones(neighbours_xy.shape[:2])
    centroid = np.sum(weights[..., None] * neighbours_xy, axis=1) / np.sum(weights, axis=1)[:, None]
    local = neighbours_xy - centroid[:, None, :]
    sxx = np.sum(weights * local[..., 0] ** 2, axis=1)
    syy = np.sum(weights * local[..., 1] ** 2, axis=1)
    sxy = np.sum(weights * local[..., 0] * local[..., 1], axis=1)
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # the major axis
    normal = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
    root = np.sqrt(0.25 * (sxx - syy) ** 2 + sxy**2)
    return centroid, normal, 0.5 * (sxx + syy) - root, 0.5 * (sxx + syy) + root


def interpolate_se2(
    stamps_s: np.ndarray, poses: np.ndarray, query_s: np.ndarray | float
) -> np.ndarray:
    """Linearly interpolate (N, 3) poses sampled at sorted ``stamps_s`` (yaw on the circle).

    Queries outside the sampled span are clamped to the end poses.
    """
    stamps_s = np.asarray(stamps_s, dtype=float)
    poses = np.asarray(poses, dtype=float)
    query = np.atleast_1d(np.asarray(query_s, dtype=float))
    x = np.interp(query, stamps_s, poses[:, 0])
    y = np.interp(query, stamps_s, poses[:, 1])
    yaw_unwrapped = np.unwrap(poses[:, 2])
    yaw = wrap_angle(np.interp(query, stamps_s, yaw_unwrapped))
    out = np.stack([x, y, yaw], axis=-1)
    return out if np.ndim(query_s) else out[0]


# ---------------------------------------------------------------- SE(3) and quaternions


def quat_wxyz_from_xyzw(q_xyzw: np.ndarray) -> np.ndarray:
    """Reorder a quaternion from ROS/scipy ``xyzw`` to smokyslam ``wxyz``."""
    q = np.asarray(q_xyzw, dtype=float)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


def quat_xyzw_from_wxyz(q_wxyz: np.ndarray) -> np.ndarray:
    """Reorder a quaternion from smokyslam ``wxyz`` to ROS/scipy ``xyzw``."""
    q = np.asarray(q_wxyz, dtype=float)
    return np.concatenate([q[..., 1:4], q[..., 0:1]], axis=-1)


def quat_wxyz_from_yaw(yaw_rad: np.ndarray | float) -> np.ndarray:
    """Quaternion ``wxyz`` of a rotation about +z; broadcasts."""
    half = 0.5 * np.asarray(yaw_rad, dtype=float)
    zeros = np.zeros_like(half)
    return np.stack([np.cos(half), zeros, zeros, np.sin(half)], axis=-1)


def yaw_from_quat_wxyz(q_wxyz: np.ndarray) -> np.ndarray | float:
    """Yaw (rotation about +z, ZYX convention) of quaternions ``wxyz``; broadcasts."""
    q = np.asarray(q_wxyz, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def rotation_matrix_from_quat_wxyz(q_wxyz: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a quaternion ``wxyz``."""
    return Rotation.from_quat(quat_xyzw_from_wxyz(q_wxyz)).as_matrix()


def quat_wxyz_from_rotation_matrix(R: np.ndarray) -> np.ndarray:
    """Quaternion ``wxyz`` (w >= 0) of a (3, 3) rotation matrix."""
    q = quat_wxyz_from_xyzw(Rotation.from_matrix(R).as_quat())
    return q if q[0] >= 0 else -q


def se3_matrix(translation_m: np.ndarray, q_wxyz: np.ndarray) -> np.ndarray:
    """(4, 4) transform from a translation and a quaternion ``wxyz``."""
    T = np.eye(4)
    T[:3, :3] = rotation_matrix_from_quat_wxyz(q_wxyz)
    T[:3, 3] = np.asarray(translation_m, dtype=float)
    return T


def se3_from_se2(pose: np.ndarray, z_m: float = 0.0) -> np.ndarray:
    """(4, 4) transform of a planar pose ``[x, y, yaw]`` lifted to height ``z_m``."""
    T = np.eye(4)
    T[:2, :2] = se2_matrix(*pose)[:2, :2]
    T[:3, 3] = [pose[0], pose[1], z_m]
    return T


def se3_inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rigid transform."""
    Ti = np.eye(4)
    R = T[:3, :3]
    Ti[:3, :3] = R.T
    Ti[:3, 3] = -R.T @ T[:3, 3]
    return Ti


# Optical camera axes (z forward, x right, y down) expressed in a body frame (x fwd, y left, z up).
R_BODY_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


# ---------------------------------------------------------------- grids


@dataclass(frozen=True)
class GridSpec:
    """Geometry of a 2D grid: ``shape = (rows_y, cols_x)``, square cells of ``resolution_m``.

    ``origin_xy_m`` is the world position of the lower-left corner of cell ``[0, 0]``.
    """

    origin_xy_m: tuple[float, float]
    resolution_m: float
    shape: tuple[int, int]

    def cells_of(self, points_xy: np.ndarray) -> np.ndarray:
        """(N, 2) integer cells ``[ix, iy]`` of (N, 2) world points (may be out of bounds)."""
        p = (np.asarray(points_xy, dtype=float) - np.asarray(self.origin_xy_m)) / self.resolution_m
        return np.floor(p).astype(np.int64)

    def centres_of(self, cells_ixy: np.ndarray) -> np.ndarray:
        """(N, 2) world positions of the centres of cells ``[ix, iy]``."""
        c = (np.asarray(cells_ixy, dtype=float) + 0.5) * self.resolution_m
        return c + np.asarray(self.origin_xy_m)

    def inside(self, cells_ixy: np.ndarray) -> np.ndarray:
        """(N,) bool: which cells ``[ix, iy]`` lie inside the grid."""
        c = np.asarray(cells_ixy)
        return (
            (c[:, 0] >= 0) & (c[:, 1] >= 0) & (c[:, 0] < self.shape[1]) & (c[:, 1] < self.shape[0])
        )

    def covering(self, other: GridSpec) -> GridSpec:
        """The grid at this resolution, on this grid's lattice, that covers both this grid's
        extent and ``other``'s (so this grid's own cells map onto whole cells)."""
        res = self.resolution_m
        ax0, ax1, ay0, ay1 = self.extent_m
        bx0, bx1, by0, by1 = other.extent_m
        ix0 = np.floor((min(ax0, bx0) - ax0) / res + 1e-6)
        iy0 = np.floor((min(ay0, by0) - ay0) / res + 1e-6)
        ix1 = np.ceil((max(ax1, bx1) - ax0) / res - 1e-6)
        iy1 = np.ceil((max(ay1, by1) - ay0) / res - 1e-6)
        origin = (float(ax0 + ix0 * res), float(ay0 + iy0 * res))
        return GridSpec(origin, res, (int(iy1 - iy0), int(ix1 - ix0)))

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the grid in the world."""
        x0, y0 = self.origin_xy_m
        return (
            x0,
            x0 + self.shape[1] * self.resolution_m,
            y0,
            y0 + self.shape[0] * self.resolution_m,
        )


def se2_fuse(
    a: np.ndarray, cov_a: np.ndarray, b: np.ndarray, cov_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Two independent estimates of one relative pose, each with its (3, 3) tangent
    (right-perturbation) covariance, fused by their information: the update of ``a`` by
    ``b`` as a measurement, ``a Exp(K log(a^-1 b))`` with ``K = cov_a (cov_a + cov_b)^-1``
    (``b``'s covariance taken in ``a``'s tangent, exact to first order for close estimates).
    Returns the fused pose and ``(I - K) cov_a``."""
    cov_a, cov_b = np.asarray(cov_a, dtype=float), np.asarray(cov_b, dtype=float)
    gain = np.linalg.solve((cov_a + cov_b).T, cov_a.T).T
    innovation = se2_log(se2_between(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))
    fused_cov = (np.eye(3) - gain) @ cov_a
    return se2_compose(a, se2_exp(gain @ innovation)), 0.5 * (fused_cov + fused_cov.T)
