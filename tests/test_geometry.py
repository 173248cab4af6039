"""The geometry module: every frame and quaternion conversion goes through here."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from smokyslam import geometry as g

poses = st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-np.pi, np.pi - 1e-9)).map(
    np.array
)


@given(poses, poses)
def test_se2_compose_matches_matrices(a, b):
    expected = g.se2_from_matrix(g.se2_matrix(*a) @ g.se2_matrix(*b))
    np.testing.assert_allclose(g.se2_compose(a, b), expected, atol=1e-9)


@given(poses)
def test_se2_inverse_composes_to_identity(a):
    np.testing.assert_allclose(g.se2_compose(a, g.se2_inverse(a)), [0, 0, 0], atol=1e-9)


def test_se2_between_is_relative_pose():
    a = np.array([1.0, 2.0, np.pi / 2])
    b = np.array([1.0, 3.0, np.pi])
    # b sits 1 m ahead of a (a faces +y) and is turned 90 degrees left.
    np.testing.assert_allclose(g.se2_between(a, b), [1.0, 0.0, np.pi / 2], atol=1e-12)


def test_transform_points_2d_rotates_then_translates():
    pose = np.array([10.0, 0.0, np.pi / 2])
    out = g.transform_points_2d(pose, np.array([[1.0, 0.0], [0.0, 2.0]]))
    np.testing.assert_allclose(out, [[10.0, 1.0], [8.0, 0.0]], atol=1e-12)


def test_quaternion_order_round_trip_and_yaw():
    q_wxyz = g.quat_wxyz_from_yaw(0.7)
    np.testing.assert_allclose(g.quat_xyzw_from_wxyz(q_wxyz), [0, 0, np.sin(0.35), np.cos(0.35)])
    np.testing.assert_allclose(g.quat_wxyz_from_xyzw(g.quat_xyzw_from_wxyz(q_wxyz)), q_wxyz)
    assert g.yaw_from_quat_wxyz(q_wxyz) == pytest.approx(0.7)
    R = g.rotation_matrix_from_quat_wxyz(q_wxyz)
    np.testing.assert_allclose(R[:2, :2], g.se2_matrix(0, 0, 0.7)[:2, :2], atol=1e-12)
    np.testing.assert_allclose(g.quat_wxyz_from_rotation_matrix(R), q_wxyz, atol=1e-12)


def test_interpolate_se2_takes_short_way_round_the_circle():
    stamps = np.array([0.0, 1.0])
    poses = np.array([[0.0, 0.0, np.pi - 0.1], [2.0, 0.0, -np.pi + 0.1]])
    mid = g.interpolate_se2(stamps, poses, 0.5)
    assert mid[0] == pytest.approx(1.0)
    assert abs(g.wrap_angle(mid[2] - np.pi)) == pytest.approx(0.0, abs=1e-9)


def test_optical_rotation_maps_camera_forward_to_body_forward():
    np.testing.assert_allclose(g.R_BODY_OPTICAL @ [0, 0, 1], [1, 0, 0])  # z fwd -> x fwd
    np.testing.assert_allclose(g.R_BODY_OPTICAL @ [1, 0, 0], [0, -1, 0])  # x right -> -y (right)
    np.testing.assert_allclose(g.R_BODY_OPTICAL @ [0, 1, 0], [0, 0, -1])  # y down -> -z


def test_se3_inverse():
    T = g.se3_matrix([1.0, 2.0, 3.0], g.quat_wxyz_from_yaw(0.3))
    np.testing.assert_allclose(g.se3_inverse(T) @ T, np.eye(4), atol=1e-12)


def test_grid_spec_cells_and_centres_round_trip():
    spec = g.GridSpec(origin_xy_m=(-1.0, 2.0), resolution_m=0.1, shape=(30, 40))
    cells = spec.cells_of(np.array([[-1.0, 2.0], [-0.95, 2.05], [2.99, 4.99], [3.0, 5.0]]))
    np.testing.assert_array_equal(cells, [[0, 0], [0, 0], [39, 29], [40, 30]])
    np.testing.assert_array_equal(spec.inside(cells), [True, True, True, False])
    np.testing.assert_allclose(spec.centres_of(np.array([[0, 0]])), [[-0.95, 2.05]])
    assert spec.extent_m == pytest.approx((-1.0, 3.0, 2.0, 5.0))


@given(st.floats(-np.pi, np.pi))
def test_rotation_2d_is_the_rotation_block_of_se2_matrix(yaw):
    np.testing.assert_allclose(g.rotation_2d(yaw), g.se2_matrix(0.0, 0.0, yaw)[:2, :2])


def test_covering_grid_keeps_the_lattice_and_spans_both():
    spec = g.GridSpec((0.0, 0.0), 0.1, (10, 20))
    # Off the lattice and finer: the covering grid stays on spec's lattice and resolution.
    other = g.GridSpec((-0.33, 0.52), 0.05, (40, 10))
    cover = spec.covering(other)
    assert cover.resolution_m == 0.1
    assert cover.origin_xy_m == pytest.approx((-0.4, 0.0))
    x0, x1, y0, y1 = cover.extent_m
    assert x0 <= -0.33 and x1 >= 2.0 - 1e-9 and y0 <= 0.0 and y1 >= 2.52 - 1e-9
    assert cover.shape == (26, 24)
    assert spec.covering(spec) == spec


def test_se2_fuse_weighs_two_estimates_by_their_covariances():
    from smokyslam.geometry import se2_fuse

    a, b = np.array([1.0, 0.0, 0.1]), np.array([1.2, 0.1, 0.14])
    cov = np.diag([0.01, 0.01, 0.001])
    fused, fused_cov = se2_fuse(a, cov, b, cov)
    # Equal covariances: halfway (up to the curvature of SE(2) over this small difference),
    # and half the covariance.
    np.testing.assert_allclose(fused, [1.1, 0.05, 0.12], atol=5e-3)
    np.testing.assert_allclose(fused_cov, cov / 2, atol=1e-12)
    # A much more certain b wins; only the certain axis moves when one axis alone is certain.
    np.testing.assert_allclose(se2_fuse(a, cov, b, cov * 1e-6)[0], b, atol=1e-4)
    a, b = np.array([1.0, 0.0, 0.0]), np.array([1.2, 0.1, 0.04])  # a's axes are the world's
    fused_x, _ = se2_fuse(a, cov, b, np.diag([1e-8, 1.0, 1.0]))  # b knows x only
    np.testing.assert_allclose(fused_x, [1.2, 0.0, 0.0], atol=0.005)


def test_se2_fuse_averages_headings_across_the_wrap():
    from smokyslam.geometry import se2_fuse

    cov = np.diag([0.01, 0.01, 0.01])
    a, b = np.array([0.0, 0.0, np.pi - 0.02]), np.array([0.0, 0.0, -np.pi + 0.02])
    fused, _ = se2_fuse(a, cov, b, cov)
    assert abs(abs(fused[2]) - np.pi) < 1e-9  # not 0, the naive mean of the two numbers


def test_line_fit_2d_finds_the_normal_and_spreads_and_leaves_out_zero_weights():
    x = np.linspace(-1.0, 1.0, 21)
    line = np.column_stack([x, 0.5 * x + 2.0])  # a line at atan(0.5) through (0, 2)
    outlier = np.array([[0.0, 9.0]])
    sets = np.stack([np.vstack([line, outlier])] * 2)  # (2, 22, 2)
    weights = np.ones((2, 22))
    weights[1, -1] = 0.0  # the second set leaves the outlier out
    centroid, normal, across, along = g.line_fit_2d(sets, weights)
    expected = np.array([-np.sin(np.arctan(0.5)), np.cos(np.arctan(0.5))])
    np.testing.assert_allclose(np.abs(normal[1] @ expected), 1.0, atol=1e-12)
    np.testing.assert_allclose(centroid[1], [0.0, 2.0], atol=1e-12)
    assert across[1] < 1e-12
    # Along the line: the summed squared distance from the centroid, 21 points to +-1 m.
    np.testing.assert_allclose(along[1], np.sum(x**2) * 1.25, rtol=1e-12)
    assert across[0] > 1.0  # the outlier 7 m off the line spreads the first set across it
    np.testing.assert_allclose(g.line_fit_2d(sets[:1])[2], across[:1])
