"""Initial guesses for map registration: Fourier-Mellin (log-polar) phase correlation.

The magnitude of an image's spectrum ignores shifts, and turns a rotation and a scale of the
image into a shift of its log-polar resampling. Phase correlation of the two log-polar spectra
gives scale and rotation (up to 180 degrees, and, for rectilinear buildings, often 90); each
guess then gets its shift from a second phase correlation, and is scored on wall agreement.
All images here are float32 wall images as stored on disk (row 0 at the top); a similarity
``A`` (3, 3) maps source pixel (col, row, 1) to destination pixel (col, row, 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft

from smokyslam.config.fusion import RegistrationConfig
from smokyslam.mapio import FREE, OCCUPIED

_CONFLICT_WEIGHT = 0.5


@dataclass
class Candidate:
    """A guess ``A`` (3, 3), source pixel -> destination pixel, and its wall ``score``."""

    A: np.ndarray
    score: float


@dataclass
class MapFeatures:
    """A stored map image's features: ``walls`` (rows, cols) float32, occupied cells blurred;
    ``free`` (rows, cols) float32, 1 on free cells farther than two cells from any wall."""

    walls: np.ndarray
    free: np.ndarray


def map_features(stored_cells: np.ndarray, sigma_cells: float) -> MapFeatures:
    """The features of a trinary map image (rows, cols) int8; walls blurred by ``sigma_cells``."""
    occupied = (stored_cells == OCCUPIED).astype(np.uint8)
    far = cv2.distanceTransform(1 - occupied, cv2.DIST_L2, 3) > 2.0
    walls = cv2.GaussianBlur(occupied.astype(np.float32), (0, 0), sigma_cells)
    return MapFeatures(walls, ((stored_cells == FREE) & far).astype(np.float32))


def similarity_candidates(
    source: MapFeatures,
    destination: MapFeatures,
    config: RegistrationConfig,
    scale_prior: float = 1.0,
) -> list[Candidate]:
    """Similarity guesses, best first, one per basin: every scale-rotation peak turned by 0,
    90, 180 and 270 degrees, each with its best ``translation_peaks`` shifts."""
    rows, cols = destination.walls.shape
    diagonal = math.hypot(*source.walls.shape) * config.max_scale * scale_prior
    # Room for every placement of the source around the destination: no wrapped shifts.
    canvas = (
        cv2.getOptimalDFTSize(int(cols + diagonal) + 2),
        cv2.getOptimalDFTSize(int(rows + diagonal) + 2),
    )
    target = np.zeros(canvas[::-1], dtype=np.float32)
    target[:rows, :cols] = destination.walls
    target_spectrum = scipy.fft.rfft2(target)
    centre = np.array([source.walls.shape[1] - 1, source.walls.shape[0] - 1]) / 2.0
    middle = (np.array(canvas, dtype=float) - 1.0) / 2.0
    candidates = []
    for scale, angle in scale_rotation_peaks(source.walls, destination.walls, config, scale_prior):
        for quarter in range(4):
            A = similarity(scale, angle + quarter * math.pi / 2.0, centre, middle)
            walls = cv2.warpAffine(source.walls, A[:2], canvas)
            norm = float(np.sqrt((walls**2).sum()))
            for dx, dy, _ in phase_peaks(walls, None, config.translation_peaks, target_spectrum):
                shifted = A.copy()
                shifted[:2, 2] += (dx, dy)
                candidates.append(Candidate(shifted, agreement(source, destination, shifted, norm)))
    candidates.sort(key=lambda c: -c.score)
    kept: list[Candidate] = []
    for candidate in candidates:  # one per basin: refining two neighbours is wasted work
        if not any(_near(candidate.A, other.A, centre) for other in kept):
            kept.append(candidate)
    return kept


def _near(A: np.ndarray, B: np.ndarray, centre: np.ndarray, tolerance_px: float = 6.0) -> bool:
    """Whether two similarities place the source's centre and its corners within a few pixels."""
    corners = np.array([[0, 0, 1], [2 * centre[0], 2 * centre[1], 1], [*centre, 1]], dtype=float)
    return bool(np.abs((A - B) @ corners.T).max() < tolerance_px)


def phase_peaks(
    a: np.ndarray, b: np.ndarray | None, count: int, b_spectrum: np.ndarray | None = None
) -> list[tuple[float, float, float]]:
    """The ``count`` strongest shifts ``(dx, dy, strength)`` that take ``a`` onto ``b``
    (``b(x) ~ a(x - d)``), both (H, W) float32; shifts are signed (wrapped), with sub-pixel
    centroids. ``b_spectrum`` (``scipy.fft.rfft2(b)``) may stand in for ``b``."""
    if b_spectrum is None:
        b_spectrum = scipy.fft.rfft2(b)
    cross = b_spectrum * np.conj(scipy.fft.rfft2(a))
    magnitude = np.abs(cross)
    # Partial whitening: sharp peaks without blowing up the empty part of the spectrum.
    cross /= magnitude + 1e-3 * magnitude.max() + 1e-12
    surface = scipy.fft.irfft2(cross, s=a.shape)
    rows, cols = surface.shape
    work = surface.copy()
    peaks = []
    for _ in range(count):
        iy, ix = np.unravel_index(int(np.argmax(work)), work.shape)
        ys, xs = (iy + np.arange(-1, 2)) % rows, (ix + np.arange(-1, 2)) % cols
        patch = np.clip(surface[np.ix_(ys, xs)], 0.0, None)
        total = patch.sum() or 1.0
        dy = iy + float((patch.sum(axis=1) * np.arange(-1, 2)).sum() / total)
        dx = ix + float((patch.sum(axis=0) * np.arange(-1, 2)).sum() / total)
        peaks.append((_signed(dx, cols), _signed(dy, rows), float(surface[iy, ix])))
        ys, xs = (iy + np.arange(-3, 4)) % rows, (ix + np.arange(-3, 4)) % cols
        work[np.ix_(ys, xs)] = -np.inf
    return peaks


def _signed(shift: float, size: int) -> float:
    return shift - size if shift > size / 2 else shift


def _log_polar_spectrum(image: np.ndarray, size: int, config: RegistrationConfig) -> np.ndarray:
    """(angle_bins, radius_bins) float32: the high-passed log magnitude spectrum, log-polar."""
    canvas = np.zeros((size, size), dtype=np.float32)
    rows, cols = image.shape
    top, left = (size - rows) // 2, (size - cols) // 2
    canvas[top : top + rows, left : left + cols] = image
    spectrum = np.log1p(np.abs(np.fft.fftshift(np.fft.fft2(canvas))))
    # Reddy-Chatterji high-pass: low frequencies (room-sized blobs, the map's outline) weigh
    # little; they swamp the wall directions otherwise.
    f = np.fft.fftshift(np.fft.fftfreq(size))
    c = np.cos(np.pi * f[:, None]) * np.cos(np.pi * f[None, :])
    spectrum *= (1.0 - c) * (2.0 - c)
    polar = cv2.warpPolar(
        spectrum.astype(np.float32),
        (config.polar_radius_bins, config.polar_angle_bins),
        (size / 2.0, size / 2.0),
        size / 2.0,
        cv2.WARP_POLAR_LOG | cv2.INTER_LINEAR,
    )
    # The radial profile (blur, wall thickness, pixel grid) is the same in both maps whatever
    # their scale: left in, it pins the scale at 1. Only the angular structure is kept, and
    # the radius axis (not periodic) is windowed.
    polar -= polar.mean(axis=0, keepdims=True)
    return polar * np.hanning(config.polar_radius_bins).astype(np.float32)


def scale_rotation_peaks(
    source: np.ndarray, destination: np.ndarray, config: RegistrationConfig, scale_prior: float
) -> list[tuple[float, float]]:
    """Up to ``rotation_peaks`` ``(scale, angle_rad)`` guesses of the source-to-destination
    similarity, scale within the configured range around ``scale_prior``. The angle is the
    image rotation (col, row axes: positive turns +col towards +row), known modulo pi."""
    size = cv2.getOptimalDFTSize(max(*source.shape, *destination.shape))
    lp_source = _log_polar_spectrum(source, size, config)
    lp_destination = _log_polar_spectrum(destination, size, config)
    per_radius_bin = math.log(size / 2.0) / config.polar_radius_bins
    peaks = phase_peaks(lp_source, lp_destination, 4 * config.rotation_peaks)
    guesses: list[tuple[float, float]] = []
    for d_radius, d_angle, _ in peaks:
        # A spatial scale s shrinks the spectrum by 1/s: a shift of -log(s) in log radius.
        scale = math.exp(-d_radius * per_radius_bin)
        angle = d_angle * 2.0 * math.pi / config.polar_angle_bins
        if not config.min_scale <= scale / scale_prior <= config.max_scale:
            continue
        # Each guess is tried at all four quarter turns: one per (scale, angle mod 90).
        if any(_same_guess((scale, angle), guess) for guess in guesses):
            continue
        guesses.append((scale, angle))
        if len(guesses) == config.rotation_peaks:
            break
    return guesses or [(scale_prior, 0.0)]


def _same_guess(a: tuple[float, float], b: tuple[float, float]) -> bool:
    quarter = math.pi / 2.0
    turn = (a[1] - b[1] + quarter / 2.0) % quarter - quarter / 2.0
    return abs(math.log(a[0] / b[0])) < 0.03 and abs(turn) < math.radians(2.0)


def similarity(
    scale: float, angle_rad: float, centre: np.ndarray, target: np.ndarray
) -> np.ndarray:
    """(3, 3): scale and rotate about source pixel ``centre``, which lands on ``target``."""
    c, s = scale * math.cos(angle_rad), scale * math.sin(angle_rad)
    R = np.array([[c, -s], [s, c]])
    A = np.eye(3)
    A[:2, :2] = R
    A[:2, 2] = target - R @ centre
    return A


def agreement(
    source: MapFeatures, destination: MapFeatures, A: np.ndarray, source_norm: float
) -> float:
    """Wall agreement of the source warped by ``A`` (3, 3) with the destination, at most 1:
    the correlation of the walls less the walls on the other's free space, normalised by all
    the walls of both (``source_norm``: of the warped source), so a small overlap scores low."""
    size = destination.walls.shape[::-1]
    walls = cv2.warpAffine(source.walls, A[:2], size)
    free = cv2.warpAffine(source.free, A[:2], size, flags=cv2.INTER_NEAREST)
    match = float((walls * destination.walls).sum())
    conflict = float((walls * destination.free).sum()) + float((free * destination.walls).sum())
    norms = source_norm * float(np.sqrt((destination.walls**2).sum()))
    return (match - _CONFLICT_WEIGHT * conflict) / norms if norms > 0.0 else 0.0
