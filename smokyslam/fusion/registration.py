"""Registering one occupancy map onto another by a homography (the paper's eq. 2).

``H`` (3, 3) maps a source pixel (col, row, 1) to a destination pixel (col, row, 1) of the two
maps' images as stored on disk (row 0 at the top, as in the PGM), not of smokyslam's
``[iy, ix]`` arrays (iy northwards): every function here takes the arrays and flips them.
The estimate minimises sum_x (dst(Hx) - src(x))^2 over the overlap: an initial similarity from
log-polar phase correlation (``phase.py``), refined by OpenCV's ECC (homography model, masked
to cells known in both maps, coarse to fine) on smoothed occupancy images. ECC maximises their
correlation coefficient: eq. 2's least squares once an offset and a gain of the values are
allowed for (a sparse radar map and a dense visual one differ by both).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import cv2
import numpy as np

from smokyslam.config.fusion import RegistrationConfig
from smokyslam.errors import FusionError
from smokyslam.fusion.phase import map_features, similarity_candidates
from smokyslam.mapio import OCCUPIED, UNKNOWN

logger = logging.getLogger(__name__)

_MIN_SIDE_CELLS = 16
_MARGIN_CELLS = 4  # kept around the known cells when the source is cropped


@dataclass
class Registration:
    """Where the source map lies in the destination map, and how far to trust it.

    H: (3, 3) source pixel (col, row) -> destination pixel (col, row), images as stored.
    rms_residual: RMS of dst(Hx) - src(x) over the overlap, occupancy values 1 / 0 (0-1).
    overlap: fraction of the source's known cells that land on destination known cells.
    correlation: ECC correlation of the smoothed maps over the overlap (-1..1).
    confidence: in [0, 1], from the correlation and the overlap.
    confident: confidence >= the config's threshold; apply H only if True.
    """

    H: np.ndarray
    rms_residual: float
    overlap: float
    correlation: float
    confidence: float
    confident: bool


def register_maps(
    source_cells: np.ndarray,
    destination_cells: np.ndarray,
    config: RegistrationConfig,
    scale_prior: float = 1.0,
) -> Registration:
    """Estimate the homography taking ``source_cells`` onto ``destination_cells``.

    Both maps are trinary (rows, cols) int8 arrays (100 / 0 / -1) indexed ``[iy, ix]``, as
    ``mapio`` loads them. ``scale_prior``: the expected source-to-destination pixel scale (the
    ratio of the resolutions); the search spans ``min_scale``-``max_scale`` times it.
    FusionError for a map without a known cell or without a wall.
    """
    src = _stored(source_cells, "source map")
    dst = _stored(destination_cells, "destination map")
    sigma = config.init_blur_sigma_cells
    candidates = similarity_candidates(
        map_features(src, sigma), map_features(dst, sigma), config, scale_prior
    )
    # Two rankings of the guesses: wall agreement (robust to partial overlap) and the
    # confidence itself (robust when one map shows fewer walls than the other, e.g. a visual
    # map against a radar map); the best few of each are refined.
    assessed = [(_assess(src, dst, c.A, config), c) for c in candidates]
    by_confidence = sorted(range(len(assessed)), key=lambda i: -assessed[i][0].confidence)
    chosen = list(range(min(config.refine_candidates, len(assessed))))
    chosen += [i for i in by_confidence[: config.refine_candidates] if i not in chosen]
    best = None
    for i in chosen:
        start, candidate = assessed[i]
        H = refine_homography(src, dst, candidate.A, config)
        refined = _assess(src, dst, H, config)
        # ECC may wander off into a degenerate warp across modalities: keep the start then.
        result = refined if _plausible(H, src.shape, config, scale_prior) else start
        if result.confidence < start.confidence:
            result = start
        logger.debug("candidate score %.3f -> %s", candidate.score, result)
        if best is None or result.confidence > best.confidence:
            best = result
    return best


def _plausible(
    H: np.ndarray, shape: tuple[int, int], config: RegistrationConfig, scale_prior: float
) -> bool:
    """Whether ``H`` is a warp a map can undergo: a scale within the searched range (with a
    margin), nearly the same in every direction, and little perspective over the map."""
    if not np.all(np.isfinite(H)):
        return False
    singular = np.linalg.svd(H[:2, :2] / H[2, 2], compute_uv=False)
    low, high = 0.8 * config.min_scale * scale_prior, 1.25 * config.max_scale * scale_prior
    perspective = float(np.abs(H[2, :2] / H[2, 2]).sum()) * max(shape)
    return (
        bool(
            low <= singular.min()
            and singular.max() <= high
            and singular.max() < 1.3 * singular.min()
        )
        and perspective < 0.3
    )


def refine_homography(
    src: np.ndarray, dst: np.ndarray, H: np.ndarray, config: RegistrationConfig
) -> np.ndarray:
    """ECC refinement of ``H`` (3, 3) between stored map images ``src`` and ``dst``, coarsest
    pyramid level first; a level where ECC does not converge keeps the estimate it was given."""
    criteria = (
        cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS,
        config.ecc_iterations,
        config.ecc_eps,
    )
    # The source's known bounding box only: less work, and OpenCV before 4.13 cannot mask
    # the source's unknown cells out of ECC (see _ecc).
    rows, cols = np.nonzero(src != UNKNOWN)
    top, left = max(rows.min() - _MARGIN_CELLS, 0), max(cols.min() - _MARGIN_CELLS, 0)
    src = src[top : rows.max() + _MARGIN_CELLS + 1, left : cols.max() + _MARGIN_CELLS + 1]
    crop = np.array([[1.0, 0.0, left], [0.0, 1.0, top], [0.0, 0.0, 1.0]])
    H = H @ crop
    H = H / H[2, 2]
    for level in reversed(range(config.pyramid_levels)):
        (src_image, src_mask), S_src = _level(src, level, config)
        (dst_image, dst_mask), S_dst = _level(dst, level, config)
        if min(*src_image.shape, *dst_image.shape) < _MIN_SIDE_CELLS:
            continue
        W = (S_dst @ H @ np.linalg.inv(S_src)).astype(np.float32)
        try:
            _, W = _ecc(src_image, dst_image, src_mask, dst_mask, W / W[2, 2], criteria)
        except cv2.error:  # no convergence (e.g. no overlap left)
            continue
        H = np.linalg.inv(S_dst) @ W.astype(float) @ S_src
        H = H / H[2, 2]
    H = H @ np.linalg.inv(crop)
    return H / H[2, 2]


def correlation(
    src: np.ndarray, dst: np.ndarray, H: np.ndarray, config: RegistrationConfig
) -> float:
    """ECC's correlation coefficient (-1..1) of the smoothed occupancy images of stored maps
    ``src`` and ``dst`` under ``H``, over the cells known in both; -1 without such cells."""
    (src_image, src_mask), _ = _level(src, 0, config)
    (dst_image, dst_mask), _ = _level(dst, 0, config)
    size = src_image.shape[::-1]
    inverse = cv2.WARP_INVERSE_MAP
    dst_at_src = cv2.warpPerspective(dst_image, H, size, flags=cv2.INTER_LINEAR | inverse)
    known = cv2.warpPerspective(dst_mask, H, size, flags=cv2.INTER_NEAREST | inverse) > 0
    known &= src_mask > 0
    if known.sum() < _MIN_SIDE_CELLS**2:
        return -1.0
    a, b = src_image[known] - src_image[known].mean(), dst_at_src[known] - dst_at_src[known].mean()
    norms = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return float((a * b).sum()) / norms if norms > 0.0 else -1.0


def agreement(cells_a: np.ndarray, cells_b: np.ndarray, config: RegistrationConfig) -> float | None:
    """:func:`correlation` of two trinary maps on one grid, as they lie (no warp); None when
    they share too few known cells to measure it."""
    rho = correlation(np.asarray(cells_a), np.asarray(cells_b), np.eye(3), config)
    return None if rho == -1.0 else rho


def _ecc(template, image, template_mask, image_mask, W, criteria):
    if hasattr(cv2, "findTransformECCWithMask"):  # OpenCV >= 4.13 masks both images
        return cv2.findTransformECCWithMask(
            template, image, template_mask, image_mask, W, cv2.MOTION_HOMOGRAPHY, criteria, 3
        )
    # Older OpenCV masks the input image only: the template's unknown cells get its mean
    # value, which adds nothing to the (zero-mean) correlation.
    template = np.where(template_mask > 0, template, template[template_mask > 0].mean())
    return cv2.findTransformECC(template, image, W, cv2.MOTION_HOMOGRAPHY, criteria, image_mask, 3)


def warp_cells(
    source_cells: np.ndarray, H: np.ndarray, destination_shape: tuple[int, int]
) -> np.ndarray:
    """(rows, cols) int8 of ``destination_shape``: the source map (``[iy, ix]`` cells) warped
    by ``H`` (stored-image pixels) onto the destination grid; nearest cell, outside unknown."""
    warped = _warp_grid(
        np.asarray(source_cells).astype(np.int16), H, destination_shape, cv2.INTER_NEAREST, UNKNOWN
    )
    return warped.astype(np.int8)


def warp_values(
    values: np.ndarray, H: np.ndarray, destination_shape: tuple[int, int], fill: float
) -> np.ndarray:
    """(rows, cols) float ``values`` over a source grid (``[iy, ix]``) warped by ``H``
    (stored-image pixels, as :func:`warp_cells`), bilinear, ``fill`` outside."""
    values = np.asarray(values, dtype=np.float32)
    return _warp_grid(values, H, destination_shape, cv2.INTER_LINEAR, fill).astype(float)


def _warp_grid(
    grid: np.ndarray, H: np.ndarray, destination_shape: tuple[int, int], flags: int, fill: float
) -> np.ndarray:
    """A ``[iy, ix]`` grid warped by the stored-image homography ``H``: flipped to the stored
    image, warped, flipped back."""
    rows, cols = destination_shape
    warped = cv2.warpPerspective(
        np.flipud(grid),
        np.asarray(H, dtype=float),
        (cols, rows),
        flags=flags,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=float(fill),
    )
    return np.ascontiguousarray(np.flipud(warped))


def map_residual(
    source_cells: np.ndarray, destination_cells: np.ndarray, H: np.ndarray
) -> tuple[float, float]:
    """``(rms_residual, overlap)`` of eq. 2 for ``H``: dst(Hx) - src(x) at every source cell
    x whose image Hx lands on a known destination cell, on occupancy values 1 / 0."""
    return _residual(np.flipud(source_cells), np.flipud(destination_cells), H)


def _residual(src: np.ndarray, dst: np.ndarray, H: np.ndarray) -> tuple[float, float]:
    dst_at_src = cv2.warpPerspective(
        dst.astype(np.int16),
        np.asarray(H, dtype=float),
        (src.shape[1], src.shape[0]),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=UNKNOWN,
    )
    known = src != UNKNOWN
    both = known & (dst_at_src != UNKNOWN)
    if not both.any():
        return 1.0, 0.0
    mismatch = (dst_at_src[both] == OCCUPIED) != (src[both] == OCCUPIED)
    return math.sqrt(mismatch.mean()), float(both.sum() / known.sum())


def _assess(src, dst, H, config: RegistrationConfig) -> Registration:
    if not np.all(np.isfinite(H)) or abs(np.linalg.det(H[:2, :2])) < 1e-6:
        return Registration(H, 1.0, 0.0, -1.0, 0.0, False)
    rms, overlap = _residual(src, dst, H)
    rho = correlation(src, dst, H, config)
    confidence = max(rho, 0.0) * min(overlap / config.full_overlap, 1.0)
    return Registration(
        H=H,
        rms_residual=rms,
        overlap=overlap,
        correlation=rho,
        confidence=confidence,
        confident=confidence >= config.confidence_threshold,
    )


def check_registrable(cells: np.ndarray, name: str) -> None:
    """FusionError, one line starting with ``name``, for a map registration cannot use: not a
    2D grid of 16 cells a side or more, no known cell, or no wall (occupied cell)."""
    cells = np.asarray(cells)
    if cells.ndim != 2 or min(cells.shape) < _MIN_SIDE_CELLS:
        raise FusionError(f"{name}: a map of {_MIN_SIDE_CELLS} cells a side or more is needed")
    if not (cells != UNKNOWN).any():
        raise FusionError(f"{name}: the map has no known cell (all unknown): nothing to register")
    if not (cells == OCCUPIED).any():
        raise FusionError(f"{name}: the map has no occupied cell: no wall to register on")


def _stored(cells: np.ndarray, name: str) -> np.ndarray:
    """The map as its image is stored (row 0 at the top), checked."""
    check_registrable(cells, name)
    return np.flipud(np.asarray(cells))


def _blurred(image: np.ndarray, sigma: float) -> np.ndarray:
    return cv2.GaussianBlur(image.astype(np.float32), (0, 0), sigma)


def _level(cells: np.ndarray, level: int, config: RegistrationConfig):
    """((image, mask), S) of pyramid ``level``: the occupancy value (1 occupied, 0 free) blurred
    over known cells only, the known mask (uint8), and S (3, 3) taking full-resolution pixels
    to this level's (pixel centres kept)."""
    known = (cells != UNKNOWN).astype(np.float32)
    value = (cells == OCCUPIED).astype(np.float32)
    rows, cols = cells.shape
    size = (max(round(cols / 2**level), 1), max(round(rows / 2**level), 1))
    if level:
        known = cv2.resize(known, size, interpolation=cv2.INTER_AREA)
        value = cv2.resize(value, size, interpolation=cv2.INTER_AREA)
    # Normalised convolution: unknown cells neither count nor leak into their neighbours.
    weight = _blurred(known, config.blur_sigma_cells)
    image = _blurred(value, config.blur_sigma_cells) / np.maximum(weight, 1e-3)
    mask = (known > 0.5).astype(np.uint8)
    fx, fy = size[0] / cols, size[1] / rows
    S = np.array([[fx, 0.0, 0.5 * fx - 0.5], [0.0, fy, 0.5 * fy - 0.5], [0.0, 0.0, 1.0]])
    return (image.astype(np.float32), mask), S
