"""The trust index t from measured smoke: how far the radar map is believed over the visual.

The camera measures its own smoke on every frame (``frontends/camera/preprocess.py``): the
salt-and-pepper fraction ``p`` of the image, its RMS contrast ``c`` (haze scales it by the
transmission) and whether tracking held. Its trust in a frame is

    camera = clip(1 - p / noise_blind, 0, 1) * clip(c / contrast_clear, 0, 1) * tracked

(``noise_blind``: the impulse fraction at which the camera is taken as blind;
``contrast_clear``: the contrast of a clear frame; ``tracked`` 1 while tracking, 0 while lost
or initialising), and the radar's trust index, rising with smoke from ``t_clear`` to 1:

    t = 1 - (1 - t_clear) * camera

The trust of a run is the mean over its camera keyframes. Per region, each keyframe's t is
spread over the cells its landmarks fell in, and a cell takes the mean of the keyframes that saw
it (the run's t where none did), so a room seen in clear air and one seen in smoke are fused
each by its own conditions.

Clear images do not make a sound map: where the camera's depths are off, its walls land
metres from the radar's. So the fusion also measures how well the visual map agrees with the
radar map where both know cells, as the correlation ``rho`` of their smoothed occupancy (the
measure registration scores by, ``fusion/registration.py``), and the camera's trust falls in
proportion below ``agreement_clear``:

    t' = 1 - (1 - t) * clip(rho / agreement_clear, 0, 1)

(measured: ``rho`` 0.54-0.83 between the visual and radar maps of ten office runs in clear
air; 0.34 in a flat where the camera's steps were 42 % off in length, and its walls 0.3-1 m
out). A forced t is used as given.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.errors import FusionError
from smokyslam.geometry import GridSpec

TRUST_SUFFIX = ".trust.npz"
"""A map's measured trust index is kept beside it: ``maps/visual.trust.npz``."""


@dataclass(frozen=True)
class TrustModel:
    """The formula's constants (config ``fusion.trust``)."""

    t_clear: float
    noise_blind: float
    contrast_clear: float
    agreement_clear: float = 0.0

    def camera_trust(
        self, impulse_fraction: np.ndarray, rms_contrast: np.ndarray, tracked: np.ndarray
    ) -> np.ndarray:
        """(N,) camera trust in [0, 1] of N frames' measurements."""
        noise = np.clip(1.0 - np.asarray(impulse_fraction, float) / self.noise_blind, 0.0, 1.0)
        contrast = np.clip(np.asarray(rms_contrast, float) / self.contrast_clear, 0.0, 1.0)
        return noise * contrast * np.asarray(tracked, dtype=float)

    def radar_trust(self, camera_trust: np.ndarray | float) -> np.ndarray:
        """The trust index t of the camera trust: ``t_clear`` for a clear camera, 1 blind."""
        return 1.0 - (1.0 - self.t_clear) * np.asarray(camera_trust, dtype=float)

    def agreement_factor(self, rho: float | None) -> float:
        """How far the camera's trust holds given its map's agreement ``rho`` with the radar
        map (1: sound, or not measured, or the factor not used)."""
        if rho is None or self.agreement_clear <= 0.0:
            return 1.0
        return float(np.clip(rho / self.agreement_clear, 0.0, 1.0))


def trust_grid(
    spec: GridSpec,
    keyframe_t: np.ndarray,
    points_xy_m: np.ndarray,
    keyframe_of_point: np.ndarray,
    default_t: float,
) -> np.ndarray:
    """(rows, cols) t per cell of ``spec``: the mean t of the keyframes whose points fell in
    the cell, each keyframe counted once; ``default_t`` where none did.

    keyframe_t: (K,) t per keyframe; points_xy_m: (P, 2) world points;
    keyframe_of_point: (P,) index of the keyframe that saw each point.
    """
    keyframe_t = np.asarray(keyframe_t, dtype=float)
    total = np.zeros(spec.shape[0] * spec.shape[1])
    count = np.zeros_like(total)
    cells = spec.cells_of(np.asarray(points_xy_m, dtype=float).reshape(-1, 2))
    inside = spec.inside(cells)
    if inside.any():
        flat = cells[inside, 1] * spec.shape[1] + cells[inside, 0]
        pairs = np.unique(np.stack([np.asarray(keyframe_of_point)[inside], flat], axis=1), axis=0)
        np.add.at(total, pairs[:, 1], keyframe_t[pairs[:, 0]])
        np.add.at(count, pairs[:, 1], 1.0)
    grid = np.full(total.shape, float(default_t))
    seen = count > 0
    grid[seen] = total[seen] / count[seen]
    return grid.reshape(spec.shape)


def save_trust(path: Path, trust: np.ndarray, t_run: float) -> Path:
    """Keep a (rows, cols) trust grid (over the map it sits beside) and the run's t."""
    partial = path.with_name(path.name + ".partial.npz")
    np.savez_compressed(partial, t=np.asarray(trust, dtype=np.float32), t_run=float(t_run))
    os.replace(partial, path)
    return path


def trust_beside(map_yaml: Path) -> Path:
    """Where the measured trust of the map ``map_yaml`` lies."""
    return map_yaml.with_name(map_yaml.stem + TRUST_SUFFIX)


def load_trust(path: Path, shape: tuple[int, int]) -> tuple[np.ndarray, float]:
    """(trust grid of ``shape``, the run's t) kept by :func:`save_trust`; FusionError for a
    file that is not one or does not fit the map."""
    try:
        with np.load(path, allow_pickle=False) as data:
            trust, t_run = np.asarray(data["t"], dtype=float), float(data["t_run"])
    except Exception as exc:  # numpy raises many kinds for a damaged file
        raise FusionError(f"{path}: not a trust file ({type(exc).__name__})") from None
    if trust.shape != tuple(shape):
        raise FusionError(f"{path}: trust grid {trust.shape} does not fit its map {shape}")
    if not (np.isfinite(trust).all() and trust.min() >= 0.0 and trust.max() <= 1.0):
        raise FusionError(f"{path}: trust values outside [0, 1]")
    return trust, t_run
