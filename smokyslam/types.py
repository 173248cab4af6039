"""Typed frames that flow between stages: reader -> smoke -> frontends -> backend -> mappers.

Every array states its shape, dtype, unit and frame. Frames are plain dataclasses (no I/O).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from smokyslam.geometry import GridSpec


@dataclass
class RadarScan:
    """One radar frame.

    points_xyz_m: (N, 3) float64, metres, radar frame (x forward, y left, z up).
    intensity: (N,) float64, sensor units (dB-like for TI).
    doppler_mps: (N,) float64, radial velocity, positive moving away from the sensor; NaN
    where unknown (a sensor or log without velocities).
    """

    stamp_s: float
    points_xyz_m: np.ndarray
    intensity: np.ndarray
    doppler_mps: np.ndarray
    frame_id: str = "radar"

    def __len__(self) -> int:
        return int(self.points_xyz_m.shape[0])

    @property
    def points_xy_m(self) -> np.ndarray:
        """(N, 2) planar points, radar frame."""
        return self.points_xyz_m[:, :2]


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in pixels (no distortion)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def camera_matrix(self) -> np.ndarray:
        """(3, 3) camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass
class CameraFrame:
    """One camera image.

    image: (H, W) uint8 mono.
    depth_m: (H, W) float32 metres along the optical axis, or None when the log has no depth.
    """

    stamp_s: float
    image: np.ndarray
    intrinsics: CameraIntrinsics | None = None
    depth_m: np.ndarray | None = None
    frame_id: str = "camera"


@dataclass
class ImuSample:
    """One IMU sample in the IMU/body frame.

    gyro_radps: (3,) angular rate, rad/s. accel_mps2: (3,) specific force, m/s^2.
    """

    stamp_s: float
    gyro_radps: np.ndarray
    accel_mps2: np.ndarray


@dataclass
class GroundTruthPose:
    """Ground-truth planar pose of ``base_link`` in the world: ``T_world_base`` as [x, y, yaw]."""

    stamp_s: float
    pose_world_base: np.ndarray


@dataclass
class GroundTruthTrajectory:
    """The log's ground truth of ``base_link``: (M,) increasing stamps_s and (M, 3)
    poses_world_base ``[x_m, y_m, yaw_rad]``. Only evaluation reads it; estimators never do."""

    stamps_s: np.ndarray
    poses_world_base: np.ndarray

    def __len__(self) -> int:
        return len(self.stamps_s)


@dataclass
class GroundTruthMap:
    """Ground-truth occupancy grid: cells[iy, ix] int8 with 100 occupied, 0 free, -1 unknown."""

    stamp_s: float
    cells: np.ndarray
    spec: GridSpec


@dataclass
class Extrinsics:
    """Sensor mounting on the rig: ``T_base_radar`` and ``T_base_camera``, (4, 4) each."""

    T_base_radar: np.ndarray = field(default_factory=lambda: np.eye(4))
    T_base_camera: np.ndarray = field(default_factory=lambda: np.eye(4))


@dataclass
class OdometryHealth:
    """How much an odometry estimate can be trusted.

    inliers: correspondences (scan matching) or points (Doppler) that agreed with the estimate.
    fitness: RMS residual of those inliers, metres (NaN when there were none).
    lost: the source could not measure this frame; the pose only follows its motion model.
    extra: source-specific statistics (e.g. ``doppler_inliers``), plain floats.
    """

    inliers: int
    fitness: float
    lost: bool
    extra: dict[str, float] = field(default_factory=dict)


@dataclass
class Odometry:
    """One frame of an odometry source, ready to become a between-factor.

    pose_world_sensor: (3,) [x_m, y_m, yaw_rad] of the sensor in the odometry's world frame.
    delta: (3,) [x_m, y_m, yaw_rad] relative pose since the previous keyframe, expressed in
    that keyframe's sensor frame (``se2_between(previous, current)``).
    covariance: (3, 3) covariance of ``delta`` in the same [x, y, yaw] order (m^2, rad^2).
    keyframe: True when this frame starts a new ``delta``; the next one is relative to it.
    """

    stamp_s: float
    pose_world_sensor: np.ndarray
    delta: np.ndarray
    covariance: np.ndarray
    health: OdometryHealth
    keyframe: bool = True


@dataclass(frozen=True)
class StepPairs:
    """The radar and the camera step of the same keyframe pairs, for evaluation against the
    truth: ``stamps_s`` (M, 2) start and end of each pair; ``radar`` and ``camera`` (M, 3)
    base_link poses of the end in the start, metres and radians (the camera's made metric,
    before the consistency check)."""

    stamps_s: np.ndarray
    radar: np.ndarray
    camera: np.ndarray


Frame = RadarScan | CameraFrame | ImuSample
"""What a log reader's ``frames()`` yields: sensor frames only. Ground truth is read apart
(``ground_truth_trajectory()``, ``ground_truth_map()``), by evaluation."""
