"""Config sections of the sensors and their logs: topics, smoke, rig, simulation, CARMEN."""

from __future__ import annotations

import math

from pydantic import Field

from smokyslam.config.base import Section as _Section


class TopicsConfig(_Section):
    """Log topics. Each stream lists candidate topics; the first one present in a log is used."""

    radar: list[str] = Field(default_factory=lambda: ["/ti_mmwave/radar_scan_pcl"])
    camera_image: list[str] = Field(default_factory=lambda: ["/camera/image_raw"])
    camera_info: list[str] = Field(default_factory=lambda: ["/camera/camera_info"])
    camera_depth: list[str] = Field(default_factory=lambda: ["/camera/depth/image_raw"])
    imu: list[str] = Field(default_factory=lambda: ["/imu", "/sensor_platform/imu"])
    ground_truth_pose: list[str] = Field(default_factory=lambda: ["/ground_truth/pose"])
    ground_truth_map: list[str] = Field(default_factory=lambda: ["/ground_truth/map"])
    ground_truth_map_observed: list[str] = Field(
        default_factory=lambda: ["/ground_truth/map_observed"]
    )
    tf_static: list[str] = Field(default_factory=lambda: ["/tf_static"])


class LogConfig(_Section):
    """How logs are read."""

    max_gap_s: float = Field(
        1.0, gt=0.0, description="a stream's log time jumping more than this is reported"
    )


class SmokeConfig(_Section):
    """Smoke emulated at replay time (seeded, so one log serves every level)."""

    radar_loss: float = Field(0.0, ge=0.0, le=1.0, description="fraction of radar returns dropped")
    camera_noise: float = Field(0.0, ge=0.0, le=1.0, description="salt-and-pepper pixel fraction")
    haze: float = Field(0.0, ge=0.0, description="haze density B, 1/m")
    airlight: float = Field(200.0, ge=0.0, le=255.0, description="haze airlight A, grey level")
    default_depth_m: float = Field(3.0, gt=0.0, description="depth d for logs without depth")
    seed: int = 0


class RigConfig(_Section):
    """Sensor mounting on base_link (x forward, y left, z up), metres and radians."""

    radar_xy_m: tuple[float, float] = (0.10, 0.0)
    radar_yaw_rad: float = 0.0
    radar_height_m: float = 1.0
    camera_xy_m: tuple[float, float] = (0.05, 0.0)
    camera_yaw_rad: float = 0.0
    camera_height_m: float = 1.2
    calibration: str | None = Field(
        None,
        description="radar calibration YAML (l_b_r_*, q_b_r_*: radar on the IMU body); "
        "replaces the log's /tf_static mounting",
    )


class RadarModelConfig(_Section):
    """Simulated TI IWR1443 radar."""

    rate_hz: float = 10.0
    fov_deg: float = Field(60.0, gt=0.0, le=180.0, description="half field of view in azimuth")
    min_range_m: float = 0.3
    max_range_m: float = 10.0
    beams: int = Field(241, ge=8, description="azimuth rays cast per frame before detection")
    range_sigma_m: float = 0.03
    azimuth_sigma_deg: float = 3.0
    doppler_sigma_mps: float = 0.05
    detection_max_prob: float = 0.9
    detection_range_scale_m: float = 12.0
    min_points: int = 10
    max_points: int = 80
    ghost_fraction: float = 0.04
    clutter_fraction: float = 0.03
    mean_points: float = Field(40.0, gt=0.0, description="mean points per frame (Poisson)")
    incidence_exponent: float = Field(2.0, ge=0.0, description="detection falls as cos(inc)^k")
    clutter_doppler_sigma_mps: float = 0.5


class CameraModelConfig(_Section):
    """Simulated mono camera."""

    rate_hz: float = 15.0
    width: int = 320
    height: int = 240
    fx: float = 220.0
    fy: float = 220.0
    pixel_noise_sigma: float = 2.0
    supersample: int = Field(
        1, ge=1, le=4, description="samples per pixel along each axis (anti-aliasing)"
    )
    depth_scale: int = Field(2, ge=1, description="depth is logged at 1/depth_scale resolution")


class ImuModelConfig(_Section):
    """Simulated IMU: gyro z and accel x/y with bias and white noise."""

    rate_hz: float = 100.0
    gyro_noise_radps: float = 0.002
    gyro_bias_radps: float = 0.003
    accel_noise_mps2: float = 0.05
    accel_bias_mps2: float = 0.05


class TrajectoryConfig(_Section):
    """Walking path through the building."""

    min_speed_mps: float = 0.3
    max_speed_mps: float = 1.0
    max_turn_rate_radps: float = math.radians(45.0)
    clearance_m: float = 0.3
    ground_truth_rate_hz: float = 50.0


class LidarConfig(_Section):
    """The ideal 2D lidar whose walk makes the observed ground truth (``sim/observed.py``)."""

    beams: int = Field(1440, ge=8, description="beams over 360 degrees (0.25 degree steps)")
    max_range_m: float = Field(20.0, gt=0.0)
    spacing_m: float = Field(0.5, gt=0.0, description="a scan each time the walk moved this far")
    turn_rad: float = Field(0.4, gt=0.0, description="or turned this far")


class SimulationConfig(_Section):
    """Everything ``smokyslam simulate`` needs beyond the command-line arguments."""

    wall_height_m: float = 2.5
    resolution_m: float = 0.1
    trajectory: TrajectoryConfig = TrajectoryConfig()
    radar: RadarModelConfig = RadarModelConfig()
    camera: CameraModelConfig = CameraModelConfig()
    imu: ImuModelConfig = ImuModelConfig()
    lidar: LidarConfig = LidarConfig()


class CarmenConfig(_Section):
    """CARMEN laser logs replayed as a radar rig (seeded, so dead reckoning is a stable baseline).

    Geometry noise (range, azimuth), field of view and range limits come from
    ``simulation.radar``; the Doppler ego-velocity and gyro are built from the logged poses.
    """

    emulate_radar: bool = Field(True, description="False: every valid beam, noise-free")
    nominal_rate_hz: float = Field(1.0, gt=0.0, description="scan i is stamped i / rate")
    points_per_scan: int = Field(40, ge=3, description="valid beams kept per scan (random)")
    dropout: float = Field(0.1, ge=0.0, lt=1.0, description="fraction of kept points dropped")
    doppler_scale_error: float = Field(0.03, description="relative scale error of the velocity")
    velocity_noise_rel: float = Field(0.05, ge=0.0, description="step noise sigma / step length")
    velocity_noise_abs_m: float = Field(0.02, ge=0.0, description="step noise sigma floor, m")
    doppler_point_sigma_mps: float = Field(0.02, ge=0.0, description="per-point Doppler noise")
    gyro_noise_deg: float = Field(1.0, ge=0.0, description="yaw noise sigma per scan, degrees")
    gyro_bias_deg: float = Field(0.05, description="yaw bias per scan, degrees")
    seed: int = 0
    max_jump_m: float = Field(
        5.0, gt=0.0, description="a line whose pose jumps this far and back is dropped"
    )
    map_radius_m: float = Field(
        30.0,
        gt=0.0,
        description="radar odometry local-map radius on these logs (replaces "
        "radar_odometry.map_radius_m): few scans see each place, so the map is kept for "
        "revisits to re-anchor to",
    )
    gyro_bias_sigma_degps: float = Field(
        0.0,
        ge=0.0,
        description="radar odometry gyro-bias estimate on these logs (replaces "
        "radar_odometry.gyro_bias_sigma_degps; 0: off): too few scans to tell the bias from "
        "map error, and scan matching absorbs it",
    )
