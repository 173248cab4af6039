"""Config of map fusion: registration by a homography, the trust index, the fusion rule."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from smokyslam.config.base import Section as _Section


class RegistrationConfig(_Section):
    """``smokyslam register``: log-polar phase correlation, then ECC refinement (``fusion/``)."""

    min_scale: float = Field(0.65, gt=0.0, description="smallest source-to-destination scale")
    max_scale: float = Field(1.5, gt=0.0, description="largest source-to-destination scale")
    max_resolution_ratio: float = Field(
        4.0, ge=1.0, description="map files whose resolutions differ more are refused"
    )
    init_blur_sigma_cells: float = Field(
        1.0, gt=0.0, description="Gaussian blur of the wall images for phase correlation"
    )
    polar_angle_bins: int = Field(720, ge=90, description="log-polar spectrum: angle samples")
    polar_radius_bins: int = Field(256, ge=32, description="log-polar spectrum: radius samples")
    rotation_peaks: int = Field(3, ge=1, description="scale-rotation peaks tried (each 4 ways)")
    translation_peaks: int = Field(3, ge=1, description="shift peaks tried per scale-rotation")
    refine_candidates: int = Field(3, ge=1, description="best initial guesses refined by ECC")
    blur_sigma_cells: float = Field(
        1.5, gt=0.0, description="Gaussian blur of the occupancy images for ECC, finest level"
    )
    pyramid_levels: int = Field(3, ge=1, le=6, description="ECC coarse-to-fine levels (halvings)")
    ecc_iterations: int = Field(60, ge=1, description="ECC iterations at most, per level")
    ecc_eps: float = Field(1e-5, gt=0.0, description="ECC stops when rho changes less")
    # At 0.3, of 17 confident placements of camera-only maps onto radar maps (48 runs, 16
    # unseen worlds), 5 disagreed with the camera run's own aligned map (under 55 % of the
    # placed walls within 0.3 m of its walls), 4 of them at overlaps of 0.29-0.38; at 0.5,
    # 1 of 13 (overlap 0.53), and no agreeing placement was lost.
    full_overlap: float = Field(
        0.5, gt=0.0, le=1.0, description="overlap (of the source's known cells) trusted fully"
    )
    confidence_threshold: float = Field(
        0.45, ge=0.0, le=1.0, description="a registration below this confidence is not applied"
    )

    @model_validator(mode="after")
    def _ordered_scales(self) -> RegistrationConfig:
        if not self.min_scale < 1.0 < self.max_scale:
            raise ValueError(
                f"need min_scale < 1 < max_scale, got {self.min_scale}, {self.max_scale}"
            )
        return self


class TrustConfig(_Section):
    """The trust index t from measured smoke (formula in ``fusion/trust.py``)."""

    # Calibrated on six training worlds (office, warehouse, corridor 9001-9006, 120 s,
    # `paper-table`'s maps, one t for every cell): at t = 0.5 (the paper's), 0.6, 0.7 and 0.8
    # the fused map scored a higher error index than the up-sampled radar map alone in all 14
    # fused rows, 1.01-2.04x; from 0.81 up, where a linear fusion of trinary maps keeps
    # the radar's value wherever the radar knows a cell and drops cells only the camera knows
    # (their trust 1 - t is below keep_trust), 1.00x. The camera's visual map, as built here,
    # held nothing the radar map lacked (docs/accuracy.md).
    t_clear: float = Field(
        0.85, ge=0.0, le=1.0, description="t when the camera is clear (rises to 1 when blind)"
    )
    noise_blind: float = Field(
        0.5, gt=0.0, le=1.0, description="salt-and-pepper fraction at which the camera is blind"
    )
    contrast_clear: float = Field(
        0.17, gt=0.0, description="RMS contrast (/255) of a clear simulated frame"
    )
    per_region: bool = Field(
        True, description="t per cell from the keyframes that saw it (else one t per run)"
    )
    agreement_clear: float = Field(
        0.6,
        ge=0.0,
        le=1.0,
        description="correlation of a sound visual map with the radar map where both know "
        "cells; below it the camera's trust falls in proportion (0: not used)",
    )


class FusionConfig(_Section):
    """Fusing the up-sampled radar map with the visual map (``fusion/``)."""

    rule: Literal["linear", "log-odds"] = Field(
        "linear", description="linear: the paper's eq. 3; log-odds: trust-weighted Bayes"
    )
    trust: float | Literal["auto"] = Field(
        "auto", description="auto: from measured smoke; a number in [0, 1] forces t"
    )
    keep_trust: float = Field(
        0.3,
        ge=0.0,
        le=1.0,
        description="a cell one map alone knows keeps its value when that map's trust reaches this",
    )
    log_odds_clip: float = Field(
        0.05, gt=0.0, lt=0.5, description="log-odds rule: probabilities clipped to [c, 1 - c]"
    )
    radar_map: Literal["radar_dense", "radar_sparse"] = Field(
        "radar_dense", description="the radar map fused (the sparse one when up-sampling is off)"
    )
    refresh_period_s: float = Field(
        5.0, gt=0.0, description="log seconds between online refreshes of the fused map"
    )
    trust_model: TrustConfig = TrustConfig()
    registration: RegistrationConfig = RegistrationConfig()

    @model_validator(mode="after")
    def _trust_in_range(self) -> FusionConfig:
        if self.trust != "auto" and not 0.0 <= self.trust <= 1.0:
            raise ValueError(f"trust must be 'auto' or in [0, 1], got {self.trust}")
        return self
