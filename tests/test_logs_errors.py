"""Bad logs give one clear LogError/TopicError; the registry picks readers by suffix and content."""

import gzip
import sys
from pathlib import Path

import numpy as np
import pytest

from smokyslam.config import SmokySlamConfig, TopicsConfig
from smokyslam.errors import LogError, TopicError
from smokyslam.frontends.readers.registry import READERS, config_for_log, log_format, open_log
from smokyslam.frontends.readers.rosbag import RosbagReader
from smokyslam.sim.recorder import LogWriter
from smokyslam.types import ImuSample, RadarScan

CONFIG = SmokySlamConfig()


@pytest.fixture(params=[".bag", ".mcap"])
def small_log(tmp_path: Path, request: pytest.FixtureRequest) -> Path:
    path = tmp_path / f"small{request.param}"
    with LogWriter(path, TopicsConfig()) as writer:
        for i in range(50):
            t = 0.1 * i
            writer.write_radar(RadarScan(t, np.ones((30, 3)), np.ones(30), np.zeros(30)))
            writer.write_imu(ImuSample(t, np.zeros(3), np.zeros(3)))
    return path


def _cut_in_half(path: Path, out: Path) -> Path:
    data = path.read_bytes()
    out.write_bytes(data[: len(data) // 2])
    return out


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(LogError, match=r"^log not found: .*nothing\.bag$"):
        open_log(tmp_path / "nothing.bag", CONFIG)


def test_text_file_renamed_as_bag(tmp_path: Path) -> None:
    for suffix, what in ((".bag", "a ROS1 bag"), (".mcap", "an MCAP file")):
        path = tmp_path / f"notes{suffix}"
        path.write_text("just some text\n")
        with pytest.raises(LogError, match=f"notes\\{suffix}: not {what} \\(wrong file header\\)"):
            open_log(path, CONFIG)


def test_a_truncated_log_is_salvaged_up_to_the_cut(small_log: Path, tmp_path: Path) -> None:
    cut = _cut_in_half(small_log, tmp_path / f"cut{small_log.suffix}")
    assert log_format(cut) in ("ros1", "ros2")  # the header survives the cut, the index not
    reader = open_log(cut, CONFIG)
    scans = [f for f in reader.frames() if isinstance(f, RadarScan)]
    assert 10 <= len(scans) < 50  # what was written before the cut
    np.testing.assert_allclose([s.stamp_s for s in scans], 0.1 * np.arange(len(scans)))
    assert "salvaged" in reader.damage and "salvaged" in reader.summary().damage


def test_a_log_cut_before_its_messages_is_one_clear_error(small_log: Path, tmp_path: Path):
    cut = tmp_path / f"stub{small_log.suffix}"
    cut.write_bytes(small_log.read_bytes()[:200])
    with pytest.raises(
        LogError, match=r"stub\.(bag|mcap): cannot read ROS[12] .*truncated or corrupt"
    ):
        open_log(cut, CONFIG)


def test_truncated_real_bag_is_salvaged(real_data_dir: Path, tmp_path: Path) -> None:
    cut = _cut_in_half(real_data_dir / "ti_mmwave_rospkg_demo.bag", tmp_path / "ti_half.bag")
    reader = open_log(cut, CONFIG)
    summary = reader.summary()
    counts = {stream.topic: stream.count for stream in summary.streams}
    assert 150 < counts["/ti_mmwave/radar_scan_pcl"] < 412 and "salvaged" in summary.damage
    assert 15.0 < summary.duration_s < 25.0  # of the 40 s recording


def test_unknown_suffix_and_plain_folder(tmp_path: Path) -> None:
    path = tmp_path / "scan.pcd"
    path.write_bytes(b"\0" * 10)
    with pytest.raises(LogError, match=r"unknown log format '\.pcd' \(expected \.bag, \.mcap"):
        open_log(path, CONFIG)
    with pytest.raises(LogError, match="a folder but not a rosbag2 log"):
        open_log(tmp_path, CONFIG)


def test_missing_required_topic_names_candidates_and_contents(small_log: Path) -> None:
    reader = open_log(small_log, CONFIG, require=("radar", "imu"))
    assert isinstance(reader, RosbagReader)
    with pytest.raises(TopicError) as error:
        open_log(small_log, CONFIG, require=("radar", "camera_image"))
    message = str(error.value)
    assert "no camera_image topic of type sensor_msgs/msg/Image" in message
    assert "looked for: /camera/image_raw" in message
    assert "/imu (sensor_msgs/msg/Imu)" in message and "/ti_mmwave/radar_scan_pcl" in message
    with pytest.raises(TopicError, match="unknown stream 'lidar'"):
        reader.require("lidar")


def test_candidate_topics_are_tried_in_order(small_log: Path) -> None:
    topics = TopicsConfig(radar=["/radar", "/ti_mmwave/radar_scan_pcl"], imu=["/imu_missing"])
    reader = RosbagReader(small_log, topics)
    assert reader.stream_topics == {"radar": "/ti_mmwave/radar_scan_pcl"}
    assert {type(frame).__name__ for frame in reader.frames()} == {"RadarScan"}


def test_topic_of_the_wrong_type_is_skipped(small_log: Path) -> None:
    reader = RosbagReader(small_log, TopicsConfig(radar=["/imu"]))
    with pytest.raises(TopicError, match="no radar topic of type sensor_msgs/msg/PointCloud2"):
        reader.require("radar")


def test_ros2_folder_is_read(tmp_path: Path) -> None:
    """A rosbag2 folder (metadata.yaml + storage file), as ros2 bag record writes it."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from smokyslam.rosmsg import MessageBuilder

    folder, builder = tmp_path / "recording", MessageBuilder(ros1=False)
    with Writer(folder, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conn = writer.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=builder.typestore)
        for i in range(4):
            msg = builder.imu(ImuSample(0.0, np.full(3, float(i)), np.zeros(3)), 10**9 * (i + 1))
            writer.write(conn, 10**9 * (i + 1), builder.serialize(msg))
    reader = open_log(folder, CONFIG, require=("imu",))
    samples = list(reader.frames())
    assert [s.stamp_s for s in samples] == [0.0, 1.0, 2.0, 3.0]
    assert [s.gyro_radps[2] for s in samples] == [0.0, 1.0, 2.0, 3.0]
    assert reader.summary().format == "ROS2 folder"


def test_carmen_logs_go_to_the_carmen_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert set(READERS) == {"ros1", "ros2", "carmen"}
    path = tmp_path / "lab.log.gz"
    with gzip.open(path, "wt") as stream:
        stream.write("# empty\n")
    assert log_format(path) == "carmen"
    with pytest.raises(TopicError, match="a CARMEN log has no camera_image stream"):
        open_log(path, CONFIG, require=("radar", "camera_image"))
    monkeypatch.setitem(sys.modules, "smokyslam.frontends.readers.carmen", None)
    with pytest.raises(LogError, match="CARMEN support not available"):
        open_log(path, CONFIG)


def test_carmen_logs_run_with_their_own_local_map_radius(tmp_path: Path, small_log: Path) -> None:
    path = tmp_path / "lab.log"
    path.write_text("# empty\n")
    config = config_for_log(path, CONFIG)
    assert config.radar_odometry.map_radius_m == CONFIG.carmen.map_radius_m == 30.0
    assert config.radar_odometry.gyro_bias_sigma_degps == CONFIG.carmen.gyro_bias_sigma_degps
    carmen_keys = {"map_radius_m", "gyro_bias_sigma_degps"}
    assert config.radar_odometry.model_dump(exclude=carmen_keys) == (
        CONFIG.radar_odometry.model_dump(exclude=carmen_keys)
    )
    assert config_for_log(small_log, CONFIG) is CONFIG
    assert CONFIG.radar_odometry.map_radius_m == 12.0
