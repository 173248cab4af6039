"""Configuration: one small pydantic model per stage, one root ``SmokySlamConfig``.

Defaults live here (the sections in ``sensors.py`` and ``estimation.py``), nowhere else, and
are mirrored in ``configs/default.yaml`` (a test keeps them equal). Components take their
section, or plain arguments without defaults of their own. Unknown keys are errors, so a typo
in a YAML file is reported rather than ignored.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from smokyslam.config.base import Section
from smokyslam.config.estimation import (
    BackendConfig,
    CameraFactorKind,
    CameraGateConfig,
    CameraOdometryConfig,
    KeyframeConfig,
    LoopClosureConfig,
    MappingConfig,
    RadarOdometryConfig,
    ScaleConfig,
    SlamConfig,
)
from smokyslam.config.fusion import FusionConfig, RegistrationConfig, TrustConfig
from smokyslam.config.localize import LocalizeConfig
from smokyslam.config.recording import RecordingConfig
from smokyslam.config.sensors import (
    CameraModelConfig,
    CarmenConfig,
    ImuModelConfig,
    LidarConfig,
    LogConfig,
    RadarModelConfig,
    RigConfig,
    SimulationConfig,
    SmokeConfig,
    TopicsConfig,
    TrajectoryConfig,
)
from smokyslam.config.upsample import (
    UpsampleConfig,
    UpsamplerModelConfig,
    UpsamplerTrainingConfig,
)
from smokyslam.errors import ConfigError

__all__ = [
    "BackendConfig",
    "CameraFactorKind",
    "CameraGateConfig",
    "CameraModelConfig",
    "CameraOdometryConfig",
    "CarmenConfig",
    "FusionConfig",
    "ImuModelConfig",
    "KeyframeConfig",
    "LidarConfig",
    "LocalizeConfig",
    "LogConfig",
    "LoopClosureConfig",
    "MappingConfig",
    "RadarModelConfig",
    "RadarOdometryConfig",
    "RecordingConfig",
    "RegistrationConfig",
    "RigConfig",
    "ScaleConfig",
    "SimulationConfig",
    "SlamConfig",
    "SmokeConfig",
    "SmokySlamConfig",
    "TopicsConfig",
    "TrajectoryConfig",
    "TrustConfig",
    "UpsampleConfig",
    "UpsamplerModelConfig",
    "UpsamplerTrainingConfig",
    "config_to_yaml",
    "deep_update",
    "load_config",
    "write_config",
]


class SmokySlamConfig(Section):
    """Root configuration."""

    topics: TopicsConfig = TopicsConfig()
    log: LogConfig = LogConfig()
    smoke: SmokeConfig = SmokeConfig()
    rig: RigConfig = RigConfig()
    simulation: SimulationConfig = SimulationConfig()
    carmen: CarmenConfig = CarmenConfig()
    radar_odometry: RadarOdometryConfig = RadarOdometryConfig()
    keyframes: KeyframeConfig = KeyframeConfig()
    mapping: MappingConfig = MappingConfig()
    camera_odometry: CameraOdometryConfig = CameraOdometryConfig()
    backend: BackendConfig = BackendConfig()
    slam: SlamConfig = SlamConfig()
    upsample: UpsampleConfig = UpsampleConfig()
    fusion: FusionConfig = FusionConfig()
    recording: RecordingConfig = RecordingConfig()
    localize: LocalizeConfig = LocalizeConfig()


def deep_update(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``base`` with ``override`` merged in; nested mappings merge key by key."""
    merged = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = deep_update(merged[key], value)
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
            loaded = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
        except UnicodeDecodeError:
            raise ConfigError(f"{path}: not a text (UTF-8) YAML file") from None
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read it ({exc.strerror or exc})") from None
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML ({exc.__class__.__name__})") from None
        if not isinstance(loaded, dict):
            raise ConfigError(f"{path}: top level must be a mapping of sections")
        data = loaded
    if overrides:
        data = deep_update(data, overrides)
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
