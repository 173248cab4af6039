"""OccupancyGrid: log-odds updates, one change per cell per observation, growth, views."""

from __future__ import annotations

import numpy as np
import pytest

from smokyslam.config import MappingConfig
from smokyslam.errors import MapError
from smokyslam.mapping import grid as grid_module
from smokyslam.mapping.grid import OccupancyGrid, get_occupancy_grid, resample_nearest
from smokyslam.mapping.raycast import raycast


def _grid(**mapping) -> OccupancyGrid:
    """A grid of the mapping config with ``mapping`` overrides."""
    return get_occupancy_grid(MappingConfig(**mapping))


def _value(grid: OccupancyGrid, cell) -> float:
    """Log-odds of a world cell, via the grid's spec (independent of its internals)."""
    centre = (np.asarray(cell, dtype=float) + 0.5) * grid.resolution_m
    ix, iy = grid.spec.cells_of(centre[None])[0]
    return float(grid.log_odds[iy, ix])


def test_duplicates_count_once_and_hit_wins_over_pass():
    grid = _grid(log_odds_hit=0.9, log_odds_miss=-0.4)
    free = [[0, 0], [0, 0], [1, 0], [2, 0]]
    grid.update(free, [[2, 0], [2, 0], [5, 5]])
    assert _value(grid, [0, 0]) == pytest.approx(-0.4)
    assert _value(grid, [1, 0]) == pytest.approx(-0.4)
    assert _value(grid, [2, 0]) == pytest.approx(0.9)  # passed and hit in one scan: hit only
    assert _value(grid, [5, 5]) == pytest.approx(0.9)
    assert _value(grid, [3, 3]) == 0.0


def test_clamping_and_decisive_weight():
    grid = _grid(log_odds_hit=0.85, log_odds_miss=-0.4, log_odds_min=-2, log_odds_max=3.5)
    for _ in range(10):
        grid.update([[0, 0]], [[1, 1]])
    assert _value(grid, [0, 0]) == pytest.approx(-2.0)
    assert _value(grid, [1, 1]) == pytest.approx(3.5)
    grid.update([[1, 1]], [[0, 0]], weight=np.inf)  # the clamps at once, either way
    assert _value(grid, [1, 1]) == pytest.approx(-2.0)
    assert _value(grid, [0, 0]) == pytest.approx(3.5)


def test_probability_and_trinary_cells():
    grid = _grid(log_odds_hit=0.85, log_odds_miss=-0.4)
    grid.update([[0, 0]], [[1, 0]])
    for passes in range(1, 5):
        grid.update([[2, 0], [3, 0]] if passes < 4 else [[3, 0]], [])
    grid.update([], [[9, 9]])  # grows the window; leaves unknown cells in between
    prob, cells, spec = grid.probability(), grid.to_cells(), grid.spec

    def at(cell):
        ix, iy = spec.cells_of((np.array([cell], dtype=float) + 0.5) * 0.1)[0]
        return iy, ix

    assert prob[at([1, 0])] == pytest.approx(1 / (1 + np.exp(-0.85)))
    assert prob[at([5, 5])] == 0.5
    assert cells[at([1, 0])] == 100  # one hit: p = 0.70 > 0.65
    assert cells[at([0, 0])] == -1  # one pass: p = 0.40, not yet free
    assert cells[at([2, 0])] == -1  # three passes: p = 0.23, still above 0.196
    assert cells[at([3, 0])] == 0  # four passes: p = 0.17
    assert cells[at([5, 5])] == -1


def test_growth_keeps_content_aligns_to_world_and_is_amortized():
    grid = OccupancyGrid(0.1, 0.85, -0.75, -2.0, 3.5, 0.65, 0.196, grow_margin_cells=8)
    grid.update([], [[0, 0]])
    spec0 = grid.spec
    assert np.allclose(
        np.array(spec0.origin_xy_m) / 0.1, np.round(np.array(spec0.origin_xy_m) / 0.1)
    )
    reallocations = 0
    last_shape = grid.spec.shape
    for i in range(1, 400):
        grid.update([], [[i, -i // 2]])
        if grid.spec.shape != last_shape:
            reallocations += 1
            last_shape = grid.spec.shape
    assert reallocations < 15  # geometric growth, not one per insert
    for i in (0, 57, 399):
        assert _value(grid, [i, -i // 2]) == pytest.approx(grid.log_odds_hit)
    x0, x1, y0, y1 = grid.spec.extent_m
    assert x0 <= 0.0 and x1 >= 40.0 and y0 <= -20.0 and y1 >= 0.1


def test_insert_rays_equals_update_of_raycast_and_pieces_agree(monkeypatch):
    rng = np.random.default_rng(0)
    ends = rng.integers(-40, 40, (300, 2))
    max_range = rng.random(300) < 0.2
    reference = _grid()
    free, hits = raycast([1, 2], ends, max_range)
    reference.update(free, hits)
    grid = _grid()
    grid.insert_rays([1, 2], ends, max_range)
    np.testing.assert_array_equal(grid.to_cells(), reference.to_cells())
    np.testing.assert_allclose(grid.log_odds, reference.log_odds)
    monkeypatch.setattr(grid_module, "_RAY_CELLS_PER_PIECE", 200)  # the masked, pieced path
    pieced = _grid()
    pieced.insert_rays([1, 2], ends, max_range)
    np.testing.assert_allclose(pieced.log_odds, reference.log_odds)


def test_runaway_growth_is_a_clear_error():
    grid = _grid()
    grid.update([], [[0, 0]])
    with pytest.raises(MapError, match="diverging"):
        grid.update([], [[400_000, 400_000]])


def test_config_factory_and_resample():
    config = MappingConfig(resolution_m=0.2, log_odds_hit=1.0)
    grid = get_occupancy_grid(config)
    assert grid.resolution_m == 0.2 and grid.log_odds_hit == 1.0
    assert grid.to_cells().shape == (0, 0)
    values = np.arange(6).reshape(2, 3)
    from smokyslam.geometry import GridSpec

    coarse = GridSpec((0.0, 0.0), 1.0, (2, 3))
    fine = GridSpec((0.5, -0.5), 0.5, (4, 4))
    out = resample_nearest(values, coarse, fine, -1)
    # Fine cell [iy=1, ix=0] has its centre at (0.75, 0.25): coarse cell [0, 0].
    assert out[1, 0] == 0 and out[3, 3] == 5 and out[0, 0] == -1
