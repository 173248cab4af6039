"""Vectorized Bresenham against the per-ray reference, and hand-checked rays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from smokyslam.mapping import raycast as raycast_module
from smokyslam.mapping.raycast import naive_raycast, ray_lengths, raycast

coordinate = st.integers(-60, 60)
ray = st.tuples(coordinate, coordinate, st.booleans())


def _assert_same(origin, ends, max_range):
    free, hits = raycast(origin, ends, max_range)
    free_ref, hits_ref = naive_raycast(origin, ends, max_range)
    np.testing.assert_array_equal(free, free_ref)
    np.testing.assert_array_equal(hits, hits_ref)
    return free, hits


@settings(max_examples=150, deadline=None)
@given(origin=st.tuples(coordinate, coordinate), rays=st.lists(ray, min_size=0, max_size=30))
def test_raycast_matches_reference_on_random_rays(origin, rays):
    ends = np.array([(x, y) for x, y, _ in rays], dtype=np.int64).reshape(-1, 2)
    max_range = np.array([flag for _, _, flag in rays], dtype=bool)
    _assert_same(np.array(origin), ends, max_range)


def test_every_octant_axis_diagonal_and_zero_length_ray_match_reference():
    angles = np.linspace(-np.pi, np.pi, 72, endpoint=False)  # every octant and the axes
    ends = np.rint(np.stack([37 * np.cos(angles), 37 * np.sin(angles)], axis=1)).astype(int)
    ends = np.concatenate([ends, [[0, 0], [5, 5], [-5, 5], [-5, -5], [5, -5]]]) + np.array([3, -4])
    max_range = np.zeros(len(ends), dtype=bool)
    max_range[::3] = True
    free, hits = _assert_same(np.array([3, -4]), ends, max_range)
    assert len(free) == ray_lengths([3, -4], ends).sum()
    assert len(hits) == (~max_range).sum()


def test_hand_traced_rays():
    free, hits = raycast([0, 0], [[3, 1]])
    np.testing.assert_array_equal(free, [[0, 0], [1, 0], [2, 1]])  # endpoint excluded
    np.testing.assert_array_equal(hits, [[3, 1]])
    # Exact halves round towards +infinity, whichever way the ray goes.
    np.testing.assert_array_equal(raycast([0, 0], [[2, 1]])[0], [[0, 0], [1, 1]])
    np.testing.assert_array_equal(raycast([0, 0], [[2, -1]])[0], [[0, 0], [1, 0]])
    # A zero-length ray hits its own cell; a max-range one leaves no hit at all.
    free, hits = raycast([4, 4], [[4, 4], [7, 4]], np.array([False, True]))
    np.testing.assert_array_equal(free, [[4, 4], [5, 4], [6, 4]])
    np.testing.assert_array_equal(hits, [[4, 4]])


def test_per_ray_origins_far_from_zero_and_in_chunks(monkeypatch):
    rng = np.random.default_rng(3)
    origins = rng.integers(-50, 50, (200, 2)) + np.array([3_000_000, -2_000_000])  # far away
    ends = origins + rng.integers(-200, 200, (200, 2))
    monkeypatch.setattr(raycast_module, "_CHUNK_CELLS", 500)  # many chunks
    _assert_same(origins, ends, None)


def test_overlong_rays_are_refused():
    with pytest.raises(ValueError, match="at most"):
        raycast([0, 0], [[1 << 19, 0]])
    with pytest.raises(ValueError, match="span"):
        raycast([-(1 << 21), 0], [[10, 0]])
