"""A TI mmWave ``.cfg`` file (the CLI commands the radar is configured with), and the numbers
the frame parser needs from it: Doppler and range resolution, and the frame period.

Formulas (TI's mmWave SDK user guide; the Demo Visualizer computes the same):

- Doppler resolution (m/s per Doppler bin) = c / (2 f_start (idle + ramp_end) L N_tx), with L
  the chirp loops per frame and N_tx the chirps per loop (one per transmitter);
- range resolution (m per range bin) = c f_s / (2 S N_adc), with the ADC sample rate f_s, the
  chirp slope S and N_adc samples per chirp.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from smokyslam.errors import ConfigError

SPEED_OF_LIGHT_MPS = 299_792_458.0


@dataclass(frozen=True)
class TiRadarConfig:
    """What a ``.cfg`` fixes: ``commands`` (every CLI line, in order, comments left out),
    ``doppler_resolution_mps``, ``range_resolution_m`` and ``frame_period_s``."""

    commands: tuple[str, ...]
    doppler_resolution_mps: float
    range_resolution_m: float
    frame_period_s: float


def _numbers(line: str, name: str, count: int, path: Path) -> list[float]:
    fields = line.split()[1:]
    try:
        values = [float(f) for f in fields]
    except ValueError:
        raise ConfigError(f"{path}: {name} has a field that is not a number: '{line}'") from None
    if len(values) < count:
        raise ConfigError(f"{path}: {name} needs {count} fields, got {len(values)}: '{line}'")
    return values


def parse_ti_config(text: str, path: Path | str = "<cfg>") -> TiRadarConfig:
    """The commands and resolutions of a ``.cfg`` text; ConfigError naming what is missing."""
    path = Path(path)
    commands = []
    for raw in text.splitlines():
        line = raw.split("%", 1)[0].strip()
        if line:
            commands.append(line)
    found = {line.split()[0]: line for line in commands}
    for name in ("profileCfg", "frameCfg", "channelCfg"):
        if name not in found:
            raise ConfigError(f"{path}: no {name} line (is this a TI mmWave .cfg?)")
    profile = _numbers(found["profileCfg"], "profileCfg", 11, path)
    frame = _numbers(found["frameCfg"], "frameCfg", 5, path)
    channel = _numbers(found["channelCfg"], "channelCfg", 2, path)
    start_ghz, idle_us, ramp_end_us = profile[1], profile[2], profile[4]
    slope_mhz_per_us, adc_samples, sample_rate_ksps = profile[7], profile[9], profile[10]
    chirps_per_loop = int(frame[1]) - int(frame[0]) + 1
    loops, period_ms = int(frame[2]), frame[4]
    transmitters = bin(int(channel[1])).count("1")
    if min(start_ghz, idle_us + ramp_end_us, slope_mhz_per_us, adc_samples, loops) <= 0:
        raise ConfigError(f"{path}: profileCfg/frameCfg give a zero or negative resolution")
    if chirps_per_loop < 1 or transmitters < 1 or period_ms <= 0:
        raise ConfigError(f"{path}: frameCfg/channelCfg give no chirps, transmitter or period")
    chirp_s = (idle_us + ramp_end_us) * 1e-6
    doppler = SPEED_OF_LIGHT_MPS / (2.0 * start_ghz * 1e9 * chirp_s * loops * chirps_per_loop)
    range_m = (SPEED_OF_LIGHT_MPS * sample_rate_ksps * 1e3) / (
        2.0 * slope_mhz_per_us * 1e12 * adc_samples
    )
    return TiRadarConfig(tuple(commands), doppler, range_m, period_ms * 1e-3)


def load_ti_config(path: Path | str) -> TiRadarConfig:
    """:func:`parse_ti_config` of the file at ``path``."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"radar config not found: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read it as text ({type(exc).__name__})") from None
    return parse_ti_config(text, path)
