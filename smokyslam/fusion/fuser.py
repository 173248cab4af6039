"""The fusion stage: a radar map and a visual map of one world frame, fused on their union.

:class:`MapFuser` takes the two maps as trinary cells on their own grids (same resolution,
cells aligned with the world origin, as every smokyslam grid is), draws both on the grid that
covers them both, and fuses them (``fusion/fuse.py``) with the trust index: the one the config
forces, or the measured one (``fusion/trust.py``), a grid over the visual map's cells or one
value.
"""

from __future__ import annotations

import numpy as np

from smokyslam.config.fusion import FusionConfig
from smokyslam.errors import FusionError
from smokyslam.fusion.fuse import FusedMap, MapValues, fuse_maps
from smokyslam.fusion.registration import agreement
from smokyslam.fusion.trust import TrustModel
from smokyslam.geometry import GridSpec
from smokyslam.mapio import UNKNOWN
from smokyslam.mapping.grid import resample_nearest


def union_spec(a: GridSpec, b: GridSpec) -> GridSpec:
    """The grid covering both ``a`` and ``b`` (same resolution), cells aligned with ``a``'s."""
    if not np.isclose(a.resolution_m, b.resolution_m, rtol=1e-6):
        raise FusionError(
            f"maps of different resolution ({a.resolution_m} m, {b.resolution_m} m) share no "
            "grid: register the visual map onto the radar map first"
        )
    return a.covering(b)


class MapFuser:
    """Fuses (radar, visual) map pairs; verb :meth:`fuse`."""

    def __init__(self, config: FusionConfig) -> None:
        self.trust = get_trust_model(config)
        self.per_region = config.trust_model.per_region
        self.radar_map = config.radar_map
        self.rule = config.rule
        self.forced_trust = None if config.trust == "auto" else float(config.trust)
        self.keep_trust = config.keep_trust
        self.clip = config.log_odds_clip
        self.registration = config.registration

    def fuse(
        self,
        radar_cells: np.ndarray,
        radar_spec: GridSpec,
        visual_cells: np.ndarray,
        visual_spec: GridSpec,
        trust: float | np.ndarray | None,
        default_trust: float | None = None,
    ) -> FusedMap:
        """The fused map on the union of the two grids.

        trust: the measured trust index, one value or (rows, cols) over ``visual_spec``
        (``default_trust`` beyond it); ignored when the config forces a value. FusionError
        when neither gives one.
        """
        spec = union_spec(radar_spec, visual_spec)
        radar_on = resample_nearest(radar_cells, radar_spec, spec, UNKNOWN)
        visual_on = resample_nearest(visual_cells, visual_spec, spec, UNKNOWN)
        t = self._trust(trust, default_trust, visual_spec, spec)
        rho = None
        if self.forced_trust is None:  # a measured t: the camera's map must agree, too
            rho = agreement(radar_on, visual_on, self.registration)
            t = 1.0 - (1.0 - np.asarray(t, dtype=float)) * self.trust.agreement_factor(rho)
        fused = fuse_maps(
            MapValues.from_cells(radar_on, spec),
            MapValues.from_cells(visual_on, spec),
            t,
            self.rule,
            self.keep_trust,
            self.clip,
        )
        fused.agreement = rho
        return fused

    def _trust(self, trust, default_trust, visual_spec: GridSpec, spec: GridSpec):
        if self.forced_trust is not None:
            return self.forced_trust
        if trust is None:
            raise FusionError("no measured trust index for the visual map: give --trust T")
        if np.ndim(trust) == 0:
            return float(trust)
        fill = float(np.mean(trust)) if default_trust is None else float(default_trust)
        return resample_nearest(np.asarray(trust, dtype=float), visual_spec, spec, fill)


def get_trust_model(config: FusionConfig) -> TrustModel:
    """The trust formula's constants from the config."""
    trust = config.trust_model
    return TrustModel(trust.t_clear, trust.noise_blind, trust.contrast_clear, trust.agreement_clear)
