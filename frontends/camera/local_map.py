"""The odometry's local map: tracks, keyframe poses, their observations, and landmarks.

At each keyframe the map records where every track was seen, triangulates the tracks whose
birth keyframe is now far enough away, and adjusts the last few keyframes and the landmarks
they see together (:mod:`bundle`), which keeps the scale from drifting.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import CameraOdometryConfig
from smokyslam.frontends.camera.bundle import WindowProblem, adjust
from smokyslam.frontends.camera.landmarks import Tracks, project, triangulate
from smokyslam.frontends.camera.pose import (
    body_to_world,
    camera_from_planar,
    planar_from_camera,
    project_planar,
)

CANDIDATE_MAX_KEYFRAMES = 6
"""Tracks still without a landmark this many keyframes after birth are dropped."""

FREE_KEYFRAMES = 4
"""Newest keyframes the window adjustment moves; older ones stay fixed and carry the gauge
and the scale (as in a local bundle adjustment)."""

MIN_SHARED_LANDMARKS = 15
"""A keyframe joins the adjustment only if it sees this many of the live landmarks."""


class LocalMap:
    """Tracks and keyframes of one map (one scale); :meth:`reset` starts a new one."""

    def __init__(self, K: np.ndarray, config: CameraOdometryConfig) -> None:
        self.K = K
        self.config = config
        self.tracks = Tracks()
        self.keyframe_id = -1
        self.keyframes: dict[int, np.ndarray] = {}  # id -> T_world_camera
        self._observations: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # id -> (ids, uv)
        self._next_track_id = 0
        self._archive: list[np.ndarray] = []

    @property
    def keyframe_pose(self) -> np.ndarray:
        """``T_world_camera`` of the latest keyframe."""
        return self.keyframes[self.keyframe_id]

    def landmarks_world(self) -> np.ndarray:
        """(N, 3) every landmark kept so far: those of finished tracks, then the live ones."""
        return np.vstack([np.zeros((0, 3)), *self._archive, self.live_landmarks()])

    def drop(self, keep: np.ndarray, archive: bool = True) -> None:
        """Remove tracks where the (N,) bool ``keep`` is False, archiving their landmarks."""
        gone = ~keep & self.tracks.has_landmark
        if archive and gone.any():
            self._archive.append(self.tracks.landmark_world[gone])
        self.tracks.keep(keep)

    def live_landmarks(self) -> np.ndarray:
        """(N, 3) world points of the tracks that have a landmark now."""
        return self.tracks.landmark_world[self.tracks.has_landmark]

    def rescale(self, centre_world: np.ndarray, factor: float) -> None:
        """Scale the map (landmarks, keyframe positions, baselines) by ``factor`` about the
        (3,) world point ``centre_world``; poses keep their orientation."""
        tracks = self.tracks
        tracks.landmark_world = centre_world + factor * (tracks.landmark_world - centre_world)
        tracks.baseline = tracks.baseline * factor
        for T in self.keyframes.values():
            T[:3, 3] = centre_world + factor * (T[:3, 3] - centre_world)

    def reset(self, T_world_camera: np.ndarray) -> None:
        """Archive the map and start an empty one whose first keyframe sits at this pose."""
        self.drop(np.zeros(len(self.tracks), dtype=bool))
        self.keyframes = {}
        self._observations = {}
        self._new_keyframe(T_world_camera)

    def add_corners(self, uv_px: np.ndarray) -> None:
        """New (M, 2) corners seen in the latest keyframe."""
        self.tracks.add(uv_px, self.keyframe_id, self._next_track_id)
        self._next_track_id += len(uv_px)
        self._observe()

    def add_keyframe(self, T_world_camera: np.ndarray) -> np.ndarray:
        """Make the current frame (tracks at their current pixels) a keyframe.

        Triangulates, adjusts the window, drops stale candidates; returns the adjusted
        ``T_world_camera`` of this keyframe.
        """
        self._new_keyframe(T_world_camera)
        self._triangulate()
        if self.config.planar_motion:
            self._adjust_window()
        tracks = self.tracks
        stale = ~tracks.has_landmark & (
            tracks.birth_keyframe <= self.keyframe_id - CANDIDATE_MAX_KEYFRAMES
        )
        self.drop(~stale)
        return self.keyframe_pose

    # ------------------------------------------------------------------ steps

    def _new_keyframe(self, T_world_camera: np.ndarray) -> None:
        self.keyframe_id += 1
        self.keyframes[self.keyframe_id] = T_world_camera.copy()
        self._observe()
        window = sorted(self._observations)[-self.config.window_keyframes :]
        self._observations = {k: self._observations[k] for k in window}
        needed = set(window) | set(np.unique(self.tracks.birth_keyframe).tolist())
        self.keyframes = {k: v for k, v in self.keyframes.items() if k in needed}

    def _observe(self) -> None:
        """Record every track's pixel in the latest keyframe."""
        self._observations[self.keyframe_id] = (
            self.tracks.track_id.copy(),
            self.tracks.uv_px.copy(),
        )

    def _triangulate(self) -> None:
        """Triangulate tracks against their birth keyframes, all qualifying tracks at once.

        A birth keyframe qualifies once its baseline to this one reaches
        tan(``min_triangulation_deg``) x the median landmark depth; landmarks are
        re-triangulated whenever their baseline has grown.
        """
        tracks = self.tracks
        T_now = self.keyframe_pose
        has = tracks.has_landmark
        _, depth = project(T_now, tracks.landmark_world[has], self.K)
        scene_depth = float(np.median(depth)) if has.any() else np.inf
        min_baseline = scene_depth * np.tan(np.radians(self.config.min_triangulation_deg))
        births = np.unique(tracks.birth_keyframe)
        T_births = np.array([self.keyframes[int(b)] for b in births])  # one per keyframe
        baselines = np.linalg.norm(T_births[:, :3, 3] - T_now[:3, 3], axis=1)
        qualifies = (births != self.keyframe_id) & (baselines >= min_baseline)
        group = np.searchsorted(births, tracks.birth_keyframe)
        rows = np.flatnonzero(qualifies[group])
        if len(rows) == 0:
            return
        points, _, ok = triangulate(
            T_births[group[rows]],
            T_now,
            tracks.birth_uv_px[rows],
            tracks.uv_px[rows],
            self.K,
            self.config.pnp_threshold_px,
        )
        baseline = baselines[group[rows]]
        better = ok & ~(tracks.baseline[rows] >= baseline)  # NaN: no landmark yet
        tracks.landmark_world[rows[better]] = points[better]
        tracks.baseline[rows[better]] = baseline[better]

    def _adjust_window(self) -> None:
        """Bundle-adjust the newest keyframes and the live landmarks, older ones held fixed.

        Only keyframes that see at least ``MIN_SHARED_LANDMARKS`` of the live landmarks take
        part: the fixed ones must tie the free ones down, or the gauge (and the scale) floats.
        """
        tracks = self.tracks
        rows = np.flatnonzero(tracks.has_landmark)
        ids = tracks.track_id[rows]  # ascending: tracks are appended in id order
        window, obs_lm, obs_kf, obs_uv = [], [], [], []
        for k in sorted(self._observations):
            seen_ids, seen_uv = self._observations[k]
            at = np.searchsorted(ids, seen_ids)
            hit = (at < len(ids)) & (ids[np.minimum(at, len(ids) - 1)] == seen_ids)
            if hit.sum() < MIN_SHARED_LANDMARKS:
                continue
            obs_lm.append(at[hit])
            obs_kf.append(np.full(hit.sum(), len(window)))
            obs_uv.append(seen_uv[hit])
            window.append(k)
        fixed = np.arange(len(window)) < len(window) - FREE_KEYFRAMES
        if fixed.sum() < 2 or window[-1] != self.keyframe_id:
            return
        lm, kf, uv = np.concatenate(obs_lm), np.concatenate(obs_kf), np.concatenate(obs_uv)
        # anchor: each landmark's first observation in the window
        order = np.lexsort((kf, lm))
        lm, kf, uv = lm[order], kf[order], uv[order]
        first = np.r_[True, lm[1:] != lm[:-1]]
        anchor_kf = np.full(len(rows), -1)
        anchor_uv = np.zeros((len(rows), 2))
        anchor_kf[lm[first]] = kf[first]
        anchor_uv[lm[first]] = uv[first]
        poses = np.array([planar_from_camera(self.keyframes[k]) for k in window])
        _, depth = project_planar(
            poses[np.maximum(anchor_kf, 0)], tracks.landmark_world[rows], self.K
        )
        ray = np.column_stack([anchor_uv, np.ones(len(rows))]) @ np.linalg.inv(self.K).T
        n_obs = np.bincount(lm[~first], minlength=len(rows))
        usable = (anchor_kf >= 0) & (depth > 0) & (n_obs > 0)
        keep_obs = ~first & usable[lm]
        index = np.cumsum(usable) - 1
        problem = WindowProblem(
            poses=poses,
            fixed=fixed,
            anchor=anchor_kf[usable],
            anchor_ray=ray[usable],
            inverse_depth=1.0 / depth[usable],
            obs_landmark=index[lm[keep_obs]],
            obs_keyframe=kf[keep_obs],
            obs_uv_px=uv[keep_obs],
        )
        if len(problem.inverse_depth) < self.config.min_inliers:
            return
        errors = adjust(problem, self.K)
        for f, k in enumerate(window):
            if not fixed[f]:
                self.keyframes[k] = camera_from_planar(problem.poses[f])
        p_cam = problem.anchor_ray / np.maximum(problem.inverse_depth, 1e-12)[:, None]
        points = body_to_world(problem.poses[problem.anchor], p_cam)
        worst = np.zeros(len(points))
        np.maximum.at(worst, problem.obs_landmark, errors)
        good = (problem.inverse_depth > 0) & (worst <= 2.0 * self.config.pnp_threshold_px)
        adjusted = rows[usable]
        tracks.landmark_world[adjusted[good]] = points[good]
        keep = np.ones(len(tracks), dtype=bool)
        keep[adjusted[~good]] = False
        self.drop(keep, archive=False)
