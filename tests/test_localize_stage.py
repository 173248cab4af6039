"""The localizer stage of the run loop: radar frames wait for the camera's next frame, whose
metric step is fused with the radar's by their covariances; a silent camera is not waited for
longer than ``CAMERA_WAIT_S``."""

import collections

import numpy as np

from smokyslam.backends.camera_factors import CameraFactor
from smokyslam.localize.stage import CAMERA_WAIT_S, Localizer, LocalizeStart
from smokyslam.types import Odometry, OdometryHealth

RADAR_COV = np.diag([0.02, 0.02, 0.01]) ** 2


class FilterStub:
    """Records what the stage asks of the particle filter."""

    def __init__(self):
        self.steps, self.updates = [], 0
        self.particles, self.count = np.zeros((1, 3)), 1

    def start_tracking(self, pose, sigmas):
        self.pose = np.asarray(pose, dtype=float)

    def predict(self, delta, covariance):
        self.steps.append((np.asarray(delta), np.asarray(covariance)))

    def update(self, points_xy):
        self.updates += 1

    def estimate(self):
        return np.zeros(3), np.eye(3)


class CameraStub:
    """A camera whose results are their stamps (``add_camera(0.1)``), and whose metric step is
    ``delta`` with ``covariance`` for every pair (None: it disagrees with the radar)."""

    def __init__(self, delta, covariance):
        self.latest_stamp_s = -np.inf
        self.delta, self.covariance = delta, covariance
        self.outcomes = collections.Counter()
        self.pairs = []

    def add(self, stamp_s):
        self.latest_stamp_s = stamp_s

    def factor(self, stamp_a_s, stamp_b_s, radar_delta, radar_covariance):
        self.pairs.append((stamp_a_s, stamp_b_s))
        if self.delta is None:
            return None
        return CameraFactor(np.asarray(self.delta), np.asarray(self.covariance), 1.0)


def radar_frame(stamp_s, step=(0.1, 0.0, 0.0)):
    health = OdometryHealth(inliers=30, fitness=0.01, lost=False)
    return Odometry(stamp_s, np.zeros(3), np.asarray(step, dtype=float), RADAR_COV, health)


def localizer(camera):
    start = LocalizeStart(np.zeros(3), np.array([0.1, 0.1, 0.1]))
    return Localizer(FilterStub(), np.zeros(3), start, camera)


def test_a_radar_frame_waits_for_the_camera_and_takes_its_step():
    camera = CameraStub([0.2, 0.0, 0.0], RADAR_COV / 4)  # four times the radar's information
    stage = localizer(camera)
    stage.localize(radar_frame(0.0), np.zeros((5, 2)))  # the first frame places the particles
    stage.localize(radar_frame(0.1), np.zeros((5, 2)))
    assert stage.track.stamps_s == [0.0] and stage.mcl.steps == []  # waiting for the camera
    stage.add_camera(0.05)
    assert stage.track.stamps_s == [0.0]  # the camera has not passed the frame yet
    stage.add_camera(0.12)
    assert stage.track.stamps_s == [0.0, 0.1] and camera.pairs == [(0.0, 0.1)]
    ((step, covariance),) = stage.mcl.steps
    # Information-weighted: 0.1 m (radar) and 0.2 m (camera, 4x the information) -> 0.18 m.
    np.testing.assert_allclose(step, [0.18, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(covariance, RADAR_COV / 5, atol=1e-12)


def test_a_camera_that_disagrees_leaves_the_radar_step():
    camera = CameraStub(None, None)
    stage = localizer(camera)
    stage.localize(radar_frame(0.0), np.zeros((5, 2)))
    stage.add_camera(0.15)
    stage.localize(radar_frame(0.1), np.zeros((5, 2)))
    ((step, covariance),) = stage.mcl.steps
    np.testing.assert_allclose(step, [0.1, 0.0, 0.0])
    np.testing.assert_allclose(covariance, RADAR_COV)


def test_a_silent_camera_is_not_waited_for_and_the_end_filters_every_frame():
    camera = CameraStub([0.2, 0.0, 0.0], RADAR_COV)
    stage = localizer(camera)
    stamps = 0.15 * np.arange(10)  # to 1.35 s
    for stamp_s in stamps:
        stage.localize(radar_frame(stamp_s), np.zeros((5, 2)))
    # The camera never came: a frame goes ahead once a later one is CAMERA_WAIT_S (0.5 s)
    # younger, so those from 0.9 s on still wait.
    assert CAMERA_WAIT_S == 0.5
    np.testing.assert_allclose(stage.track.stamps_s, stamps[:6])
    assert camera.pairs == [] and camera.outcomes["untracked"] == 5  # 0.15-0.75 s
    stage.flush()
    np.testing.assert_allclose(stage.track.stamps_s, stamps)
    assert all(np.allclose(step, [0.1, 0.0, 0.0]) for step, _ in stage.mcl.steps)
    assert stage.mcl.updates == len(stamps)


def test_without_a_camera_every_frame_is_filtered_at_once():
    stage = localizer(None)
    for stamp_s in (0.0, 0.1, 0.2):
        stage.localize(radar_frame(stamp_s), np.zeros((5, 2)))
        assert stage.track.stamps_s[-1] == stamp_s
