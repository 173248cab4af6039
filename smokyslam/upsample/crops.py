"""Random training crops of map pairs, rotated and flipped (the 8 symmetries of the square).

A crop is drawn from a pair chosen at random, at a random position (so every phase of the
network's stride is seen), kept when the truth knows enough of it. Maps smaller than a crop
are padded with unknown cells, exactly what the world beyond a map is.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from smokyslam.config.upsample import UpsamplerTrainingConfig
from smokyslam.mapio import OCCUPIED, UNKNOWN
from smokyslam.upsample.dataset import MapPair
from smokyslam.upsample.encoding import encode_cells, target_values

MIN_KNOWN_SHARE = 0.15
"""A crop whose truth knows less than this share is drawn again (a few tries)."""
TRIES = 4


class CropSampler:
    """Batches of (inputs (B, 2, C, C), targets (B, 1, C, C), L1 weights (B, 1, C, C))."""

    def __init__(
        self,
        pairs: Sequence[MapPair],
        config: UpsamplerTrainingConfig,
        rng: np.random.Generator,
    ) -> None:
        if not pairs:
            raise ValueError("no training pairs")
        self.crop = config.crop_cells
        self.rng = rng
        self.occupied_weight, self.unknown_weight = config.occupied_weight, config.unknown_weight
        self.pairs = [self._padded(pair) for pair in pairs]

    def _padded(self, pair: MapPair) -> tuple[np.ndarray, np.ndarray]:
        rows, cols = pair.truth.shape
        pad = ((0, max(self.crop - rows, 0)), (0, max(self.crop - cols, 0)))
        return (
            np.pad(pair.sparse, pad, constant_values=UNKNOWN),
            np.pad(pair.truth, pad, constant_values=UNKNOWN),
        )

    def batch(self, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sparse, truth = zip(*(self._crop() for _ in range(size)), strict=True)
        inputs = np.stack([encode_cells(s) for s in sparse])
        truth = np.stack(truth)
        targets = target_values(truth)[:, None]
        weights = np.select(
            [truth == OCCUPIED, truth == UNKNOWN], [self.occupied_weight, self.unknown_weight], 1.0
        ).astype(np.float32)[:, None]
        return inputs, targets, weights

    def _crop(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.crop
        for _ in range(TRIES):
            sparse, truth = self.pairs[self.rng.integers(len(self.pairs))]
            r0 = self.rng.integers(truth.shape[0] - c + 1)
            c0 = self.rng.integers(truth.shape[1] - c + 1)
            window = (slice(r0, r0 + c), slice(c0, c0 + c))
            if (truth[window] != UNKNOWN).mean() >= MIN_KNOWN_SHARE:
                break
        turns, flip = int(self.rng.integers(4)), bool(self.rng.integers(2))
        return _symmetry(sparse[window], turns, flip), _symmetry(truth[window], turns, flip)


def _symmetry(cells: np.ndarray, turns: int, flip: bool) -> np.ndarray:
    cells = np.rot90(cells, turns)
    return np.ascontiguousarray(cells[:, ::-1] if flip else cells)
