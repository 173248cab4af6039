"""2D ray casting: exact distances in a box, agreement with dense ray marching elsewhere."""

from __future__ import annotations

import numpy as np
import pytest
from sim_scenes import l_world, pillar_world

from smokyslam.geometry import GridSpec
from smokyslam.sim.raycast2d import NO_FACE, cast_rays, directions_from_angles
from smokyslam.sim.world import World, box_world


def march(world: World, origin: np.ndarray, dirs: np.ndarray, max_m: float) -> np.ndarray:
    """Reference: first occupied sample along each ray, sampled every 0.5 mm."""
    t = np.arange(0.0, max_m, 5e-4)
    pts = origin + t[None, :, None] * dirs[:, None, :]
    cells = world.spec.cells_of(pts.reshape(-1, 2))
    ok = world.spec.inside(cells)
    occ = np.zeros(len(cells), dtype=bool)
    occ[ok] = world.occupied[cells[ok, 1], cells[ok, 0]]
    occ = occ.reshape(len(dirs), len(t))
    return np.where(occ.any(axis=1), t[np.argmax(occ, axis=1)], np.inf)


def test_box_distances_faces_and_normals_are_exact():
    world = box_world(8.0, 6.0)
    dirs = directions_from_angles(np.radians([0.0, 90.0, 180.0, -90.0]))
    hits = cast_rays(world, np.array([3.0, 2.0]), dirs, 20.0)
    np.testing.assert_allclose(hits.distance_m, [5.0, 4.0, 3.0, 2.0], atol=1e-9)
    np.testing.assert_array_equal(hits.face_axis, [0, 1, 0, 1])
    np.testing.assert_allclose(hits.normal_xy, [[-1, 0], [0, -1], [1, 0], [0, 1]])
    np.testing.assert_allclose(hits.points_xy_m, [[8, 2], [3, 6], [0, 2], [3, 0]], atol=1e-9)


def test_incidence_cosine_of_oblique_ray():
    world = box_world(8.0, 6.0)
    dirs = directions_from_angles(np.radians([30.0]))
    hits = cast_rays(world, np.array([4.0, 3.0]), dirs, 20.0)
    assert hits.cos_incidence(dirs)[0] == pytest.approx(np.cos(np.radians(30.0)))
    assert hits.distance_m[0] == pytest.approx(4.0 / np.cos(np.radians(30.0)))


@pytest.mark.parametrize(
    ("make_world", "origin"), [(pillar_world, (2.37, 3.21)), (l_world, (1.13, 1.71))]
)
def test_distances_match_dense_marching(make_world, origin):
    world = make_world()
    rng = np.random.default_rng(3)
    dirs = directions_from_angles(rng.uniform(-np.pi, np.pi, 200))
    origin = np.array(origin)
    hits = cast_rays(world, origin, dirs, 15.0)
    expected = march(world, origin, dirs, 15.0)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.distance_m, expected, atol=1e-3)
    # Hit points lie on the boundary: just before is free, just after is occupied.
    before = hits.points_xy_m - 1e-4 * dirs
    after = hits.points_xy_m + 1e-4 * dirs
    assert world.is_free(before).all()
    assert not world.is_free(after).any()
    # The reported cell is occupied and its square contains the hit point.
    ix, iy = hits.cells_ixy.T
    assert world.occupied[iy, ix].all()
    lower = world.spec.centres_of(hits.cells_ixy) - 0.5 * world.spec.resolution_m
    offset = hits.points_xy_m - lower
    assert np.all((offset > -1e-9) & (offset < world.spec.resolution_m + 1e-9))


def test_misses_out_of_range_outside_grid_and_inside_a_wall():
    world = box_world(8.0, 6.0)
    world.occupied[30:35, -1] = False  # a doorway in the east wall to the outside
    spec: GridSpec = world.spec
    door_y = spec.centres_of(np.array([[0, 32]]))[0, 1]
    dirs = directions_from_angles(np.array([0.0, np.pi]))
    hits = cast_rays(world, np.array([4.0, door_y]), dirs, 3.0)
    assert not hits.hit.any() and np.isinf(hits.distance_m).all()
    assert (hits.face_axis == NO_FACE).all() and np.isnan(hits.points_xy_m).all()
    inside = cast_rays(world, np.array([-0.05, 3.0]), dirs, 3.0)
    assert inside.hit.all() and (inside.distance_m == 0.0).all()
