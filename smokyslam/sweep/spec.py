"""The sweep file: which worlds, smoke levels, sources and configs to cross (``smokyslam sweep``).

```yaml
worlds:
  - {kind: office, seeds: [10001, 10002], duration_s: 120}
  - {plan: plans/willow.yaml, seeds: [1], duration_s: 120}
  - {log: logs/hall.mcap}
smoke: ["0:0", "0.1:0.2", "0.2:0.4"]
sources: [radar, camera, fused, dead-reckoning]
configs: {default: {}, wide_azimuth: {radar_odometry: {azimuth_sigma_deg: 3.0}}}
```

A world is a procedural ``kind`` (office, warehouse, corridor) or a floor-plan YAML ``plan``,
simulated once per seed (``sensors`` optional, e.g. ``[radar, imu]``), or an existing ``log``.
Paths are relative to the sweep file. ``configs`` are named overrides of the base config
(``-c``); without it, one config ``default``. Everything is checked when the file is loaded:
a bad file is one ConfigError line naming the problem.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from smokyslam.config import SmokySlamConfig, deep_update, load_config
from smokyslam.errors import ConfigError, SmokySlamError
from smokyslam.smoke import SmokeLevel, parse_smoke


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class WorldSpec(_Strict):
    """One world entry: exactly one of ``kind``, ``plan`` or ``log``."""

    kind: str | None = None
    plan: str | None = None
    log: str | None = None
    seeds: list[int] = Field(default_factory=lambda: [1])
    duration_s: float = Field(120.0, gt=0.0)
    sensors: list[str] = Field(default_factory=lambda: ["radar", "camera", "imu"])

    @model_validator(mode="after")
    def _one_source(self) -> WorldSpec:
        given = [name for name in ("kind", "plan", "log") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of kind, plan or log (got {given or 'none'})")
        return self


class SweepFile(_Strict):
    worlds: list[WorldSpec] = Field(min_length=1)
    smoke: list[str] = Field(default_factory=lambda: ["0:0"], min_length=1)
    sources: list[str] = Field(min_length=1)
    configs: dict[str, dict[str, Any]] = Field(default_factory=lambda: {"default": {}})

    @field_validator("configs", mode="before")
    @classmethod
    def _names_are_text(cls, configs: Any) -> Any:
        for name in configs if isinstance(configs, dict) else ():
            if not isinstance(name, str):
                raise ValueError(
                    f"config name {name!r} is not text (YAML reads a bare off, on, yes, no, "
                    "true, false or number as one): quote it"
                )
        return configs


@dataclass(frozen=True)
class World:
    """A world of the sweep as it will be run: ``name`` (folder-safe, unique), ``kind`` (the
    world kind, ``plan-<name>`` or ``log``, for the summary), ``seed`` (None for a given
    log), and either the ``log`` to use as it is or what to simulate (``simulate``: a kind or
    a plan path, for ``duration_s``, with ``sensors``)."""

    name: str
    kind: str
    seed: int | None
    log: Path | None = None
    simulate: str | None = None
    duration_s: float = 0.0
    sensors: tuple[str, ...] = ()

    def log_path(self, out_dir: Path) -> Path:
        """The log its runs read: the given one, or where the sweep simulates it."""
        return self.log if self.log is not None else out_dir / "logs" / f"{self.name}.mcap"


@dataclass(frozen=True)
class Sweep:
    """A loaded sweep, every name checked: ``configs`` maps a name to its effective config."""

    worlds: list[World]
    levels: list[SmokeLevel]
    sources: list[str]
    configs: dict[str, SmokySlamConfig]


def load_sweep(path: Path | str, base: SmokySlamConfig) -> Sweep:
    """The sweep file at ``path`` over the ``base`` config; ConfigError on any problem."""
    from smokyslam.pipelines.compare import parse_sources
    from smokyslam.sim.simulate import parse_sensors
    from smokyslam.sim.worlds import WORLD_NAMES

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep file not found: {path}")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        spec = SweepFile.model_validate(data)
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: not a YAML sweep file ({type(exc).__name__})") from None
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(part) for part in error["loc"]) or "top level"
        raise ConfigError(f"{path}: {where}: {error['msg']}") from None
    root = path.parent
    sources = parse_sources(",".join(spec.sources))
    levels = [parse_smoke(text) for text in spec.smoke]
    worlds: list[World] = []
    for entry in spec.worlds:
        if entry.kind is not None and entry.kind not in WORLD_NAMES:
            raise ConfigError(
                f"{path}: unknown world kind '{entry.kind}' (one of {', '.join(WORLD_NAMES)})"
            )
        try:
            sensors = tuple(sorted(parse_sensors(",".join(entry.sensors))))
        except SmokySlamError as exc:
            raise ConfigError(f"{path}: sensors: {exc}") from None
        if entry.log is not None:
            log = (root / entry.log).resolve()
            if not log.exists():
                raise ConfigError(f"{path}: log not found: {entry.log} ({log})")
            worlds.append(World(_safe(log.stem), "log", None, log=log))
            continue
        target = entry.kind
        if entry.plan is not None:
            plan = (root / entry.plan).resolve()
            if not plan.is_file():
                raise ConfigError(f"{path}: floor plan not found: {entry.plan} ({plan})")
            target = str(plan)
        kind = entry.kind or f"plan-{_safe(Path(entry.plan).stem)}"
        for seed in entry.seeds:
            name = f"{kind}-{seed}-{entry.duration_s:g}s"
            worlds.append(World(name, kind, seed, None, target, entry.duration_s, sensors))
    names = [world.name for world in worlds]
    if len(set(names)) != len(names):
        raise ConfigError(f"{path}: a world is listed twice ({_first_repeat(names)})")
    configs = {}
    base_data = base.model_dump(mode="json")
    for name, override in spec.configs.items():
        if _safe(name) != name:
            raise ConfigError(f"{path}: config name '{name}': use letters, digits, - and _")
        try:
            configs[name] = load_config(overrides=deep_update(base_data, override))
        except ConfigError as exc:
            raise ConfigError(f"{path}: configs.{name}: {exc}") from None
    return Sweep(worlds, levels, sources, configs)


def _safe(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)


def _first_repeat(names: list[str]) -> str:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            return name
        seen.add(name)
    return ""
