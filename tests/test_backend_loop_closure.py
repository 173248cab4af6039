"""Loop closures: 2D ICP recovers relative poses; the closer finds revisits and refuses
recent keyframes, wrong places and large corrections."""

import numpy as np

from smokyslam.backends.loop_closure import JOINED_CACHE_SIZE, get_loop_closer
from smokyslam.backends.scan_match import Scan, icp_2d
from smokyslam.config import LoopClosureConfig, SlamConfig
from smokyslam.geometry import se2_between, se2_compose, se2_inverse, transform_points_2d

SUBMAP_RANGE_M = 6.0
VOXEL_M = SlamConfig().submap_voxel_m
"""The run's submap thinning, which joined loop-closure targets share."""


def world_points(seed: int = 0) -> np.ndarray:
    """(N, 2) points every 5 cm on the walls of a 20 x 10 m floor with two rooms and pillars."""
    rng = np.random.default_rng(seed)
    segments = [
        ((0, 0), (20, 0)),
        ((20, 0), (20, 10)),
        ((20, 10), (0, 10)),
        ((0, 10), (0, 0)),
        ((10, 0), (10, 2.5)),  # the dividing wall has a doorway at y 2.5-4.5
        ((10, 4.5), (10, 10)),
        ((0, 6), (4, 6)),
        ((14, 7), (17, 7)),
    ]
    for cx, cy in rng.uniform([1, 1], [19, 9], size=(8, 2)):
        s = rng.uniform(0.2, 0.5)
        corners = [(cx - s, cy - s), (cx + s, cy - s), (cx + s, cy + s), (cx - s, cy + s)]
        segments += [(corners[k], corners[(k + 1) % 4]) for k in range(4)]
    points = []
    for a, b in segments:
        a, b = np.array(a, float), np.array(b, float)
        n = max(int(np.linalg.norm(b - a) / 0.05), 2)
        points.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return np.concatenate(points)


WORLD = world_points()


def submap(pose: np.ndarray, rng: np.random.Generator, count: int = 300) -> np.ndarray:
    """(count, 2) wall points within range of ``pose``, in its frame, with 3 cm noise."""
    near = WORLD[np.linalg.norm(WORLD - pose[:2], axis=1) < SUBMAP_RANGE_M]
    near = near[rng.choice(len(near), size=min(count, len(near)), replace=False)]
    local = transform_points_2d(se2_inverse(pose), near)
    return local + rng.normal(0.0, 0.03, local.shape)


def test_icp_recovers_the_relative_pose_from_a_rough_guess():
    rng = np.random.default_rng(1)
    target_pose, source_pose = np.array([5.0, 3.0, 0.3]), np.array([6.0, 3.6, -0.2])
    truth = se2_between(target_pose, source_pose)
    guess = se2_compose(truth, [0.4, -0.3, 0.15])
    target = Scan(submap(target_pose, rng, count=600))
    result = icp_2d(Scan(submap(source_pose, rng)), target, guess)
    error = se2_between(truth, result.delta)
    assert np.hypot(error[0], error[1]) < 0.02
    assert abs(error[2]) < 0.005
    assert result.inlier_fraction > 0.9
    # Noise on both sides (3 cm each) plus the gaps between sampled target points.
    assert 0.04 < result.rms_m < 0.12


def out_and_back() -> np.ndarray:
    """60 keyframes: 30 east along y = 3 from x = 2, then 30 back west along y = 3.3."""
    east = np.stack([2.0 + 0.4 * np.arange(30), np.full(30, 3.0), np.zeros(30)], axis=1)
    west = np.stack([13.6 - 0.4 * np.arange(30), np.full(30, 3.3), np.full(30, np.pi)], axis=1)
    return np.concatenate([east, west])


def drifted(truth: np.ndarray) -> np.ndarray:
    """Odometry-like estimates: each step picks up 1 cm of lateral and 2 mrad of heading error."""
    estimate = [truth[0]]
    for k in range(1, len(truth)):
        step = se2_compose(se2_between(truth[k - 1], truth[k]), [0.0, 0.01, 0.002])
        estimate.append(se2_compose(estimate[-1], step))
    return np.array(estimate)


def test_closer_finds_revisits_with_accurate_relative_poses():
    rng = np.random.default_rng(2)
    truth = out_and_back()
    estimate = drifted(truth)
    closer = get_loop_closer(LoopClosureConfig(min_index_gap=20, min_spacing=3), VOXEL_M)
    closures = []
    for k in range(len(truth)):
        found = closer.check(k, estimate[: k + 1], submap(truth[k], rng))
        if found is not None:
            closures.append(found)
    assert len(closures) >= 6
    outcomes = closer.outcomes
    assert outcomes["accepted"] == len(closures)
    refused = sum(outcomes[k] for k in ("overcorrected", "few_inliers", "high_rms"))
    assert outcomes["candidates"] >= refused + len(closures)
    assert all(c.new_index - c.old_index >= 20 for c in closures)
    assert np.all(np.diff([c.new_index for c in closures]) >= 3)
    for closure in closures:
        error = se2_between(
            se2_between(truth[closure.old_index], truth[closure.new_index]), closure.delta
        )
        # Measured over seeds 0-7: at most 3.1 cm and 5 mrad from a 0.65 m / 0.12 rad guess.
        assert np.hypot(error[0], error[1]) < 0.04
        assert abs(error[2]) < 0.01
        floor = np.array(LoopClosureConfig().floor_sigmas)
        assert np.all(np.sqrt(np.diag(closure.covariance)) >= floor * 0.999)


def test_closer_refuses_recent_far_wrong_and_overcorrected_matches():
    rng = np.random.default_rng(3)
    truth = out_and_back()
    closer = get_loop_closer(LoopClosureConfig(min_index_gap=30), VOXEL_M)
    old = truth[0]
    closer.check(0, truth[:1], submap(old, rng))
    # Too recent: the same place again one keyframe later.
    assert closer.check(1, np.array([old, old]), submap(old, rng)) is None
    assert closer.outcomes["searches"] == 0
    poses = np.array([old] * 40)
    # The estimate says "back at keyframe 0" but the rig is in the other room.
    other_room = np.array([15.0, 5.0, 1.0])
    assert closer.check(39, poses, submap(other_room, rng)) is None
    # Both stored keyframes were candidates; the other room's walls do not line up with theirs.
    assert closer.outcomes == {"searches": 1, "candidates": 2, "few_inliers": 2}
    # Far from every old keyframe: not even tried.
    poses[39] = [12.0, 8.0, 0.0]
    assert closer.check(39, poses, submap(poses[39], rng)) is None
    assert closer.outcomes == {"searches": 2, "candidates": 2, "few_inliers": 2}
    # A right match that needs a larger correction than allowed.
    strict = get_loop_closer(LoopClosureConfig(min_index_gap=30, max_correction_m=0.1), VOXEL_M)
    strict.check(0, truth[:1], submap(old, rng))
    poses = np.array([old] * 40)
    actual = se2_compose(old, [0.4, 0.2, 0.0])
    assert strict.check(39, poses, submap(actual, rng)) is None
    assert strict.outcomes["overcorrected"] == 1
    relaxed = get_loop_closer(LoopClosureConfig(min_index_gap=30, max_correction_m=1.0), VOXEL_M)
    relaxed.check(0, truth[:1], submap(old, rng))
    found = relaxed.check(39, poses, submap(actual, rng))
    assert found is not None
    assert relaxed.outcomes == {"searches": 1, "candidates": 1, "accepted": 1}
    np.testing.assert_allclose(found.delta, [0.4, 0.2, 0.0], atol=0.05)


def test_a_near_closure_needs_less_overlap_than_a_far_one():
    """Half of the new submap is clutter the old one never saw (an inlier fraction near 0.5):
    with the estimate 5 cm off it is a near closure and is taken; the same scans with the
    estimate 0.5 m off need the full ``min_inlier_fraction`` and are refused. Measured on the
    ICP attempts of 30 simulated 120 s runs at inlier fractions 0.45-0.6: near ones (shift at
    most 0.2 m) were right (within 0.15 m and 2.5 deg) 231 times and wrong (beyond 0.3 m or
    5 deg) never; far ones 18 times right and 95 times wrong."""
    rng = np.random.default_rng(5)
    old = np.array([5.0, 3.0, 0.3])
    walls = submap(old, rng, count=300)
    clutter = rng.uniform(-6.0, 6.0, (300, 2))
    for offset, taken in [([0.05, 0.0, 0.0], True), ([0.5, 0.0, 0.0], False)]:
        closer = get_loop_closer(LoopClosureConfig(min_index_gap=30), VOXEL_M)
        closer.check(0, old[None], submap(old, rng, count=600))
        poses = np.array([old] * 40)
        poses[39] = se2_compose(old, offset)
        closure = closer.check(39, poses, np.concatenate([walls, clutter]))
        assert (closure is not None) is taken
        assert closer.outcomes["accepted" if taken else "few_inliers"] == 1
        if taken:
            np.testing.assert_allclose(closure.delta, [0.0, 0.0, 0.0], atol=0.05)


def aisle_points() -> np.ndarray:
    """(N, 2) points every 5 cm on a 40 m aisle between two walls 3 m apart, lined on each
    side by 0.2 m square rack posts every metre: the same view repeats every metre."""
    x = np.arange(0.0, 40.0, 0.05)
    walls = [np.column_stack([x, np.full_like(x, y)]) for y in (0.0, 3.0)]
    edge = np.arange(-0.1, 0.1, 0.05)
    square = np.concatenate(
        [np.column_stack([edge, np.full_like(edge, side)]) for side in (-0.1, 0.1)]
        + [np.column_stack([np.full_like(edge, side), edge]) for side in (-0.1, 0.1)]
    )
    posts = [square + np.array([x0, y]) for x0 in np.arange(0.5, 40.0, 1.0) for y in (0.8, 2.2)]
    return np.concatenate(walls + posts)


def test_a_far_match_onto_a_repeating_copy_is_dropped():
    """The estimate has drifted 0.6 m along an aisle whose view repeats every metre: ICP from
    it settles on the copy 1 m from the truth. Restarted around that match, ICP finds the
    truth fitting as well, so the closure is dropped; with the rival search off it is taken,
    1 m wrong. The same drift in the two-room floor, with no copy, is corrected."""
    rng = np.random.default_rng(6)
    aisle = aisle_points()

    def aisle_submap(pose: np.ndarray) -> np.ndarray:
        near = aisle[np.linalg.norm(aisle - pose[:2], axis=1) < SUBMAP_RANGE_M]
        local = transform_points_2d(se2_inverse(pose), near)
        return local + rng.normal(0.0, 0.03, local.shape)

    old = np.array([20.0, 1.5, 0.0])
    poses = np.array([old] * 40)
    poses[39] = se2_compose(old, [0.6, 0.0, 0.0])
    for radii, taken in [((), True), ((0.5, 1.0), False)]:
        closer = get_loop_closer(LoopClosureConfig(min_index_gap=30, rival_radii_m=radii), VOXEL_M)
        closer.check(0, old[None], aisle_submap(old))
        closure = closer.check(39, poses, aisle_submap(old))
        assert (closure is not None) is taken
        assert closer.outcomes["rival"] == (0 if taken else 1)
        if taken:  # the slid copy: a metre off the truth (the same place)
            assert abs(abs(closure.delta[0]) - 1.0) < 0.05
    closer = get_loop_closer(LoopClosureConfig(min_index_gap=30), VOXEL_M)
    old = np.array([5.0, 3.0, 0.3])
    closer.check(0, old[None], submap(old, rng, count=600))
    poses = np.array([old] * 40)
    poses[39] = se2_compose(old, [0.6, 0.0, 0.0])
    closure = closer.check(39, poses, submap(old, rng))
    assert closure is not None
    np.testing.assert_allclose(closure.delta, [0.0, 0.0, 0.0], atol=0.05)


def test_a_match_of_a_racks_two_faces_is_refused():
    """A rack 1 m deep, seen once from the aisle south of it and once from the aisle north of
    it, with the estimate 1 m south of the truth: the north face then lies on the south face,
    and the end wall both aisles see holds the rest, so without normals ICP takes that match,
    a metre wrong. With oriented normals the two faces point apart and do not correspond, so
    no closure is made. Simulated warehouses showed this: every closure there more than
    0.3 m wrong laid one side of the racks onto the other."""
    rng = np.random.default_rng(7)

    def wall(a, b):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(int(np.linalg.norm(b - a) / 0.05), 2)
        return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)

    end_wall = wall((11.0, -3.0), (11.0, 4.5))
    south_view = np.concatenate([wall((0, 0), (10, 0)), wall((0, -2.5), (10, -2.5)), end_wall])
    north_view = np.concatenate([wall((0, 1), (10, 1)), wall((0, 3.5), (10, 3.5)), end_wall])
    south, north = np.array([6.0, -1.25, 0.0]), np.array([6.0, 2.25, 0.0])

    def seen_from(pose, points):
        local = transform_points_2d(se2_inverse(pose), points)
        local = local + rng.normal(0.0, 0.03, local.shape)
        return local, np.zeros_like(local)  # every point seen from the keyframe's origin

    poses = np.array([south] * 40)
    poses[39] = north - [0.0, 1.0, 0.0]  # odometry drifted a metre south
    for normal_radius_m, taken in [(None, True), (1.0, False)]:
        config = LoopClosureConfig(min_index_gap=30, normal_radius_m=normal_radius_m)
        closer = get_loop_closer(config, VOXEL_M)
        closer.check(0, south[None], *seen_from(south, south_view))
        closure = closer.check(39, poses, *seen_from(north, north_view))
        assert (closure is not None) is taken
        assert closer.outcomes["accepted" if taken else "few_inliers"] == 1
        if taken:  # the faces laid onto each other: a metre south of the truth
            error = se2_between(se2_between(south, north), closure.delta)
            assert abs(error[1] + 1.0) < 0.1


def test_a_small_old_submap_is_matched_joined_with_its_neighbours():
    """Old submaps that each saw only 4 m around a pass east, every 1.5 m, and a new one that
    saw 8 m around the way back west: no single old submap holds the 0.35 of the new points a
    near closure needs (0.17-0.26 here), so with ``target_neighbours`` 0 there is no closure.
    Joined with two stored neighbours on each side the old keyframe's target holds about half
    of them, and the closure is made and accurate (over seeds 0-7 at most 2.1 cm and 0.15 deg
    from the truth, from a guess 11 cm and 1.1 deg off)."""
    east = np.stack([2.0 + 1.5 * np.arange(10), np.full(10, 3.0), np.zeros(10)], axis=1)
    back = np.array([8.3, 3.3, np.pi - 0.1])
    poses = np.vstack([east, se2_compose(back, [0.1, 0.05, 0.02])])

    def seen(pose: np.ndarray, radius_m: float, count: int) -> np.ndarray:
        near = WORLD[np.linalg.norm(WORLD - pose[:2], axis=1) < radius_m]
        near = near[rng.choice(len(near), size=min(count, len(near)), replace=False)]
        local = transform_points_2d(se2_inverse(pose), near)
        return local + rng.normal(0.0, 0.03, local.shape)

    for neighbours in (0, 2):
        rng = np.random.default_rng(8)
        config = LoopClosureConfig(min_index_gap=5, target_neighbours=neighbours)
        closer = get_loop_closer(config, VOXEL_M)
        for k, pose in enumerate(east):
            assert closer.check(k, east[: k + 1], seen(pose, 4.0, 200)) is None
        closure = closer.check(10, poses, seen(back, 8.0, 500))
        assert (closure is not None) is (neighbours > 0)
        if closure is not None:
            error = se2_between(se2_between(east[closure.old_index], back), closure.delta)
            assert np.hypot(error[0], error[1]) < 0.04
            assert abs(error[2]) < np.radians(0.5)
            assert closure.inlier_fraction > 0.4


def test_a_joined_target_follows_its_submaps_placements():
    """The joined target is kept while its submaps' placements hold (within 1 cm) and built
    again once the estimate moves one of them (here by 0.5 m after, say, a loop closure)."""
    rng = np.random.default_rng(9)
    east = np.stack([2.0 + 1.5 * np.arange(5), np.full(5, 3.0), np.zeros(5)], axis=1)
    closer = get_loop_closer(LoopClosureConfig(min_index_gap=1, target_neighbours=2), VOXEL_M)
    for k, pose in enumerate(east):
        closer.check(k, east[: k + 1], submap(pose, rng))
    old = np.arange(5)
    first = closer._joined(2, old, east)
    nudged = east.copy()
    nudged[4, 0] += 0.005
    assert closer._joined(2, old, nudged) is first
    moved = east.copy()
    moved[4, 1] += 0.5
    again = closer._joined(2, old, moved)
    assert again is not first
    # The old keyframe's own points are where they were; keyframe 4's moved with it.
    assert len(again.xy) >= len(first.xy)
    shift = again.tree.query(first.xy)[0]
    assert np.median(shift) < 0.01 and np.percentile(shift, 95) > 0.1


def test_a_joined_target_survives_a_heading_across_the_half_turn_and_the_cache_is_bounded():
    """A placement whose heading crosses +-180 deg (a 0.06 deg move) is the same placement;
    the cache keeps only the most recently used joined targets."""
    rng = np.random.default_rng(10)
    count = JOINED_CACHE_SIZE + 8
    line = np.stack([2.0 + 0.4 * np.arange(count), np.full(count, 3.0), np.zeros(count)], axis=1)
    line[4, 2] = np.pi - 0.0005
    closer = get_loop_closer(LoopClosureConfig(min_index_gap=1, target_neighbours=2), VOXEL_M)
    for k, pose in enumerate(line):
        closer.check(k, line[: k + 1], submap(pose, rng))
    old = np.arange(count)
    first = closer._joined(2, old, line)
    across = line.copy()
    across[4, 2] = -np.pi + 0.0005
    assert closer._joined(2, old, across) is first
    for k in range(count):
        closer._joined(k, old, line)
    assert list(closer._joined_cache) == list(range(count - JOINED_CACHE_SIZE, count))
    assert closer._joined(count - 1, old, line) is closer._joined(count - 1, old, line)


def test_a_near_closure_may_be_noisier_than_a_far_one():
    """Long-range radar points are noisy: here the new submap's walls are 20 cm off (inlier
    RMS about 0.13 m). With the estimate 5 cm off the match is near and is taken under
    ``near_max_rms_m`` (0.15 m); with the same scans 0.5 m off it is far, and a far match must
    keep ``max_rms_m`` (0.12 m): one that moves the estimate on noisy evidence is as often an
    aisle slid along as a real correction."""
    old = np.array([5.0, 3.0, 0.3])
    for offset, near_max_rms_m, outcome in [
        (0.05, 0.15, "accepted"),
        (0.5, 0.15, "high_rms"),
        (0.05, 0.12, "high_rms"),
    ]:
        rng = np.random.default_rng(7)
        config = LoopClosureConfig(min_index_gap=30, near_max_rms_m=near_max_rms_m)
        closer = get_loop_closer(config, VOXEL_M)
        closer.check(0, old[None], submap(old, rng, count=600))
        poses = np.array([old] * 40)
        poses[39] = se2_compose(old, [offset, 0.0, 0.0])
        noisy = submap(old, rng)
        closure = closer.check(39, poses, noisy + rng.normal(0.0, 0.2, noisy.shape))
        assert closer.outcomes[outcome] == 1
        if closure is not None:
            assert 0.12 < closure.rms_m < 0.15
            np.testing.assert_allclose(closure.delta, [0.0, 0.0, 0.0], atol=0.05)
