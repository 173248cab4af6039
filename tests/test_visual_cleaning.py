"""Cleaning visual points before flattening (open3d): strays go, walls stay, cameras follow."""

from __future__ import annotations

import numpy as np
import pytest

from smokyslam.config import MappingConfig
from smokyslam.mapping.visual_cleaning import clean_point_indices

pytest.importorskip("open3d")


def _wall_and_strays(seed: int = 0) -> tuple[np.ndarray, int]:
    rng = np.random.default_rng(seed)
    wall = np.c_[rng.uniform(0, 5, 500), 2.0 + rng.normal(0, 0.01, 500), rng.uniform(0.3, 1.8, 500)]
    strays = rng.uniform([0.0, -5.0, 0.3], [5.0, 10.0, 1.8], (20, 3))
    return np.r_[wall, strays], len(wall)


def test_off_by_default_keeps_every_point():
    points, _ = _wall_and_strays()
    np.testing.assert_array_equal(clean_point_indices(points, MappingConfig()), np.arange(520))


def test_outlier_removal_drops_strays_and_keeps_the_wall():
    points, n_wall = _wall_and_strays()
    kept = clean_point_indices(points, MappingConfig(visual_cleaning=True))
    assert (kept < n_wall).sum() == n_wall  # every wall point
    assert (kept >= n_wall).sum() <= 6  # most of the 20 strays go (measured: 15)


def test_voxels_keep_one_point_each_and_indices_point_into_the_input():
    points, n_wall = _wall_and_strays()
    config = MappingConfig(visual_cleaning=True, visual_voxel_m=0.25)
    kept = clean_point_indices(points, config)
    assert np.all(np.diff(kept) > 0) and kept.max() < len(points)
    voxels = np.floor(points[kept] / 0.25).astype(int)
    assert len(np.unique(voxels, axis=0)) == len(kept)  # one point per voxel
    assert (kept < n_wall).sum() < 0.5 * n_wall
