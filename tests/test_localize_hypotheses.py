"""Resampling that keeps the tracking filter's hypotheses (``localize/hypotheses.py``)."""

import numpy as np
import pytest

from smokyslam.localize.hypotheses import KEEP_PARTICLES, resample_keeping, split
from smokyslam.localize.sampling import low_variance

RADIUS_M, RADIUS_RAD = 1.0, np.radians(30.0)


def two_places(rng, light: float) -> tuple[np.ndarray, np.ndarray]:
    """1000 particles around (0, 0, 0), 300 around (3.9, 0, 0) holding ``light`` of the
    weight (the place the first scans favour and the true one)."""
    near = rng.normal(0.0, [0.2, 0.2, 0.05], (1000, 3))
    far = rng.normal(0.0, [0.2, 0.2, 0.05], (300, 3)) + np.array([3.9, 0.0, 0.0])
    weights = np.concatenate([np.full(1000, (1 - light) / 1000), np.full(300, light / 300)])
    return np.vstack([near, far]), weights


def test_the_particles_split_into_places_the_heaviest_particle_s_first():
    poses, weights = two_places(np.random.default_rng(0), 0.1)  # lighter particles far off
    groups = split(poses, weights, RADIUS_M, RADIUS_RAD)
    assert len(groups) >= 2
    heaviest = groups[0]
    assert np.all(heaviest < 1000) and len(heaviest) > 990
    assert sum(np.count_nonzero(g >= 1000) for g in groups) == 300
    assert all(np.all(g >= 1000) or np.all(g < 1000) for g in groups)


@pytest.mark.parametrize("light", [1e-6, 1e-12])
def test_a_disfavoured_place_keeps_particles_and_its_weight(light):
    """Plain low-variance resampling leaves no particle where 1e-6 of the weight lies; the
    hypotheses' resampling keeps at least KEEP_PARTICLES there, with the same total weight,
    and the favoured place its share of the count."""
    rng = np.random.default_rng(1)
    poses, weights = two_places(rng, light)
    plain = poses[low_variance(weights, 500, rng)]
    assert np.all(plain[:, 0] < 2.0)
    kept, kept_weights = resample_keeping(poses, weights, 500, rng, RADIUS_M, RADIUS_RAD)
    far = kept[:, 0] > 2.0
    assert np.count_nonzero(far) >= KEEP_PARTICLES
    assert np.count_nonzero(~far) == pytest.approx(500, abs=5)
    share = kept_weights[far].sum() / kept_weights.sum()
    assert share == pytest.approx(light, rel=1e-6)
    assert np.all(np.abs(kept[far, :2] - [3.9, 0.0]).max(axis=1) < 1.5)


def test_a_place_below_the_keeping_share_is_dropped():
    rng = np.random.default_rng(2)
    poses, weights = two_places(rng, 1e-30)
    weights[1000:] = np.exp(-45.0) / 300  # below KEEP_SHARE (e^-40) of the whole
    kept, _ = resample_keeping(poses, weights / weights.sum(), 500, rng, RADIUS_M, RADIUS_RAD)
    assert np.all(kept[:, 0] < 2.0)
