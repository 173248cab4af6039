"""Scale-drift correction from the floor: a level camera stays at one height above it.

Monocular odometry loses scale a little at every keyframe: landmarks triangulated from short
baselines (mostly in turns, where they leave the view fast) come out slightly too near, the
poses fitted to them move slightly too little, and the error compounds (measured: the scale
shrank 9x over a 120 s office walk). A level camera carried at a constant height over a flat
floor has a scale reference in every view: the floor's depth below the camera. This module
measures that height in odometry units at every keyframe and returns the factor that brings
it back to the height the first map measured.

The odometry stays up to scale: the reference is the first map's own floor height (in its
own units), not a height in metres. Maps restarted after a loss are brought to the same
reference, so their scale no longer jumps.

Floor landmarks are found without labels: the floor is the lowest surface, so its landmarks
are the deepest cluster below the camera with enough support (``floor_min_points`` within
``floor_gate`` of each other); a few gated medians then centre on it. Once found, the search
keeps to heights near the tracked one, so a frame that sees little floor does not jump to
another cluster. Wall corners near the floor (the lowest mortar line) can fall into the gate
and pull the height a little low; the bias is steady, so it shows as a constant scale, not
as a drift. Limitation: while no floor is in view, the deepest wall points with enough
support pass for the floor; the tracking window keeps the error of such a frame within
two gates.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config import CameraOdometryConfig

CENTRING_ITERATIONS = 3
"""Gated medians that centre the height on the cluster found."""

TRACKING_WINDOW = 2.0
"""Once tracked, the floor is searched within this many gates of the tracked height."""

MAX_MISSES = 2
"""Keyframes in a row without the floor in the gate before it is searched for afresh."""


class FloorScale:
    """Tracks the floor height below the camera; one verb, :meth:`correction`."""

    def __init__(self, config: CameraOdometryConfig) -> None:
        self.config = config
        self.reference_height: float | None = None  # first map's floor height, its units
        self._height: float | None = None  # tracked height in the current map's units
        self._misses = 0

    def restart(self) -> None:
        """A new map began (new scale): find the floor again, keep the reference."""
        self._height = None
        self._misses = 0

    def correction(self, points_world: np.ndarray) -> float:
        """Scale factor for the map, given (N, 3) live landmarks in the odometry world.

        The world's z axis is up from the camera centre (a level camera at z = 0), so a
        landmark's height below the camera is ``-z``. Returns 1.0 while the floor is not
        seen by at least ``floor_min_points`` landmarks.
        """
        cfg = self.config
        depth_below = -np.asarray(points_world, dtype=float).reshape(-1, 3)[:, 2]
        depth_below = depth_below[np.isfinite(depth_below) & (depth_below > 0)]
        if len(depth_below) < cfg.floor_min_points:
            return 1.0
        height = self._find_floor(depth_below, self._height)
        if height is None:
            self._misses += 1
            if self._misses >= MAX_MISSES:
                self._height = None
            return 1.0
        self._misses = 0
        if self.reference_height is None:
            self.reference_height = self._height = height
            return 1.0
        factor = float((self.reference_height / height) ** cfg.floor_scale_gain)
        self._height = height * factor
        return factor

    def _find_floor(self, depth_below: np.ndarray, near: float | None) -> float | None:
        """The deepest well-supported cluster of heights (within the tracking window of
        ``near`` when given), centred by gated medians; None if there is none."""
        gate, needed = self.config.floor_gate, self.config.floor_min_points
        heights = np.sort(depth_below)

        def count(low: np.ndarray, high: np.ndarray) -> np.ndarray:
            return np.searchsorted(heights, high, side="right") - np.searchsorted(heights, low)

        support = count(heights * (1 - gate), heights * (1 + gate))
        candidate = support >= needed
        if near is not None:
            candidate &= np.abs(heights - near) <= TRACKING_WINDOW * gate * near
        if not candidate.any():
            return None
        height: float | None = float(heights[np.flatnonzero(candidate)[-1]])
        for _ in range(CENTRING_ITERATIONS):
            height = self._gated_median(heights, height)
            if height is None:
                return None
        return height

    def _gated_median(self, heights: np.ndarray, height: float) -> float | None:
        near = np.abs(heights - height) <= self.config.floor_gate * height
        if near.sum() < self.config.floor_min_points:
            return None
        return float(np.median(heights[near]))
