"""Write every frame type to .mcap / .bag with LogWriter and read it back with RosbagReader."""

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1

from smokyslam.config import TopicsConfig
from smokyslam.errors import LogError, TopicError
from smokyslam.frontends.readers.rosbag import RosbagReader
from smokyslam.geometry import R_BODY_OPTICAL, GridSpec, se3_from_se2, se3_matrix
from smokyslam.rosmsg import MessageBuilder
from smokyslam.sim.recorder import EPOCH_OFFSET_NS, LogWriter
from smokyslam.types import (
    CameraFrame,
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthPose,
    ImuSample,
    RadarScan,
)

INTRINSICS = CameraIntrinsics(width=64, height=48, fx=50.0, fy=51.0, cx=31.5, cy=23.5)
SPEC = GridSpec(origin_xy_m=(-1.0, -2.0), resolution_m=0.1, shape=(30, 40))


def _wall_map() -> GroundTruthMap:
    """An L-shaped wall: a row at y in [0.0, 0.1) for x >= 0.5 and a column at x in [2.0, 2.1)."""
    cells = np.zeros(SPEC.shape, dtype=np.int8)
    (ix0, iy0), (ix1, _) = SPEC.cells_of(np.array([[0.55, 0.05], [2.05, 0.0]]))
    cells[iy0, ix0:] = 100
    cells[:, ix1] = 100
    cells[-3:, :5] = -1
    return GroundTruthMap(stamp_s=0.0, cells=cells, spec=SPEC)


def _extrinsics() -> Extrinsics:
    T_base_camera = se3_from_se2(np.array([0.05, 0.01, 0.2]), z_m=1.2)
    T_base_camera[:3, :3] = T_base_camera[:3, :3] @ R_BODY_OPTICAL
    T_base_radar = se3_matrix([0.1, -0.03, 1.0], np.array([0.9, 0.1, -0.2, 0.3]) / np.sqrt(0.95))
    return Extrinsics(T_base_radar=T_base_radar, T_base_camera=T_base_camera)


def _frames(rng: np.random.Generator) -> dict[str, list]:
    radar = [
        RadarScan(t, rng.normal(size=(n, 3)) * 3, rng.uniform(0, 40, n), rng.normal(size=n))
        for t, n in ((0.05, 40), (0.15, 0), (0.25, 37))
    ]
    camera = []
    for t in (0.1, 0.2):
        depth_half = rng.uniform(0.3, 9.0, (24, 32)).astype(np.float32)
        depth_half[0, 0] = np.nan  # no depth -> 0 mm -> NaN
        depth = np.repeat(np.repeat(depth_half, 2, axis=0), 2, axis=1)
        image = rng.integers(0, 256, (48, 64), dtype=np.uint8)
        camera.append(CameraFrame(t, image, INTRINSICS, depth))
    imu = [ImuSample(0.01 * i, rng.normal(size=3), rng.normal(size=3)) for i in range(30)]
    yaws = (0.0, 3.1, -3.1, 1.0, -0.5)
    poses = [
        GroundTruthPose(0.02 * i, np.array([1.5 * i, -0.5 * i, yaw])) for i, yaw in enumerate(yaws)
    ]
    return {"radar": radar, "camera": camera, "imu": imu, "poses": poses}


@pytest.fixture(params=[".mcap", ".bag"])
def log(tmp_path: Path, request: pytest.FixtureRequest) -> tuple[Path, dict[str, list]]:
    frames = _frames(np.random.default_rng(7))
    path = tmp_path / f"sim{request.param}"
    with LogWriter(path, TopicsConfig()) as writer:
        writer.write_tf_static(_extrinsics(), 0.0)
        writer.write_ground_truth_map(_wall_map())
        for scan in frames["radar"]:
            writer.write_radar(scan)
        for frame in frames["camera"]:
            writer.write_camera(frame, depth_scale=2)
        for sample in frames["imu"]:
            writer.write_imu(sample)
        for pose in frames["poses"]:
            writer.write_ground_truth_pose(pose)
    return path, frames


def _read(path: Path) -> dict[str, list]:
    frames = list(RosbagReader(path, TopicsConfig()).frames())
    stamps = [f.stamp_s for f in frames]
    assert stamps == sorted(stamps), "frames not in time order"
    by_type: dict[str, list] = {}
    for frame in frames:
        by_type.setdefault(type(frame).__name__, []).append(frame)
    return by_type


def test_mcap_is_one_file_and_nothing_else_is_left(log: tuple[Path, dict]) -> None:
    path, _ = log
    assert path.is_file()
    assert [p.name for p in path.parent.iterdir()] == [path.name]


def test_radar_round_trip_within_float32(log: tuple[Path, dict]) -> None:
    path, written = log
    read = _read(path)["RadarScan"]
    assert [len(s) for s in read] == [40, 0, 37]
    for got, want in zip(read, written["radar"], strict=True):
        assert got.stamp_s == pytest.approx(want.stamp_s, abs=1e-9)
        f32 = np.float32
        np.testing.assert_array_equal(got.points_xyz_m, want.points_xyz_m.astype(f32))
        np.testing.assert_array_equal(got.intensity, want.intensity.astype(f32))
        np.testing.assert_array_equal(got.doppler_mps, want.doppler_mps.astype(f32))
        assert got.frame_id == "radar"


def test_camera_round_trip_with_half_resolution_depth(log: tuple[Path, dict]) -> None:
    path, written = log
    read = _read(path)["CameraFrame"]
    assert len(read) == 2
    for got, want in zip(read, written["camera"], strict=True):
        assert got.stamp_s == pytest.approx(want.stamp_s, abs=1e-9)
        assert got.image.dtype == np.uint8
        assert got.image.tobytes() == want.image.tobytes()
        assert got.intrinsics == INTRINSICS
        assert got.depth_m.shape == (48, 64) and got.depth_m.dtype == np.float32
        np.testing.assert_allclose(got.depth_m, want.depth_m, atol=5e-4, equal_nan=True)
        assert np.isnan(got.depth_m[:2, :2]).all() and np.isfinite(got.depth_m).sum() == 48 * 64 - 4


def test_imu_and_ground_truth_pose_round_trip(log: tuple[Path, dict]) -> None:
    path, written = log
    read = _read(path)
    for got, want in zip(read["ImuSample"], written["imu"], strict=True):
        assert got.stamp_s == pytest.approx(want.stamp_s, abs=1e-9)
        np.testing.assert_array_equal(got.gyro_radps, want.gyro_radps)
        np.testing.assert_array_equal(got.accel_mps2, want.accel_mps2)
    # Ground truth is never a frame: estimators cannot see it. Evaluation reads it apart.
    assert "GroundTruthPose" not in read and "GroundTruthMap" not in read
    truth = RosbagReader(path, TopicsConfig()).ground_truth_trajectory()
    assert len(truth) == 5
    for stamp_s, got, want in zip(
        truth.stamps_s, truth.poses_world_base, written["poses"], strict=True
    ):
        assert stamp_s == pytest.approx(want.stamp_s, abs=1e-9)
        np.testing.assert_allclose(got, want.pose_world_base, atol=1e-12)


def test_map_keeps_its_orientation(log: tuple[Path, dict]) -> None:
    path, _ = log
    reader = RosbagReader(path, TopicsConfig())
    grid = reader.ground_truth_map()
    assert grid.spec == SPEC
    np.testing.assert_array_equal(grid.cells, _wall_map().cells)
    # the wall column at x = 2.05 m and the row at y = 0.05 m read back in those world cells
    wall = grid.spec.cells_of(np.array([[2.05, -1.5], [2.05, 0.7], [1.0, 0.05], [2.85, 0.05]]))
    assert (grid.cells[wall[:, 1], wall[:, 0]] == 100).all()
    free = grid.spec.cells_of(np.array([[0.2, 0.05], [1.0, 0.5], [1.0, -0.05]]))
    assert (grid.cells[free[:, 1], free[:, 0]] == 0).all()


def test_occupancy_grid_data_follows_ros_layout() -> None:
    """ROS: data[j * width + i] is the cell whose lower-left corner is origin + (i, j) * res."""
    msg = MessageBuilder(ros1=False).occupancy_grid(_wall_map(), EPOCH_OFFSET_NS)
    width, res = msg.info.width, msg.info.resolution
    ox, oy = msg.info.origin.position.x, msg.info.origin.position.y
    occupied = np.flatnonzero(np.asarray(msg.data) == 100)
    i, j = occupied % width, occupied // width
    x_m, y_m = ox + (i + 0.5) * res, oy + (j + 0.5) * res
    on_column = np.isclose(x_m, 2.05)
    assert on_column.sum() == SPEC.shape[0]
    np.testing.assert_allclose(y_m[~on_column], 0.05)
    assert x_m[~on_column].min() == pytest.approx(0.55)


def test_extrinsics_rebuilt_from_tf_static(log: tuple[Path, dict]) -> None:
    path, _ = log
    extrinsics = RosbagReader(path, TopicsConfig()).extrinsics()
    np.testing.assert_allclose(extrinsics.T_base_radar, _extrinsics().T_base_radar, atol=1e-12)
    np.testing.assert_allclose(extrinsics.T_base_camera, _extrinsics().T_base_camera, atol=1e-12)


def test_writes_out_of_order_read_back_in_order(tmp_path: Path) -> None:
    path = tmp_path / "shuffled.mcap"
    stamps = [0.5, 0.1, 0.3, 0.0, 0.4]
    with LogWriter(path, TopicsConfig()) as writer:
        for t in stamps:
            writer.write_imu(ImuSample(t, np.full(3, t), np.zeros(3)))
    read = list(RosbagReader(path, TopicsConfig()).frames())
    assert [f.gyro_radps[0] for f in read] == sorted(stamps)
    assert [f.stamp_s for f in read] == pytest.approx(sorted(stamps))


def test_depth_written_before_its_image_still_pairs(tmp_path: Path) -> None:
    path, builder = tmp_path / "depth_first.bag", MessageBuilder(ros1=True)
    image = np.arange(48 * 64, dtype=np.uint32).reshape(48, 64).astype(np.uint8)
    depth = np.full((48, 64), 2.0, dtype=np.float32)
    topics = TopicsConfig()
    with Writer1(path) as writer:
        conns = {
            name: writer.add_connection(topic[0], msgtype, typestore=builder.typestore)
            for name, topic, msgtype in (
                ("image", topics.camera_image, "sensor_msgs/msg/Image"),
                ("depth", topics.camera_depth, "sensor_msgs/msg/Image"),
                ("imu", topics.imu, "sensor_msgs/msg/Imu"),
            )
        }
        base = EPOCH_OFFSET_NS
        for i in range(3):
            t = base + i * 100_000_000
            if i != 1:  # frame 1 has no depth at all
                msg = builder.depth_image(depth + i, 2, t)
                writer.write(conns["depth"], t, builder.serialize(msg))
            writer.write(conns["image"], t, builder.serialize(builder.image(image, "mono8", t)))
            imu = builder.imu(ImuSample(0.0, np.zeros(3), np.zeros(3)), t + 1)
            writer.write(conns["imu"], t + 1, builder.serialize(imu))
    frames = list(RosbagReader(path, TopicsConfig()).frames())
    assert [type(f).__name__[0] for f in frames] == list("CICICI")
    cameras = frames[::2]
    assert cameras[0].depth_m[5, 5] == pytest.approx(2.0)
    assert cameras[1].depth_m is None
    assert cameras[2].depth_m[5, 5] == pytest.approx(4.0)
    assert all(c.intrinsics is None for c in cameras)


def test_writer_refuses_to_overwrite_unless_asked(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    with LogWriter(path, TopicsConfig()) as writer:
        writer.write_imu(ImuSample(0.0, np.zeros(3), np.zeros(3)))
    with pytest.raises(LogError, match="exists already"):
        LogWriter(path, TopicsConfig())
    with LogWriter(path, TopicsConfig(), overwrite=True) as writer:
        for i in range(3):
            writer.write_imu(ImuSample(0.1 * i, np.zeros(3), np.zeros(3)))
    assert len(list(RosbagReader(path, TopicsConfig()).frames())) == 3


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    path = tmp_path / "broken.bag"
    with pytest.raises(RuntimeError), LogWriter(path, TopicsConfig()) as writer:
        writer.write_imu(ImuSample(0.0, np.zeros(3), np.zeros(3)))
        raise RuntimeError("simulator crashed")
    assert list(tmp_path.iterdir()) == []


def test_writer_rejects_unknown_suffix(tmp_path: Path) -> None:
    with pytest.raises(LogError, match=r"unknown log format '\.txt'"):
        LogWriter(tmp_path / "x.txt", TopicsConfig())


def test_frames_decode_only_the_streams_asked_for(log: tuple[Path, dict]) -> None:
    path, _ = log
    reader = RosbagReader(path, TopicsConfig())
    kinds = {type(f).__name__ for f in reader.frames(("radar", "imu"))}
    assert kinds == {"RadarScan", "ImuSample"}
    images = list(reader.frames(("camera_image",)))
    assert [type(f).__name__ for f in images] == ["CameraFrame"] * 2
    assert all(f.depth_m is None and f.intrinsics == INTRINSICS for f in images)
    with_depth = list(reader.frames(("camera_image", "camera_depth")))
    assert all(f.depth_m is not None for f in with_depth)
    with pytest.raises(TopicError, match="unknown sensor streams"):
        list(reader.frames(("ground_truth_pose",)))


def test_queries_while_frames_are_paused_read_what_a_fresh_reader_reads(
    log: tuple[Path, dict],
) -> None:
    """One reader answers many queries (an open file is kept for the next): a query in the
    middle of a paused frame stream, and a stream left unfinished, change nothing read."""
    path, written = log
    reader = RosbagReader(path, TopicsConfig())
    frames = reader.frames()
    head = [next(frames) for _ in range(3)]
    truth = reader.ground_truth_trajectory()  # while the stream is paused mid-log
    ground_map = reader.ground_truth_map()
    stamps = [f.stamp_s for f in head] + [f.stamp_s for f in frames]
    unfinished = reader.frames(("radar",))
    next(unfinished)
    del unfinished
    fresh = RosbagReader(path, TopicsConfig())
    assert stamps == [f.stamp_s for f in fresh.frames()]
    assert [f.stamp_s for f in reader.frames()] == stamps
    assert len(truth.stamps_s) == len(written["poses"]) == 5
    again = fresh.ground_truth_trajectory().poses_world_base
    np.testing.assert_allclose(truth.poses_world_base, again)
    np.testing.assert_array_equal(ground_map.cells, fresh.ground_truth_map().cells)
