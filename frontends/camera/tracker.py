"""Sub-pixel corner tracking: Shi-Tomasi corners followed by pyramidal Lucas-Kanade.

Corners are detected only at keyframes and only away from the points already tracked; every
other frame costs one forward and one backward LK pass on a few hundred points.
"""

from __future__ import annotations

import cv2
import numpy as np

from smokyslam.config import CameraOdometryConfig

_LK_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)

BACKWARD_LEVELS = 1
"""Pyramid levels of the backward (checking) LK pass."""

PATCH_ERROR_FACTOR, PATCH_ERROR_FLOOR = 3.0, 8.0
"""A track whose LK patch error exceeds 3x the frame's median (and 8 grey levels) is dropped."""


class LKTracker:
    """Builds pyramids, follows points between consecutive frames and finds new corners."""

    def __init__(self, config: CameraOdometryConfig) -> None:
        self.config = config
        self._window = (config.lk_window_px, config.lk_window_px)

    def track(
        self,
        previous: np.ndarray,
        current: np.ndarray,
        uv_px: np.ndarray,
        guess_uv_px: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Follow (N, 2) pixel points from the ``previous`` (for the odometry: the latest
        keyframe's) into the ``current`` (H, W) image.

        guess_uv_px: optional (N, 2) predicted positions in ``current`` (e.g. landmarks
            projected at a predicted pose), used as the LK starting point.
        Returns (N, 2) float64 positions and an (N,) bool mask of points that were found, stay
        inside the image, match their patch about as well as the frame's typical track, and
        come back to within ``fb_max_error_px`` when tracked backwards.
        """
        n = len(uv_px)
        if n == 0:
            return np.zeros((0, 2)), np.zeros(0, dtype=bool)
        p0 = uv_px.astype(np.float32).reshape(-1, 1, 2)
        flags = 0
        p1_init = None
        if guess_uv_px is not None:
            flags = cv2.OPTFLOW_USE_INITIAL_FLOW
            p1_init = guess_uv_px.astype(np.float32).reshape(-1, 1, 2).copy()
        p1, ok1, error = cv2.calcOpticalFlowPyrLK(
            previous,
            current,
            p0,
            p1_init,
            winSize=self._window,
            maxLevel=self.config.lk_levels,
            criteria=_LK_CRITERIA,
            flags=flags,
        )
        # The backward check starts at the original points, so it needs no coarse levels:
        # a wrong forward match drifts away from them even at full resolution.
        p0_back, ok0, _ = cv2.calcOpticalFlowPyrLK(
            current,
            previous,
            p1,
            p0.copy(),
            winSize=self._window,
            maxLevel=min(self.config.lk_levels, BACKWARD_LEVELS),
            criteria=_LK_CRITERIA,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        uv1 = p1.reshape(-1, 2).astype(np.float64)
        fb_error = np.linalg.norm(p0_back.reshape(-1, 2) - p0.reshape(-1, 2), axis=1)
        h, w = current.shape[:2]
        inside = (uv1[:, 0] >= 0) & (uv1[:, 1] >= 0) & (uv1[:, 0] <= w - 1) & (uv1[:, 1] <= h - 1)
        found = ok1.ravel().astype(bool) & ok0.ravel().astype(bool) & inside
        # Patch difference (mean absolute grey level): a match into other texture, e.g. an
        # occluder, differs far more than the frame's typical track does.
        error = error.ravel()
        typical = np.median(error[found]) if found.any() else 0.0
        similar = error <= max(PATCH_ERROR_FACTOR * typical, PATCH_ERROR_FLOOR)
        ok = found & similar & (fb_error < self.config.fb_max_error_px)
        return uv1, ok

    def detect(self, image: np.ndarray, existing_uv_px: np.ndarray, count: int) -> np.ndarray:
        """Up to ``count`` new (M, 2) corners at least ``min_distance_px`` from existing points.

        The image border (half an LK window) is left out, where tracks die at once.
        """
        if count <= 0:
            return np.zeros((0, 2))
        cfg = self.config
        h, w = image.shape[:2]
        border = cfg.lk_window_px // 2
        mask = np.zeros((h, w), np.uint8)
        mask[border : h - border, border : w - border] = 255
        if len(existing_uv_px):
            taken = np.zeros((h, w), np.uint8)
            uv = np.clip(np.rint(existing_uv_px).astype(np.int64), 0, [w - 1, h - 1])
            taken[uv[:, 1], uv[:, 0]] = 255
            side = 2 * int(np.ceil(cfg.min_distance_px)) + 1
            taken = cv2.dilate(taken, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side, side)))
            mask[taken > 0] = 0
        corners = cv2.goodFeaturesToTrack(
            image, count, cfg.quality_level, cfg.min_distance_px, mask=mask, blockSize=3
        )
        if corners is None:
            return np.zeros((0, 2))
        return corners.reshape(-1, 2).astype(np.float64)
