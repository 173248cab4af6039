"""Resampling that keeps the tracking filter's hypotheses (``localize/hypotheses.py``)."""

import numpy as np
import pytest

from smokyslam.localize.hypotheses import (
    KEEP_PARTICLES,
    MAX_HYPOTHESES,
    resample_keeping,
    split,
)
from smokyslam.localize.sampling import low_variance


def two_places(rng, light: float, apart_m: float = 3.9) -> tuple[np.ndarray, np.ndarray]:
    """1000 particles around (0, 0, 0), 300 around (``apart_m``, 0, 0) holding ``light`` of
    the weight (the place the first scans favour and the true one)."""
    near = rng.normal(0.0, [0.05, 0.05, 0.02], (1000, 3))
    far = rng.normal(0.0, [0.05, 0.05, 0.02], (300, 3)) + np.array([apart_m, 0.0, 0.0])
    weights = np.concatenate([np.full(1000, (1 - light) / 1000), np.full(300, light / 300)])
    return np.vstack([near, far]), weights


def test_the_particles_split_into_places_the_heaviest_particle_s_first():
    poses, weights = two_places(np.random.default_rng(0), 0.1)  # lighter particles far off
    groups = split(poses, weights)
    assert len(groups) == 2
    assert np.array_equal(np.sort(groups[0]), np.arange(1000))
    assert np.array_equal(np.sort(groups[1]), np.arange(1000, 1300))


def test_places_a_metre_apart_are_two_hypotheses():
    """Two places 1 m apart along an aisle are told apart (half the estimate's 1 m mode)."""
    poses, weights = two_places(np.random.default_rng(3), 0.4, apart_m=1.0)
    groups = split(poses, weights)
    assert len(groups) == 2
    assert all(np.all(g < 1000) or np.all(g >= 1000) for g in groups)  # none mixes them
    mixed = split(poses, weights, radius_m=1.0)  # with the estimate's mode radius they mix
    assert not all(np.all(g < 1000) or np.all(g >= 1000) for g in mixed)


def test_particles_beyond_the_last_hypothesis_are_kept_as_one_group():
    """Twelve places: eight hypotheses and one group of the rest, every particle in one."""
    rng = np.random.default_rng(4)
    centres = np.column_stack([2.0 * np.arange(12), np.zeros(12), np.zeros(12)])
    poses = np.repeat(centres, 50, axis=0) + rng.normal(0.0, 0.05, (600, 3))
    weights = rng.uniform(0.5, 1.0, len(poses))
    weights /= weights.sum()
    groups = split(poses, weights)
    assert len(groups) == MAX_HYPOTHESES + 1
    assert np.array_equal(np.sort(np.concatenate(groups)), np.arange(len(poses)))
    kept, kept_weights = resample_keeping(poses, weights, 400, rng)
    assert kept_weights.sum() == pytest.approx(1.0)
    for k in range(12):  # every place keeps its weight
        place = np.abs(kept[:, 0] - 2.0 * k) < 0.5
        truth = weights[50 * k : 50 * (k + 1)].sum()
        assert kept_weights[place].sum() == pytest.approx(truth, rel=0.05)


@pytest.mark.parametrize("light", [1e-6, 1e-12])
def test_a_disfavoured_place_keeps_particles_and_its_weight(light):
    """Plain low-variance resampling leaves no particle where 1e-6 of the weight lies; the
    hypotheses' resampling keeps at least KEEP_PARTICLES there, with the same total weight,
    and the favoured place its share of the count."""
    rng = np.random.default_rng(1)
    poses, weights = two_places(rng, light)
    plain = poses[low_variance(weights, 500, rng)]
    assert np.all(plain[:, 0] < 2.0)
    kept, kept_weights = resample_keeping(poses, weights, 500, rng)
    far = kept[:, 0] > 2.0
    assert np.count_nonzero(far) >= KEEP_PARTICLES
    assert np.count_nonzero(~far) == pytest.approx(500, abs=5)
    share = kept_weights[far].sum() / kept_weights.sum()
    assert share == pytest.approx(light, rel=1e-6)
    assert np.all(np.abs(kept[far, :2] - [3.9, 0.0]).max(axis=1) < 0.5)


def test_a_place_below_the_keeping_share_is_dropped():
    rng = np.random.default_rng(2)
    poses, weights = two_places(rng, 1e-30)
    weights[1000:] = np.exp(-45.0) / 300  # below KEEP_SHARE (e^-40) of the whole
    kept, _ = resample_keeping(poses, weights / weights.sum(), 500, rng)
    assert np.all(kept[:, 0] < 2.0)
