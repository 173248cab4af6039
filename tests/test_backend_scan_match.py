"""Scan matching's oriented normals: each point's surface normal, turned to the side it was
seen from, and matches only between points seen from the same side."""

import numpy as np
import pytest

from smokyslam.backends.scan_match import Scan, match_covariance, oriented_normals


def noisy_wall(rng: np.random.Generator, y: float) -> np.ndarray:
    """(N, 2) points every 5 cm along x in [0, 8] at height ``y``, with 3 cm noise."""
    x = np.arange(0.0, 8.0, 0.05)
    return np.column_stack([x, np.full_like(x, y)]) + rng.normal(0.0, 0.03, (len(x), 2))


def test_a_walls_normals_point_to_the_sensor_that_saw_it():
    rng = np.random.default_rng(0)
    wall = noisy_wall(rng, 2.0)
    for sensor_y, side in [(0.0, -1.0), (4.0, 1.0)]:
        origins = np.tile([4.0, sensor_y], (len(wall), 1))
        normals = oriented_normals(wall, origins, 1.0)
        assert np.all(np.abs(np.linalg.norm(normals, axis=1) - 1.0) < 1e-9)
        # Within 10 degrees of the wall's normal on the sensor's side, everywhere.
        assert np.all(side * normals[:, 1] > np.cos(np.radians(10.0)))


def test_scattered_points_and_unknown_origins_get_no_normal():
    rng = np.random.default_rng(1)
    clutter = rng.uniform(0.0, 4.0, (200, 2))
    origins = np.zeros_like(clutter)
    assert np.mean(np.abs(oriented_normals(clutter, origins, 1.0)).sum(axis=1) > 0) < 0.1
    wall = noisy_wall(rng, 2.0)
    assert not oriented_normals(wall, None, 1.0).any()
    assert not oriented_normals(wall, np.zeros_like(wall), None).any()


def test_points_match_only_points_seen_from_the_same_side():
    rng = np.random.default_rng(2)
    wall = noisy_wall(rng, 2.0)
    from_south = Scan(wall, np.tile([4.0, 0.0], (len(wall), 1)), 1.0)
    probe = np.array([[4.0, 2.05]])
    up, down = np.array([[0.0, 1.0]]), np.array([[0.0, -1.0]])
    distance, index = from_south.match(probe, down, 0.3)  # seen from the south too
    assert distance[0] < 0.1 and index[0] < len(wall)
    distance, index = from_south.match(probe, up, 0.3)  # the wall's other side
    assert np.isinf(distance[0]) and index[0] == len(wall)
    # A point without a normal, or a scan without normals, matches either side.
    assert from_south.match(probe, np.zeros((1, 2)), 0.3)[0][0] < 0.1
    assert Scan(wall).match(probe, up, 0.3)[0][0] < 0.1


def corridor(rng: np.random.Generator, end_walls: bool) -> tuple[np.ndarray, np.ndarray]:
    """(points, origins) (N, 2) of a corridor along x, walls at y = +-1 with 3 cm noise, seen
    from its centre line; with ``end_walls`` also walls across it at x = 0 and x = 8."""
    walls = [noisy_wall(rng, -1.0), noisy_wall(rng, 1.0)]
    origins = [np.column_stack([w[:, 0], np.zeros(len(w))]) for w in walls]
    if end_walls:
        y = np.arange(-1.0, 1.0, 0.05)
        for x, sensor_x in [(0.0, 1.0), (8.0, 7.0)]:
            walls.append(
                np.column_stack([np.full_like(y, x), y]) + rng.normal(0, 0.03, (len(y), 2))
            )
            origins.append(np.tile([sensor_x, 0.0], (len(y), 1)))
    return np.concatenate(walls), np.concatenate(origins)


def test_a_corridor_match_claims_little_along_the_corridor():
    rng = np.random.default_rng(3)
    sigmas = (0.35, 2.1)
    for end_walls in (False, True):
        points, origins = corridor(rng, end_walls)
        target = Scan(points, origins, 1.0)
        source = Scan(points + rng.normal(0.0, 0.03, points.shape), origins, 1.0)
        along, across = np.sqrt(
            np.diag(match_covariance(source, target, np.zeros(3), 0.3, sigmas))
        )[:2]
        if end_walls:  # the walls across the corridor fix the position along it
            assert along < 2.0 * across
        else:
            assert along > 20.0 * across
    # Without normals every matched point fixes both axes (point-to-point information): along
    # the corridor (where a turn moves no point) the sigma is one point's over sqrt(N).
    plain = match_covariance(Scan(points), Scan(points), np.zeros(3), 0.3, sigmas)
    assert np.sqrt(plain[0, 0]) == pytest.approx(2.1 / np.sqrt(len(points)), rel=0.01)
