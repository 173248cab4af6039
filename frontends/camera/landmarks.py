"""The tracked points and the landmarks triangulated from them.

Every track is a row of :class:`Tracks`: its pixel position now, and either a world landmark
or, while it has none yet, where it was born (keyframe and pixel) so it can be triangulated
against a later keyframe once the camera has moved enough.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from smokyslam.geometry import se3_inverse

RAY_ANGLE_FLOOR_DEG = 0.05
"""Points whose two rays meet at a smaller angle are too far to place (depth unknown)."""

EPIPOLE_CLEARANCE_DEG = 3.0
"""Points seen closer than this to the direction of travel are not triangulated."""


@dataclass
class Tracks:
    """Columnar table of N tracks (every array has N rows).

    uv_px: (N, 2) pixel position in the latest frame.
    anchor_uv_px: (N, 2) pixel position in the latest keyframe, which LK tracks from.
    landmark_world: (N, 3) world point of the track, NaN until triangulated (odometry units).
    baseline: (N,) distance between the two camera centres the landmark was triangulated
        from (odometry units), NaN until triangulated.
    birth_uv_px: (N, 2) pixel position in the keyframe the track was born in.
    birth_keyframe: (N,) int id of that keyframe.
    track_id: (N,) int unique id, increasing in the order tracks were added.
    """

    uv_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    anchor_uv_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    landmark_world: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    baseline: np.ndarray = field(default_factory=lambda: np.zeros(0))
    birth_uv_px: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    birth_keyframe: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    track_id: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.uv_px)

    @property
    def has_landmark(self) -> np.ndarray:
        """(N,) bool: tracks with a triangulated landmark."""
        return np.isfinite(self.landmark_world[:, 0])

    def keep(self, mask: np.ndarray) -> None:
        """Drop the tracks where the (N,) bool ``mask`` is False."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name)[mask])

    def add(self, uv_px: np.ndarray, keyframe_id: int, first_id: int) -> None:
        """Append (M, 2) new corners born in keyframe ``keyframe_id``, without landmarks,
        with track ids ``first_id, first_id + 1, ...``."""
        m = len(uv_px)
        self.track_id = np.concatenate([self.track_id, np.arange(first_id, first_id + m)])
        self.uv_px = np.vstack([self.uv_px, uv_px])
        self.anchor_uv_px = np.vstack([self.anchor_uv_px, uv_px])
        self.landmark_world = np.vstack([self.landmark_world, np.full((m, 3), np.nan)])
        self.baseline = np.concatenate([self.baseline, np.full(m, np.nan)])
        self.birth_uv_px = np.vstack([self.birth_uv_px, uv_px])
        self.birth_keyframe = np.concatenate(
            [self.birth_keyframe, np.full(m, keyframe_id, dtype=np.int64)]
        )


def angle_between_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) angles in degrees between rows of two (N, 3) arrays of vectors."""
    cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def project(
    T_world_camera: np.ndarray, points_world: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project (N, 3) world points: (N, 2) pixels and (N,) depths along the optical axis."""
    T = se3_inverse(T_world_camera)
    p = points_world @ T[:3, :3].T + T[:3, 3]
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (p[:, :2] / z[:, None]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    return uv, z


def _project_each(
    T_world_camera: np.ndarray, points_world: np.ndarray, K: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`project` with one (N, 4, 4) pose per (N, 3) point."""
    R = T_world_camera[:, :3, :3]
    p = np.einsum("nji,nj->ni", R, points_world - T_world_camera[:, :3, 3])  # R^T (X - t)
    z = p[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (p[:, :2] / z[:, None]) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    return uv, z


def triangulate(
    T_world_a: np.ndarray,
    T_world_b: np.ndarray,
    uv_a_px: np.ndarray,
    uv_b_px: np.ndarray,
    K: np.ndarray,
    max_error_px: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Triangulate (N, 2) pixel pairs seen from two camera poses (optical axes).

    T_world_a: (4, 4), or (N, 4, 4) one first view per pair; T_world_b: (4, 4).
    Linear (DLT) triangulation, all pairs at once. Returns (N, 3) world points, their (N,)
    ray angles in degrees (NaN behind a camera), and an (N,) bool mask of the points in front
    of both cameras, seen under a ray angle of at least ``RAY_ANGLE_FLOOR_DEG`` and
    reprojecting within ``max_error_px`` in both images. Whether a pair of views has parallax
    enough is the caller's decision, made once per pair: a per-point angle threshold would
    keep the points noise made look closer.
    """
    n = len(uv_a_px)
    if n == 0:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=bool)
    T_a = np.broadcast_to(np.asarray(T_world_a, dtype=float), (n, 4, 4))
    T_cw_a = np.linalg.inv(T_a)
    P_a = np.einsum("ij,njk->nik", K, T_cw_a[:, :3])
    P_b = K @ se3_inverse(T_world_b)[:3]
    uv_a, uv_b = np.asarray(uv_a_px, dtype=float), np.asarray(uv_b_px, dtype=float)
    A = np.stack(
        [
            uv_a[:, 0:1] * P_a[:, 2] - P_a[:, 0],
            uv_a[:, 1:2] * P_a[:, 2] - P_a[:, 1],
            uv_b[:, 0:1] * P_b[2] - P_b[0],
            uv_b[:, 1:2] * P_b[2] - P_b[1],
        ],
        axis=1,
    )
    X = np.linalg.svd(A)[2][:, -1]  # (N, 4) null vectors
    with np.errstate(divide="ignore", invalid="ignore"):
        points = X[:, :3] / X[:, 3:4]
    uv_a_hat, z_a = _project_each(T_a, points, K)
    uv_b_hat, z_b = project(T_world_b, points, K)
    error = np.maximum(
        np.linalg.norm(uv_a_hat - uv_a, axis=1), np.linalg.norm(uv_b_hat - uv_b, axis=1)
    )
    in_front = (z_a > 0) & (z_b > 0) & np.isfinite(points).all(axis=1)
    angle = np.full(n, np.nan)
    angle[in_front] = angle_between_deg(
        points[in_front] - T_a[in_front, :3, 3], points[in_front] - T_world_b[:3, 3]
    )
    # Points seen near the epipole (the direction of travel) have no depth to speak of. Judge
    # that from the bearing alone: a test on the triangulated angle would keep the points
    # noise made look closer, and shrink the scale a little at every keyframe.
    baseline = T_world_b[:3, 3] - T_a[:, :3, 3]
    rays = np.column_stack([uv_b, np.ones(n)]) @ np.linalg.inv(K).T @ T_world_b[:3, :3].T
    sine = np.linalg.norm(np.cross(rays, baseline), axis=1) / (
        np.linalg.norm(rays, axis=1) * np.maximum(np.linalg.norm(baseline, axis=1), 1e-12)
    )
    off_epipole = sine >= np.sin(np.radians(EPIPOLE_CLEARANCE_DEG))
    ok = in_front & off_epipole & (angle >= RAY_ANGLE_FLOOR_DEG) & (error <= max_error_px)
    return points, angle, ok
