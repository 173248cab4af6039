"""The Rerun recorder: fed by hand, read back with rerun's own reader; the viewer command."""

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from smokyslam.backends.slam import SlamStatus
from smokyslam.config import RecordingConfig
from smokyslam.errors import ViewerError
from smokyslam.frontends.camera.preprocess import ImageQuality
from smokyslam.frontends.camera.result import (
    CameraHealth,
    CameraOdometryResult,
    CameraView,
    TrackingStatus,
)
from smokyslam.geometry import GridSpec
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthTrajectory,
    RadarScan,
)
from smokyslam.viz.recorder import (
    FrameRecord,
    NullRecorder,
    RecordingSetup,
    RunSnapshot,
    open_recorder,
)
from smokyslam.viz.viewer import find_recording


@pytest.fixture(autouse=True)
def _no_rerun_files_in_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))


def rows_per_entity(path) -> dict[str, int]:
    """Rows per entity path of a recording's data (blueprint excluded), read by rerun."""
    import rerun.chunk

    rows: dict[str, int] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for chunk in rerun.chunk.RrdReader(path).stream():
            rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    return rows


def has_blueprint(path) -> bool:
    import rerun.chunk

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return len(rerun.chunk.RrdReader(path).blueprints()) > 0


def camera_result(stamp_s: float, lost: bool = False) -> CameraOdometryResult:
    image = np.full((24, 32), 90, dtype=np.uint8)
    features = np.array([[5.0, 5.0], [20.0, 10.0]])
    return CameraOdometryResult(
        stamp_s=stamp_s,
        status=TrackingStatus.LOST if lost else TrackingStatus.TRACKING,
        pose_world_camera=np.zeros(3),
        T_world_camera=np.eye(4),
        keyframe_id=0,
        relative_pose=np.zeros(3),
        covariance=np.eye(3),
        health=CameraHealth(tracked=2),
        quality=ImageQuality(0.2, 0.15, 0.1, 3, False),
        is_keyframe=False,
        reinitialized=False,
        reinitializations=0,
        landmarks_world=np.zeros((0, 3)),
        view=CameraView(image, image, features, np.array([True, False])),
    )


def test_a_recording_made_as_the_run_goes_reads_back(tmp_path):
    cells = np.zeros((20, 30), dtype=np.int8)
    cells[0, :] = 100
    spec = GridSpec((0.0, 0.0), 0.1, cells.shape)
    stamps = np.arange(5) * 0.1
    poses = np.column_stack([stamps, np.zeros(5), np.zeros(5)])
    truth = GroundTruthTrajectory(stamps, poses + np.array([0.0, 0.05, 0.0]))
    config = RecordingConfig(path_period_s=0.2, maps_period_s=10.0)
    recorder = open_recorder(tmp_path / "run.rrd", config)
    recorder.start(
        RecordingSetup(
            "radar",
            Extrinsics(),
            CameraIntrinsics(32, 24, 30.0, 30.0, 16.0, 12.0),
            lambda s: np.asarray(s) + 1.7e9,
            truth,
            GroundTruthMap(0.0, cells, spec),
        )
    )
    snapshots = 0
    for i, (stamp_s, pose) in enumerate(zip(stamps, poses, strict=True)):
        scan = RadarScan(stamp_s, np.array([[2.0, 0.0, 0.0]]), np.ones(1), np.array([0.5]))
        recorder.log_frame(FrameRecord(i, stamp_s, pose, scan, SlamStatus(inliers=10)))
        recorder.log_camera(camera_result(stamp_s + 0.05), 0.6)
        if due := recorder.due(stamp_s):
            maps = {"radar_sparse": (cells, spec)} if due.maps else {}
            recorder.log_snapshot(RunSnapshot(stamp_s, poses[: i + 1], poses[:1], [], maps))
            snapshots += 1
    recorder.log_snapshot(
        RunSnapshot(0.4, poses, poses[:2], [(0, 1)], {"radar_sparse": (cells, spec)})
    )
    recorder.log_result(np.array([1.0, 2.0, 0.5]), stamps, poses)
    recorder.close()
    rows = rows_per_entity(tmp_path / "run.rrd")
    assert snapshots == 3  # at 0, 0.2 and 0.4 s: every path_period_s of sensor time
    assert rows["/world/map/rig"] == 5 and rows["/world/map/rig/radar/points"] == 5
    assert rows["/world/map/rig/camera/image"] == 5 + 1  # the pinhole, then one per frame
    assert rows["/camera/clean"] == 5 and rows["/camera/clean/features"] == 5
    assert rows["/world/map/trajectory/radar"] == snapshots + 1 + 1  # and the final path
    assert rows["/world/map/maps/radar_sparse"] == 1
    assert rows["/world/map/loop_closures"] == 1
    assert rows["/error/radar/position_m"] == 5 and rows["/trust/t"] == 5
    for entity in ("/world/ground_truth/map", "/world/ground_truth/path", "/world/map/rig/radar"):
        assert entity in rows
    assert has_blueprint(tmp_path / "run.rrd")


def test_the_error_so_far_is_the_distance_from_the_anchored_truth():
    from smokyslam.viz.truth_anchor import TruthAnchor

    stamps = np.array([0.0, 1.0, 2.0])
    truth = GroundTruthTrajectory(
        stamps, np.array([[5.0, 5.0, np.pi / 2], [5.0, 6.0, np.pi / 2], [5.0, 7.0, np.pi / 2]])
    )
    anchor = TruthAnchor(truth)
    T = anchor.start(0.0)
    assert T[:3, 3] == pytest.approx([5.0, 5.0, 0.0])
    # One metre forward in the map frame is one metre north in the world: no error.
    assert anchor.error_m(1.0, np.array([1.0, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-9)
    assert anchor.error_m(1.5, np.array([1.5, 0.3, 0.0])) == pytest.approx(0.3)
    assert np.isnan(anchor.error_m(3.0, np.zeros(3)))


def test_no_path_and_no_viewer_means_the_null_recorder():
    recorder = open_recorder(None, RecordingConfig())
    assert isinstance(recorder, NullRecorder) and not recorder.due(1e9)


def test_finding_a_folder_recording(tmp_path):
    with pytest.raises(ViewerError, match="no recording in this folder"):
        find_recording(tmp_path)
    (tmp_path / "other.rrd").write_bytes(b"")
    assert find_recording(tmp_path) == tmp_path / "other.rrd"
    (tmp_path / "run.rrd").write_bytes(b"")
    assert find_recording(tmp_path) == tmp_path / "run.rrd"
    with pytest.raises(ViewerError, match="not a Rerun recording"):
        find_recording(__file__)


def test_view_without_a_display_is_one_clear_line(tmp_path):
    (tmp_path / "run.rrd").write_bytes(b"")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = subprocess.run(
        [sys.executable, "-m", "smokyslam.cli", "view", str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
    )
    assert out.returncode == 1 and "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "no display" in lines[0] and "run.rrd" in lines[0]
