"""Config of the radar-map up-sampler: how maps are up-sampled, and how the model is trained."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from smokyslam.config.base import Section as _Section


class UpsamplerModelConfig(_Section):
    """The generator's shape (a U-Net, ``upsample/model.py``); stored in every weights file."""

    base_channels: int = Field(12, ge=4, le=64, description="channels at full resolution")
    depth: int = Field(4, ge=1, le=6, description="halvings of resolution (stride 2**depth)")
    max_channels: int = Field(128, ge=4, le=512, description="channels at most, any depth")


class UpsamplerTrainingConfig(_Section):
    """``smokyslam train-upsampler``: pairs from procedural worlds, then pix2pix training."""

    worlds: int = Field(60, ge=1, description="training worlds (seeds 0..worlds-1)")
    validation_worlds: int = Field(6, ge=1, description="validation worlds (seeds from 5000)")
    walk_s: tuple[float, float] = (40.0, 90.0)
    radar_loss: tuple[float, float] = (0.0, 0.3)
    epochs: int = Field(30, ge=1)
    steps_per_epoch: int = Field(200, ge=1)
    batch: int = Field(8, ge=1)
    crop_cells: int = Field(96, ge=32, description="training crops, cells per side")
    learning_rate: float = Field(3e-4, gt=0.0, description="Adam; decays linearly to a tenth")
    decay_from_epoch: int = Field(15, ge=0, description="epochs at the full learning rate")
    bce_weight: float = Field(100.0, ge=0.0, description="cross-entropy of the dense value")
    l1_weight: float = Field(100.0, ge=0.0, description="pix2pix's L1 (its lambda)")
    occupied_weight: float = Field(3.0, ge=1.0, description="weight of true wall cells")
    unknown_weight: float = Field(0.1, ge=0.0, description="weight of cells never observed")
    line_weight: float = Field(100.0, ge=0.0, description="milliMap's line-detector prior")
    adversarial_weight: float = Field(1.0, ge=0.0)
    ema_decay: float = Field(
        0.995, ge=0.0, lt=1.0, description="moving average of the generator's weights, per step"
    )
    threads: int = Field(2, ge=1, description="torch CPU threads (fixed, for determinism)")
    jobs: int = Field(2, ge=1, description="processes simulating training worlds")
    model: UpsamplerModelConfig = UpsamplerModelConfig()

    @model_validator(mode="after")
    def _ordered_ranges(self) -> UpsamplerTrainingConfig:
        for name in ("walk_s", "radar_loss"):
            lo, hi = getattr(self, name)
            if not 0.0 <= lo <= hi:
                raise ValueError(f"{name} must be 0 <= low <= high, got {lo}, {hi}")
        return self


class UpsampleConfig(_Section):
    """Up-sampling the stitched radar map (``smokyslam upsample``, ``map --upsample``, run)."""

    method: Literal["gan", "classical", "none"] = "gan"
    weights: str | None = Field(None, description="weights file; None = the shipped weights")
    margin_cells: int = Field(
        48, ge=0, description="unknown border added around a map before the network's pass"
    )
    extend_cells: int | None = Field(
        48,
        ge=0,
        description="the dense map's grid: the sparse map's known cells and this many cells"
        " around them (the network's values just beyond what the radar saw), wherever the"
        " sparse grid's window happens to end; null: the sparse map's own grid",
    )
    max_pass_cells: int = Field(
        1536, ge=128, description="maps larger than this per side go in overlapping tiles"
    )
    keep_walls_above: float = Field(
        0.4,
        ge=0.0,
        le=1.0,
        description="gan: cells the radar map holds occupied stay occupied unless the"
        " network's probability is below this (1: the network alone)",
    )
    half_turn: bool = Field(
        True,
        description="gan: average the network's pass over the map with its pass over the map"
        " turned by 180 degrees (test-time augmentation)",
    )
    refresh_period_s: float = Field(
        5.0, gt=0.0, description="log seconds between background refreshes during a run"
    )
    worker_process: bool = Field(
        True,
        description="up-sample in a worker process during a run (off: on a thread of the run's"
        " own process)",
    )
    # The classical baseline's radii: the best error index on training worlds (seeds < 30)
    # over walls 1-3 cells and gaps up to 1.5 m.
    closing_radius_cells: int = Field(1, ge=1, description="classical: wall closing radius")
    free_fill_radius_cells: int = Field(15, ge=1, description="classical: free gap fill radius")
    training: UpsamplerTrainingConfig = UpsamplerTrainingConfig()
