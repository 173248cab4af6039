"""format_summary: the text ``smokyslam info`` prints."""

from pathlib import Path

from smokyslam.frontends.readers.base import LogSummary, StreamSummary
from smokyslam.loginfo import format_summary


def test_table_lists_every_topic_aligned_with_rates() -> None:
    summary = LogSummary(
        path=Path("run.mcap"),
        format="ROS2 MCAP",
        duration_s=29.987,
        start_s=1.7e9,
        streams=[
            StreamSummary("/imu", "sensor_msgs/msg/Imu", 3000, 100.0),
            StreamSummary("/tf_static", "tf2_msgs/msg/TFMessage", 1, 0.0),
            StreamSummary("/ti_mmwave/radar_scan_pcl", "sensor_msgs/msg/PointCloud2", 300, 9.96),
        ],
    )
    lines = format_summary(summary).splitlines()
    assert lines[:4] == [
        "log:      run.mcap",
        "format:   ROS2 MCAP",
        "duration: 29.99 s",
        "messages: 3301",
    ]
    table = lines[5:]
    assert table[0].split() == ["topic", "type", "count", "rate", "Hz"]
    assert table[1].split() == ["/imu", "sensor_msgs/msg/Imu", "3000", "100.0"]
    assert table[2].split() == ["/tf_static", "tf2_msgs/msg/TFMessage", "1", "-"]
    assert table[3].split() == [
        "/ti_mmwave/radar_scan_pcl",
        "sensor_msgs/msg/PointCloud2",
        "300",
        "10.0",
    ]
    # columns line up: every row has the same width and the type column starts at one place
    assert len({len(row) for row in table}) == 1
    assert len({row.index(row.split()[1]) for row in table}) == 1


def test_empty_log() -> None:
    text = format_summary(LogSummary(Path("e.bag"), "ROS1 bag", 0.0, 0.0, []))
    assert "messages: 0" in text and "(no topics)" in text
