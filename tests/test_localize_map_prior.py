"""The map the localizer weighs against: a map as sparse as a stitched radar map is
up-sampled first (``localize/map_prior.py``); any other map is used as given."""

import numpy as np
import pytest
from scipy.ndimage import binary_dilation
from sim_scenes import l_world

from smokyslam.config import SmokySlamConfig
from smokyslam.localize.map_prior import isolated_share, localization_map
from smokyslam.mapio import FREE, OCCUPIED, UNKNOWN


def test_the_isolated_share_counts_occupied_cells_without_an_occupied_neighbour():
    cells = np.full((10, 10), FREE, dtype=np.int8)
    assert isolated_share(cells) == 0.0
    cells[2, 2] = cells[7, 7] = OCCUPIED  # two lone returns
    cells[5, 1:5] = OCCUPIED  # a wall of four
    cells[0, 9] = UNKNOWN
    assert isolated_share(cells) == pytest.approx(2 / 6)
    cells[3, 3] = OCCUPIED  # a diagonal neighbour joins (2, 2) to it
    assert isolated_share(cells) == pytest.approx(1 / 7)


def sparse_radar_map(cells: np.ndarray, rng) -> np.ndarray:
    """A radar-like map of a ground-truth map: the free space known, a wall surface cell
    returned with probability 0.3, the rest unknown."""
    surface = (cells == OCCUPIED) & binary_dilation(cells == FREE, np.ones((3, 3), bool))
    sparse = np.where(cells == FREE, FREE, UNKNOWN).astype(np.int8)
    sparse[surface & (rng.random(cells.shape) < 0.3)] = OCCUPIED
    return sparse


def test_a_sparse_radar_map_is_up_sampled_and_a_whole_map_is_used_as_given():
    pytest.importorskip("torch")
    world = l_world()
    truth = world.ground_truth_cells()
    config = SmokySlamConfig()
    given = localization_map(truth, world.spec, config)
    assert not given.densified and given.isolated_share < 0.05 and given.cells is truth

    sparse = sparse_radar_map(truth, np.random.default_rng(0))
    assert isolated_share(sparse) > 0.3  # as sparse as a stitched radar map (0.24-0.46)
    used = localization_map(sparse, world.spec, config)
    assert used.densified and used.isolated_share == pytest.approx(isolated_share(sparse))
    assert isolated_share(used.cells) < 0.1  # the returns joined into walls
    # Its walls lie where the truth's are: most of its occupied cells touch a true wall.
    near_wall = binary_dilation(truth == OCCUPIED, np.ones((3, 3), bool))
    occupied = used.cells == OCCUPIED
    assert np.count_nonzero(occupied) > 2 * np.count_nonzero(sparse == OCCUPIED)
    assert np.count_nonzero(occupied & near_wall) > 0.8 * np.count_nonzero(occupied)

    config.localize.densify = "never"
    assert localization_map(sparse, world.spec, config).cells is sparse
    config.localize.densify = "always"
    assert localization_map(truth, world.spec, config).densified
