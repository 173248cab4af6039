"""Monocular camera odometry that survives smoke: LK tracks, PnP on landmarks, keyframes.

Per frame: clean the image (impulse replacement / CLAHE as measured), follow the tracks with
LK from the latest keyframe, fit the pose to the tracked landmarks (PnP + RANSAC, then a
planar refinement). At keyframes (enough parallax, or too few landmarks left) the local map
triangulates new landmarks, bundle-adjusts the newest keyframes, and new corners are
detected. A map starts from two views (essential matrix), and starts again, with a new
scale, after tracking is lost.

Scale: the odometry is up to scale. The first map's first baseline is 1 unit; a map restarted
after a loss guesses its baseline from the speed before the loss, and the floor's depth below
the camera holds every map to the first map's units (``floor_scale.py``). Given the camera's
height above the floor, that depth also gives metres: ``metres_per_unit`` of each result.
``reinitializations`` counts the maps started after the first.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from smokyslam.config import CameraOdometryConfig
from smokyslam.frontends.camera.floor_scale import FloorScale
from smokyslam.frontends.camera.initializer import start_two_view
from smokyslam.frontends.camera.landmarks import angle_between_deg, project
from smokyslam.frontends.camera.local_map import LocalMap
from smokyslam.frontends.camera.pose import (
    PoseEstimate,
    camera_from_planar,
    planar_from_camera,
    solve_pnp,
)
from smokyslam.frontends.camera.preprocess import Preprocessor
from smokyslam.frontends.camera.result import (
    LOST_VARIANCE,
    CameraHealth,
    CameraOdometryResult,
    CameraView,
    TrackingStatus,
)
from smokyslam.frontends.camera.tracker import LKTracker
from smokyslam.geometry import se2_between, se2_compose
from smokyslam.types import CameraFrame, CameraIntrinsics

log = logging.getLogger(__name__)

MAX_EXTRAPOLATION_S = 1.0
"""While lost, the pose coasts at the last velocity this long, then holds still."""


class CameraOdometry:
    """Tracks a mono camera through a stream of frames; one verb, :meth:`track`."""

    def __init__(
        self,
        intrinsics: CameraIntrinsics,
        config: CameraOdometryConfig,
        camera_height_m: float | None,
    ) -> None:
        """``camera_height_m``: the optical centre's height above the floor (the rig's
        ``T_base_camera``), for metric scale; None when unknown."""
        self.intrinsics = intrinsics
        self.camera_height_m = camera_height_m
        self.config = config
        self.K = intrinsics.camera_matrix
        self._preprocessor = Preprocessor(config)
        self._tracker = LKTracker(config)
        self._map = LocalMap(self.K, config)
        self._floor = FloorScale(config)
        self._status = TrackingStatus.INITIALIZING
        self._T = camera_from_planar(np.zeros(3))
        self._velocity = np.zeros(3)  # planar body-frame motion per second
        self._speed = 0.0  # odometry units per second, smoothed
        self._stamp_s: float | None = None
        self._anchor_image: np.ndarray | None = None  # the latest keyframe's image
        self._reference_stamp_s = 0.0
        self._lost_since_s = 0.0
        self._reinitializations = 0
        self._clean: np.ndarray | None = None  # the latest frame after preprocessing

    # ------------------------------------------------------------------ public

    def track(self, frame: CameraFrame) -> CameraOdometryResult:
        """Process one frame and return its pose and health.

        frame.image: (H, W) uint8 mono at the intrinsics' size; (H, W, 3) colour is turned grey.
        """
        image = np.ascontiguousarray(frame.image, dtype=np.uint8)
        if image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        image, quality = self._preprocessor.apply(image)
        self._clean = image
        dt = 0.0 if self._stamp_s is None else max(frame.stamp_s - self._stamp_s, 0.0)
        if (
            self._status is TrackingStatus.LOST
            and frame.stamp_s - self._lost_since_s > MAX_EXTRAPOLATION_S
        ):
            self._velocity = np.zeros(3)
        pose_before = planar_from_camera(self._T)
        predicted = camera_from_planar(se2_compose(pose_before, self._velocity * dt))
        tracked = self._follow_tracks(image, predicted)
        keyframe_before = self._map.keyframe_id
        relative_from = self._map.keyframes.get(keyframe_before, self._T)
        health = CameraHealth(tracked=tracked)
        covariance = np.eye(3) * LOST_VARIANCE
        landmarks = np.zeros((0, 3))
        moved_by_start = reinitialized = False
        if self._stamp_s is None:
            self._restart(image, frame.stamp_s, self._T)
        elif self._status is TrackingStatus.TRACKING:
            tracked_pose = self._track_pose(image, predicted, tracked, force_keyframe=False)
            if tracked_pose is None:
                log.info("camera lost at %.2f s (%d tracks)", frame.stamp_s, tracked)
                self._status = TrackingStatus.LOST
                self._lost_since_s = frame.stamp_s
                self._T = predicted
                self._restart(image, frame.stamp_s, predicted)
            else:
                health, covariance, landmarks = tracked_pose
        else:
            self._T = predicted
            waiting = self._status
            moved_by_start = self._try_start(image, frame.stamp_s)
            if moved_by_start:
                tracked_pose = self._track_pose(image, self._T, tracked, force_keyframe=True)
                if tracked_pose is None:  # the start does not hold up: wait for another
                    self._status = waiting
                    self._restart(image, frame.stamp_s, self._T)
                else:
                    health, covariance, landmarks = tracked_pose
                    reinitialized = waiting is TrackingStatus.LOST
                    self._reinitializations += int(reinitialized)
        if not moved_by_start:
            self._update_velocity(pose_before, dt)
        self._stamp_s = frame.stamp_s
        pose = planar_from_camera(self._T)
        relative_from = self._map.keyframes.get(keyframe_before, relative_from)  # adjusted
        tracking = self._status is TrackingStatus.TRACKING
        return CameraOdometryResult(
            stamp_s=frame.stamp_s,
            status=self._status,
            pose_world_camera=pose,
            T_world_camera=self._T.copy(),
            keyframe_id=keyframe_before,
            relative_pose=se2_between(planar_from_camera(relative_from), pose),
            covariance=covariance,
            health=health,
            quality=quality,
            is_keyframe=tracking and self._map.keyframe_id != keyframe_before,
            reinitialized=reinitialized,
            reinitializations=self._reinitializations,
            landmarks_world=landmarks,
            metres_per_unit=self.metres_per_unit,
        )

    @property
    def metres_per_unit(self) -> float | None:
        """Metres per odometry unit: the camera height over the first map's floor depth
        below the camera (None until the floor is found, or without a height)."""
        reference = self._floor.reference_height
        if self.camera_height_m is None or reference is None:
            return None
        return self.camera_height_m / reference

    def view(self, raw: np.ndarray) -> CameraView:
        """The latest frame as tracked: ``raw`` (the image given to :meth:`track`), its
        cleaned image and the points being tracked in it."""
        tracks = self._map.tracks
        clean = self._clean if self._clean is not None else raw
        return CameraView(raw, clean, tracks.uv_px.copy(), tracks.has_landmark.copy())

    def landmarks_world(self) -> np.ndarray:
        """(N, 3) every landmark triangulated so far, in the odometry world (x forward, y left,
        z up from the first camera centre), odometry units. Maps restarted after a loss bring
        their own scale."""
        return self._map.landmarks_world()

    # ------------------------------------------------------------------ steps

    def _follow_tracks(self, image: np.ndarray, predicted: np.ndarray) -> int:
        """LK from the latest keyframe image, starting from the previous positions (landmarks:
        from their projection in ``predicted``).

        Tracking from the keyframe rather than the previous frame keeps LK errors from adding
        up frame after frame: on a forward walk they add up to a lag towards the focus of
        expansion.
        """
        tracks = self._map.tracks
        if self._anchor_image is None or len(tracks) == 0:
            return 0
        guess = tracks.uv_px.copy()
        has = tracks.has_landmark
        if has.any():
            uv, z = project(predicted, tracks.landmark_world[has], self.K)
            usable = (z > 0) & np.isfinite(uv).all(axis=1)
            guess[np.flatnonzero(has)[usable]] = uv[usable]
        uv, ok = self._tracker.track(self._anchor_image, image, tracks.anchor_uv_px, guess)
        tracks.uv_px = uv
        self._map.drop(ok)
        return len(tracks)

    def _track_pose(
        self, image: np.ndarray, guess: np.ndarray, tracked: int, force_keyframe: bool
    ) -> tuple[CameraHealth, np.ndarray, np.ndarray] | None:
        """PnP against the landmarks; keyframe if due. None when too few inliers (lost)."""
        tracks = self._map.tracks
        has = tracks.has_landmark
        estimate = solve_pnp(
            tracks.landmark_world[has],
            tracks.uv_px[has],
            self.K,
            guess,
            self.config.pnp_threshold_px,
            self.config.planar_motion,
        )
        if estimate is None or estimate.inliers.sum() < self.config.min_inliers:
            return None
        health, landmarks = self._accept_pose(estimate, tracked)
        if force_keyframe or self._needs_keyframe(health):
            self._make_keyframe(image)
        return health, estimate.covariance, landmarks

    def _accept_pose(self, estimate: PoseEstimate, tracked: int) -> tuple[CameraHealth, np.ndarray]:
        """Take a PnP pose; drop the landmark tracks that disagree with it."""
        tracks = self._map.tracks
        has = tracks.has_landmark
        keep = np.ones(len(tracks), dtype=bool)
        keep[np.flatnonzero(has)[~estimate.inliers]] = False
        self._map.drop(keep, archive=False)
        self._T = estimate.T_world_camera
        inlier_points = tracks.landmark_world[tracks.has_landmark]
        C_key = self._map.keyframe_pose[:3, 3]
        parallax = angle_between_deg(inlier_points - C_key, inlier_points - self._T[:3, 3])
        n_inliers = int(estimate.inliers.sum())
        health = CameraHealth(
            tracked=tracked,
            landmarks=int(has.sum()),
            inliers=n_inliers,
            inlier_ratio=n_inliers / max(int(has.sum()), 1),
            parallax_deg=float(np.median(parallax)),
            residual_rms_px=estimate.residual_rms_px,
        )
        return health, inlier_points

    def _needs_keyframe(self, health: CameraHealth) -> bool:
        """Too few landmarks left, or enough parallax since the last keyframe."""
        cfg = self.config
        return health.inliers < cfg.min_tracked or health.parallax_deg >= cfg.keyframe_parallax_deg

    def _make_keyframe(self, image: np.ndarray) -> None:
        """Keyframe here: the map triangulates and adjusts; then new corners, anchored here."""
        self._T = self._map.add_keyframe(self._T)
        self._hold_floor_scale()
        self._detect(image)

    def _hold_floor_scale(self) -> None:
        """Rescale the map about the camera so the floor stays at its reference depth."""
        if not (self.config.floor_scale and self.config.planar_motion):
            return
        factor = self._floor.correction(self._map.live_landmarks())
        if factor != 1.0:
            self._map.rescale(self._T[:3, 3].copy(), factor)
            self._velocity[:2] *= factor
            self._speed *= factor

    def _detect(self, image: np.ndarray) -> None:
        """New corners in the new keyframe; every track is anchored (tracked from) here."""
        tracks = self._map.tracks
        self._anchor_image = image
        new = self._tracker.detect(image, tracks.uv_px, self.config.max_corners - len(tracks))
        self._map.add_corners(new)
        tracks.anchor_uv_px = tracks.uv_px.copy()

    def _restart(self, image: np.ndarray, stamp_s: float, T_world_camera: np.ndarray) -> None:
        """Drop the map; make this frame the reference view of a new two-view start."""
        self._map.reset(T_world_camera)
        self._floor.restart()
        self._reference_stamp_s = stamp_s
        self._detect(image)

    def _try_start(self, image: np.ndarray, stamp_s: float) -> bool:
        """Attempt a two-view start against the reference view; restart it if tracks ran out.

        Returns True when a map started (the pose jumped over the frames it waited).
        """
        tracks = self._map.tracks
        T_reference = self._map.keyframe_pose
        first_map = self._status is TrackingStatus.INITIALIZING
        elapsed_s = max(stamp_s - self._reference_stamp_s, 1e-3)
        baseline = self._speed * elapsed_s if not first_map and self._speed > 0 else 1.0
        start = start_two_view(
            T_reference, tracks.birth_uv_px, tracks.uv_px, self.K, baseline, self.config
        )
        if start is None:
            if len(tracks) < max(self.config.min_inliers, self.config.max_corners // 4):
                self._restart(image, stamp_s, self._T)
            return False
        tracks.landmark_world = start.points_world
        tracks.baseline = np.full(len(tracks), baseline)
        self._map.drop(start.inliers, archive=False)
        step = se2_between(
            planar_from_camera(T_reference), planar_from_camera(start.T_world_camera)
        )
        self._velocity = step / elapsed_s
        self._speed = float(np.hypot(*step[:2]) / elapsed_s)
        self._T = start.T_world_camera
        self._status = TrackingStatus.TRACKING
        return True

    def _update_velocity(self, pose_before: np.ndarray, dt: float) -> None:
        if self._status is not TrackingStatus.TRACKING or dt <= 0:
            return
        step = se2_between(pose_before, planar_from_camera(self._T))
        self._velocity = step / dt
        self._speed = 0.8 * self._speed + 0.2 * float(np.hypot(*step[:2]) / dt)
