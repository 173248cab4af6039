"""Configuration: one small pydantic model per stage, one root ``SmokySlamConfig``.

Defaults live here and are mirrored in ``configs/default.yaml`` (a test keeps them equal).
Unknown keys are errors, so a typo in a YAML file is reported rather than ignored.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from smokyslam.errors import ConfigError


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True)


class TopicsConfig(_Section):
    """Log topics. Each stream lists candidate topics; the first one present in a log is used."""

    radar: list[str] = ["/ti_mmwave/radar_scan_pcl"]
    camera_image: list[str] = ["/camera/image_raw"]
    camera_info: list[str] = ["/camera/camera_info"]
    camera_depth: list[str] = ["/camera/depth/image_raw"]
    imu: list[str] = ["/imu", "/sensor_platform/imu"]
    ground_truth_pose: list[str] = ["/ground_truth/pose"]
    ground_truth_map: list[str] = ["/ground_truth/map"]
    tf_static: list[str] = ["/tf_static"]


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


class CameraModelConfig(_Section):
    """Simulated mono camera."""

    rate_hz: float = 15.0
    width: int = 320
    height: int = 240
    fx: float = 220.0
    fy: float = 220.0
    pixel_noise_sigma: float = 2.0
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


class SimulationConfig(_Section):
    """Everything ``smokyslam simulate`` needs beyond the command-line arguments."""

    wall_height_m: float = 2.5
    resolution_m: float = 0.1
    trajectory: TrajectoryConfig = TrajectoryConfig()
    radar: RadarModelConfig = RadarModelConfig()
    camera: CameraModelConfig = CameraModelConfig()
    imu: ImuModelConfig = ImuModelConfig()


class SmokySlamConfig(_Section):
    """Root configuration."""

    topics: TopicsConfig = TopicsConfig()
    smoke: SmokeConfig = SmokeConfig()
    rig: RigConfig = RigConfig()
    simulation: SimulationConfig = SimulationConfig()


def _deep_update(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = _deep_update(merged[key], value)
        else:
            merged[key] = value
    return merged


def _format_validation_error(error: ValidationError, source: str) -> str:
    first = error.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    if first["type"] == "extra_forbidden":
        return f"{source}: unknown config key '{where}'"
    return f"{source}: invalid value for '{where}': {first['msg']}"


def load_config(
    path: Path | str | None = None, overrides: dict[str, Any] | None = None
) -> SmokySlamConfig:
    """Build the effective config: defaults, then a YAML file, then ``overrides`` (nested dict).

    Raises ConfigError on a missing file, bad YAML, an unknown key or an invalid value.
    """
    data: dict[str, Any] = {}
    source = "defaults"
    if path is not None:
        path = Path(path)
        source = str(path)
        if not path.is_file():
            raise ConfigError(f"config file not found: {path}")
        try:
            loaded = yaml.safe_load(path.read_text()) or {}
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML ({exc.__class__.__name__})") from exc
        if not isinstance(loaded, dict):
            raise ConfigError(f"{path}: top level must be a mapping of sections")
        data = loaded
    if overrides:
        data = _deep_update(data, overrides)
    try:
        return SmokySlamConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation_error(exc, source)) from None


def config_to_yaml(config: SmokySlamConfig) -> str:
    """The config as YAML text (tuples written as lists), suitable for ``load_config``."""
    return yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False)


def write_config(config: SmokySlamConfig, path: Path | str) -> Path:
    """Write the effective config into an output folder (``config.yaml``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(config_to_yaml(config))
    return path


SourceName = Literal["camera", "radar", "dead-reckoning", "fused"]
