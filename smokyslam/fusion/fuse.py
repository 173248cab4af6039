"""Fusing a radar map and a visual map of one grid by the trust index t (the paper's eq. 3).

Both maps come as values on the error index's scale (1 occupied, 0 free, 0.5 unknown) with a
mask of the cells each one knows; ``t`` is the radar's trust, a scalar or one per cell
(``fusion/trust.py``), and ``1 - t`` the camera's.

- ``linear`` (the paper): where both maps know a cell, ``t * radar + (1 - t) * visual``; where
  one map alone knows it, its value is kept when that map's trust reaches ``keep_trust`` (the
  paper's rule), else the cell stays unknown.
- ``log-odds`` (Bayesian): each map's evidence ``logit(p)`` (p clipped to ``[clip, 1 - clip]``)
  weighted by ``2 t`` and ``2 (1 - t)`` and summed; at t = 0.5 that is the plain Bayesian sum
  of two independent observations, and a map trusted less speaks with less weight.

The fused values are made trinary with map_server's thresholds, like every saved map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from smokyslam.errors import FusionError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN, trinary_from_probability

RULES = ("linear", "log-odds")

FUSED_MAP = "fused"
"""The fused map's name in every output folder (``maps/fused.*``)."""


@dataclass
class MapValues:
    """A map on the error index's scale: ``values`` (rows, cols) in [0, 1] (0.5 unknown) and
    ``known`` (rows, cols) bool, over ``spec``."""

    values: np.ndarray
    known: np.ndarray
    spec: GridSpec

    @classmethod
    def from_cells(cls, cells: np.ndarray, spec: GridSpec) -> MapValues:
        """Of trinary cells (100 / 0 / -1), as saved maps hold them."""
        cells = np.asarray(cells)
        values = np.select([cells == OCCUPIED, cells == FREE], [1.0, 0.0], 0.5)
        return cls(values.astype(np.float32), cells != UNKNOWN, spec)


@dataclass
class FusedMap:
    """A fused map: ``values`` (rows, cols) float32 in [0, 1] over ``spec``, the ``rule`` that
    made it, and the trust it used (the mean over the cells both maps know)."""

    values: np.ndarray
    spec: GridSpec
    rule: str
    trust_mean: float
    agreement: float | None = None
    """The visual map's agreement with the radar map, where measured (``fusion/trust.py``)."""

    def to_cells(self) -> np.ndarray:
        """Trinary cells (map_server thresholds), as saved."""
        return trinary_from_probability(self.values.astype(float))

    def summary(self) -> dict[str, float | str]:
        """``fusion`` in metrics.json."""
        summary: dict[str, float | str] = {"rule": self.rule, "trust_mean": self.trust_mean}
        if self.agreement is not None:
            summary["agreement"] = self.agreement
        return summary


def fuse_maps(
    radar: MapValues,
    visual: MapValues,
    trust: float | np.ndarray,
    rule: str,
    keep_trust: float,
    clip: float,
) -> FusedMap:
    """The fusion of two maps on the same grid (``radar.spec``) by ``rule``."""
    if radar.values.shape != visual.values.shape:
        raise FusionError(
            f"maps to fuse must share a grid: {radar.values.shape} vs {visual.values.shape}"
        )
    t = np.broadcast_to(np.asarray(trust, dtype=np.float64), radar.values.shape)
    if not np.isfinite(t).all() or t.min() < 0.0 or t.max() > 1.0:
        raise FusionError("the trust index must lie in [0, 1]")
    r, v = radar.values.astype(np.float64), visual.values.astype(np.float64)
    both = radar.known & visual.known
    if rule == "linear":
        fused = np.full(r.shape, 0.5)
        fused[both] = t[both] * r[both] + (1.0 - t[both]) * v[both]
        radar_only = radar.known & ~visual.known & (t >= keep_trust)
        visual_only = visual.known & ~radar.known & (1.0 - t >= keep_trust)
        fused[radar_only] = r[radar_only]
        fused[visual_only] = v[visual_only]
    elif rule == "log-odds":
        evidence = np.where(radar.known, 2.0 * t * _logit(r, clip), 0.0)
        evidence += np.where(visual.known, 2.0 * (1.0 - t) * _logit(v, clip), 0.0)
        fused = 1.0 / (1.0 + np.exp(-evidence))
    else:
        raise FusionError(f"unknown fusion rule '{rule}' (choose {', '.join(RULES)})")
    trust_mean = float(t[both].mean()) if both.any() else float(t.mean())
    return FusedMap(fused.astype(np.float32), radar.spec, rule, trust_mean)


def _logit(p: np.ndarray, clip: float) -> np.ndarray:
    p = np.clip(p, clip, 1.0 - clip)
    return np.log(p / (1.0 - p))
