"""PointCloud2 decoding goes by field name, offset and datatype, whatever the layout."""

import logging
from pathlib import Path

import numpy as np
import pytest

from smokyslam.config import TopicsConfig
from smokyslam.errors import MessageError
from smokyslam.frontends.readers.rosbag import RosbagReader
from smokyslam.rosmsg import MessageBuilder, typestore_for
from smokyslam.rosmsg_decode import radar_scan_from_pointcloud2
from smokyslam.sim.recorder import LogWriter
from smokyslam.types import RadarScan

# PointField datatype codes of the numpy kinds used below.
_CODES = {"i1": 1, "u1": 2, "i2": 3, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}


def _cloud(points: np.ndarray, *, height: int = 1, row_pad: int = 0, ros1: bool = False):
    """A PointCloud2 whose fields, offsets and point_step are those of a structured array."""
    types = typestore_for(ros1).types
    dtype = points.dtype
    fields = [
        types["sensor_msgs/msg/PointField"](
            name=name, offset=offset, datatype=_CODES[dtype.fields[name][0].str[1:]], count=1
        )
        for name, (_, offset) in sorted(dtype.fields.items(), key=lambda item: -item[1][1])
    ]
    width = len(points) // height
    rows = points.view(np.uint8).reshape(height, width * dtype.itemsize)
    data = np.hstack([rows, np.full((height, row_pad), 0xAB, np.uint8)]).reshape(-1)
    header = MessageBuilder(ros1).header(0, "")
    return types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=height,
        width=width,
        fields=fields,
        is_bigendian=dtype.fields["x"][0].byteorder == ">",
        point_step=dtype.itemsize,
        row_step=width * dtype.itemsize + row_pad,
        data=data,
        is_dense=True,
    )


def _values(n: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    return {name: rng.normal(size=n) * 5 for name in ("x", "y", "z", "intensity", "velocity")}


def _structured(spec: dict[str, tuple[str, int]], itemsize: int, values: dict) -> np.ndarray:
    dtype = np.dtype(
        {
            "names": list(spec),
            "formats": [kind for kind, _ in spec.values()],
            "offsets": [offset for _, offset in spec.values()],
            "itemsize": itemsize,
        }
    )
    points = np.zeros(len(values["x"]), dtype=dtype)
    for name in spec:
        points[name] = values[name]
    return points


def test_ti_layout_32_byte_points() -> None:
    """ti_mmwave_rospkg: x, y, z at 0/4/8, intensity at 16, velocity at 20, 32-byte points."""
    values = _values(42)
    spec = {"x": ("<f4", 0), "y": ("<f4", 4), "z": ("<f4", 8)}
    spec |= {"intensity": ("<f4", 16), "velocity": ("<f4", 20)}
    scan, dropped, has_velocity = radar_scan_from_pointcloud2(
        _cloud(_structured(spec, 32, values), ros1=True), 1.5
    )
    assert dropped == 0 and has_velocity and len(scan) == 42 and scan.stamp_s == 1.5
    assert scan.frame_id == "radar"  # empty frame_id in the TI driver
    np.testing.assert_array_equal(scan.points_xyz_m[:, 2], values["z"].astype(np.float32))
    np.testing.assert_array_equal(scan.intensity, values["intensity"].astype(np.float32))
    np.testing.assert_array_equal(scan.doppler_mps, values["velocity"].astype(np.float32))


def test_shuffled_mixed_types_big_endian_and_padding() -> None:
    values = _values(25)
    values["intensity"] = np.round(np.abs(values["intensity"]) * 100)
    spec = {
        "velocity": (">f8", 0),
        "intensity": (">u2", 8),
        "y": (">f4", 12),
        "x": (">f4", 20),
        "z": (">f8", 28),
    }
    points = _structured(spec, 44, values)
    scan, _, _ = radar_scan_from_pointcloud2(_cloud(points, height=5, row_pad=6), 0.0)
    assert len(scan) == 25
    np.testing.assert_array_equal(scan.points_xyz_m[:, 0], values["x"].astype(np.float32))
    np.testing.assert_array_equal(scan.points_xyz_m[:, 1], values["y"].astype(np.float32))
    np.testing.assert_array_equal(scan.points_xyz_m[:, 2], values["z"])
    np.testing.assert_array_equal(scan.intensity, values["intensity"])
    np.testing.assert_array_equal(scan.doppler_mps, values["velocity"])


def test_missing_optional_fields_read_as_zero_and_no_velocity_as_unknown() -> None:
    values = _values(4)
    spec = {"x": ("<f4", 4), "y": ("<f4", 8)}
    scan, _, has_velocity = radar_scan_from_pointcloud2(_cloud(_structured(spec, 16, values)), 0.0)
    np.testing.assert_array_equal(scan.points_xyz_m[:, 1], values["y"].astype(np.float32))
    assert not scan.points_xyz_m[:, 2].any() and not scan.intensity.any()
    assert not has_velocity and np.isnan(scan.doppler_mps).all()


def test_truncated_cloud_is_reported() -> None:
    cloud = _cloud(_structured({"x": ("<f4", 0), "y": ("<f4", 4)}, 8, _values(10)))
    cloud.data = cloud.data[:-3]
    with pytest.raises(MessageError, match=r"truncated: 77 bytes for 10x1 points of 8 bytes"):
        radar_scan_from_pointcloud2(cloud, 0.0)


def test_missing_xy_and_bad_layouts_are_reported() -> None:
    values = _values(3)
    no_y = _cloud(_structured({"x": ("<f4", 0), "z": ("<f4", 4)}, 8, values))
    with pytest.raises(MessageError, match=r"lacks x/y fields \(has: z, x\)"):
        radar_scan_from_pointcloud2(no_y, 0.0)
    overrun = _cloud(_structured({"x": ("<f4", 0), "y": ("<f4", 4)}, 8, values))
    overrun.fields[0].offset = 6  # field y now runs past point_step
    with pytest.raises(MessageError, match="overruns point_step 8"):
        radar_scan_from_pointcloud2(overrun, 0.0)
    overrun.fields[0].offset, overrun.fields[0].datatype = 4, 9
    with pytest.raises(MessageError, match="unknown datatype 9"):
        radar_scan_from_pointcloud2(overrun, 0.0)


def test_non_finite_points_are_dropped_and_counted() -> None:
    values = _values(6)
    values["x"][1] = np.nan
    values["z"][3] = np.inf
    values["velocity"][4] = np.nan  # the point stays; its Doppler is unknown
    values["intensity"][5] = np.inf
    spec = {name: ("<f4", 4 * i) for i, name in enumerate(values)}
    scan, dropped, _ = radar_scan_from_pointcloud2(_cloud(_structured(spec, 20, values)), 0.0)
    assert dropped == 2 and len(scan) == 4
    np.testing.assert_array_equal(scan.points_xyz_m[:, 0], values["x"][[0, 2, 4, 5]].astype("f4"))
    assert np.isnan(scan.doppler_mps[2]) and np.isfinite(scan.doppler_mps[[0, 1, 3]]).all()
    assert scan.intensity[3] == 0.0
    all_nan = {name: np.full(5, np.nan) for name in values}
    empty, dropped, _ = radar_scan_from_pointcloud2(_cloud(_structured(spec, 20, all_nan)), 0.0)
    assert dropped == 5 and len(empty) == 0 and empty.points_xyz_m.shape == (0, 3)


def test_reader_counts_dropped_points_and_warns_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "nan.mcap"
    with LogWriter(path, TopicsConfig()) as writer:
        for i in range(3):
            xyz = np.ones((4, 3))
            xyz[: i + 1, 1] = np.nan
            writer.write_radar(RadarScan(0.1 * i, xyz, np.zeros(4), np.zeros(4)))
    reader = RosbagReader(path, TopicsConfig())
    with caplog.at_level(logging.WARNING):
        sizes = [len(scan) for scan in reader.frames()]
    assert sizes == [3, 2, 1] and reader.checks.counts["radar_points_nonfinite"] == 6
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "6 radar points with NaN/inf coordinates dropped" in warnings[0]
