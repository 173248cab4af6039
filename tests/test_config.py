"""Config: defaults mirrored in configs/, unknown keys rejected, overrides applied."""

from pathlib import Path

import pytest
import yaml

from smokyslam.config import SmokySlamConfig, config_to_yaml, load_config, write_config
from smokyslam.errors import ConfigError

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def test_default_yaml_mirrors_the_models():
    on_disk = yaml.safe_load((CONFIGS / "default.yaml").read_text())
    assert on_disk == SmokySlamConfig().model_dump(mode="json")


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_every_shipped_config_loads(path):
    assert isinstance(load_config(path), SmokySlamConfig)


def test_unknown_key_is_named(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("smoke:\n  radar_los: 0.1\n")
    with pytest.raises(ConfigError, match=r"unknown config key 'smoke\.radar_los'"):
        load_config(bad)


def test_invalid_value_is_named(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("smoke:\n  radar_loss: 1.5\n")
    with pytest.raises(ConfigError, match=r"smoke\.radar_loss"):
        load_config(bad)


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "nope.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("smoke: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(broken)


def test_overrides_beat_file_and_round_trip(tmp_path):
    base = tmp_path / "c.yaml"
    base.write_text("smoke:\n  radar_loss: 0.1\n  haze: 0.3\n")
    config = load_config(base, {"smoke": {"radar_loss": 0.2}})
    assert config.smoke.radar_loss == 0.2
    assert config.smoke.haze == 0.3
    written = write_config(config, tmp_path / "out" / "config.yaml")
    assert load_config(written) == config
    assert "radar_loss: 0.2" in config_to_yaml(config)
