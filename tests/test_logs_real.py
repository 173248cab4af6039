"""The real TI mmWave demo bag (ROS1, 32-byte points, empty frame_id) reads as expected."""

from pathlib import Path

import numpy as np
import pytest

from smokyslam.config import SmokySlamConfig
from smokyslam.frontends.readers.registry import open_log
from smokyslam.loginfo import format_summary
from smokyslam.types import ImuSample, RadarScan


@pytest.fixture(scope="module")
def ti_frames(real_data_dir: Path) -> tuple:
    path = real_data_dir / "ti_mmwave_rospkg_demo.bag"
    reader = open_log(path, SmokySlamConfig(), require=("radar", "imu"))
    return reader, list(reader.frames())


def test_ti_radar_scans(ti_frames: tuple) -> None:
    reader, frames = ti_frames
    scans = [f for f in frames if isinstance(f, RadarScan)]
    assert len(scans) == 412 and reader.checks.counts["radar_points_nonfinite"] == 0
    sizes = np.array([len(s) for s in scans])
    assert 38 < sizes.mean() < 48 and sizes.min() >= 10
    points = np.concatenate([s.points_xyz_m for s in scans])
    ranges_m = np.linalg.norm(points, axis=1)
    assert 0.3 < np.median(ranges_m) < 10.0 and ranges_m.max() < 30.0
    doppler = np.concatenate([s.doppler_mps for s in scans])
    assert 0.3 < np.mean(doppler != 0.0) < 0.8 and np.abs(doppler).max() < 5.0
    intensity = np.concatenate([s.intensity for s in scans])
    assert intensity.min() > 0.0 and 5.0 < np.median(intensity) < 20.0
    assert scans[0].frame_id == "radar"
    assert 0.0 <= scans[0].stamp_s < 0.1 and scans[-1].stamp_s == pytest.approx(40.2, abs=0.1)


def test_ti_imu_and_time_order(ti_frames: tuple) -> None:
    _, frames = ti_frames
    imu = [f for f in frames if isinstance(f, ImuSample)]
    assert len(imu) == 8270
    accel = np.array([s.accel_mps2 for s in imu])
    assert np.linalg.norm(accel, axis=1).mean() == pytest.approx(9.81, abs=0.3)
    stamps = np.array([f.stamp_s for f in frames])
    assert (np.diff(stamps) >= 0).all() and stamps[0] == 0.0


def test_ti_summary(ti_frames: tuple) -> None:
    reader, _ = ti_frames
    summary = reader.summary()
    assert summary.format == "ROS1 bag" and summary.duration_s == pytest.approx(40.26, abs=0.01)
    streams = {s.topic: s for s in summary.streams}
    assert len(streams) == 4
    radar, imu = streams["/ti_mmwave/radar_scan_pcl"], streams["/sensor_platform/imu"]
    assert radar.count == 412 and radar.rate_hz == pytest.approx(10.2, abs=0.2)
    # 8270 messages in 40.26 s: about 205 Hz in this bag
    assert imu.count == 8270 and imu.rate_hz == pytest.approx(205.4, abs=1.0)
    text = format_summary(summary)
    rows = {line.split()[0]: line.split()[1:] for line in text.splitlines() if line[:1] == "/"}
    assert rows["/ti_mmwave/radar_scan_pcl"] == ["sensor_msgs/msg/PointCloud2", "412", "10.2"]
    assert rows["/sensor_platform/imu"] == ["sensor_msgs/msg/Imu", "8270", "205.4"]
    assert "duration: 40.26 s" in text
