"""Conversions from smokyslam frames to ROS messages (rosbags message objects), and the shared
constants and typestore helpers that :mod:`smokyslam.rosmsg_decode` reads with.

Encoding goes through :class:`MessageBuilder`, bound to a ROS1 (noetic) or ROS2 (humble)
typestore. Decoding lives in :mod:`smokyslam.rosmsg_decode`.

Message layouts written by smokyslam:

- radar: ``sensor_msgs/PointCloud2``, little-endian float32 fields x, y, z, intensity,
  velocity (``RadarScan.doppler_mps``), 20-byte points, frame ``radar``.
- camera: ``sensor_msgs/Image`` mono8 plus ``CameraInfo`` (plumb_bob, zero distortion).
- depth: ``sensor_msgs/Image`` 16UC1 in millimetres, usually at reduced resolution; 0 means
  no depth.
- IMU: ``sensor_msgs/Imu`` in ``base_link``; orientation unknown (covariance[0] = -1).
- ground truth: ``geometry_msgs/PoseStamped`` of ``base_link`` in ``map`` (planar pose as
  position + yaw quaternion) and ``nav_msgs/OccupancyGrid`` (100/0/-1). The grid's ``data``
  is row-major from the origin cell (lower-left), so it maps onto ``cells[iy, ix]`` directly.
- ``/tf_static``: ``tf2_msgs/TFMessage`` with ``base_link -> radar`` and
  ``base_link -> camera`` (each ``T_base_child``).
"""

from __future__ import annotations

import itertools
from functools import cache
from typing import Any

import cv2
import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from smokyslam.geometry import (
    quat_wxyz_from_rotation_matrix,
    quat_wxyz_from_yaw,
    quat_xyzw_from_wxyz,
)
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthPose,
    ImuSample,
    RadarScan,
)

FRAME_MAP, FRAME_BASE, FRAME_RADAR, FRAME_CAMERA = "map", "base_link", "radar", "camera"

STREAM_MSGTYPES: dict[str, str] = {
    "radar": "sensor_msgs/msg/PointCloud2",
    "camera_image": "sensor_msgs/msg/Image",
    "camera_info": "sensor_msgs/msg/CameraInfo",
    "camera_depth": "sensor_msgs/msg/Image",
    "imu": "sensor_msgs/msg/Imu",
    "ground_truth_pose": "geometry_msgs/msg/PoseStamped",
    "ground_truth_map": "nav_msgs/msg/OccupancyGrid",
    "ground_truth_map_observed": "nav_msgs/msg/OccupancyGrid",
    "tf_static": "tf2_msgs/msg/TFMessage",
}
"""Message type of every stream named in ``TopicsConfig``."""

RADAR_FIELDS = ("x", "y", "z", "intensity", "velocity")
"""PointCloud2 field names of a radar point, in the order smokyslam writes them."""
_NS_PER_S = 1_000_000_000


@cache
def typestore_for(ros1: bool) -> Typestore:
    """The rosbags typestore smokyslam writes with (ROS1 noetic gets tf2_msgs/TFMessage added)."""
    if not ros1:
        return get_typestore(Stores.ROS2_HUMBLE)
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(
        get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage")
    )
    return store


def header_stamp_ns(msg: Any) -> int:
    """Header stamp of a message in nanoseconds (0 when the publisher left it empty)."""
    stamp = msg.header.stamp
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)


class MessageBuilder:
    """Builds ROS messages from smokyslam frames in one typestore (ROS1 or ROS2)."""

    def __init__(self, ros1: bool) -> None:
        self.ros1 = ros1
        self.typestore = typestore_for(ros1)
        self._types = self.typestore.types
        self._seq = itertools.count()

    def serialize(self, msg: Any) -> bytes:
        """Wire bytes of ``msg``: ROS1 serialization or CDR."""
        if self.ros1:
            return bytes(self.typestore.serialize_ros1(msg, msg.__msgtype__))
        return bytes(self.typestore.serialize_cdr(msg, msg.__msgtype__))

    def time(self, stamp_ns: int) -> Any:
        """``builtin_interfaces/Time`` of a stamp in nanoseconds."""
        return self._types["builtin_interfaces/msg/Time"](
            sec=stamp_ns // _NS_PER_S, nanosec=stamp_ns % _NS_PER_S
        )

    def header(self, stamp_ns: int, frame_id: str) -> Any:
        """``std_msgs/Header`` (ROS1 headers also get an increasing ``seq``)."""
        stamp = self.time(stamp_ns)
        if self.ros1:
            return self._types["std_msgs/msg/Header"](
                seq=next(self._seq), stamp=stamp, frame_id=frame_id
            )
        return self._types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def pointcloud2(self, scan: RadarScan, stamp_ns: int) -> Any:
        """Radar scan as an unorganized cloud of float32 x, y, z, intensity, velocity."""
        point_field = self._types["sensor_msgs/msg/PointField"]
        dtype = np.dtype([(name, "<f4") for name in RADAR_FIELDS])
        points = np.empty(len(scan), dtype=dtype)
        points["x"], points["y"], points["z"] = scan.points_xyz_m.T
        points["intensity"] = scan.intensity
        points["velocity"] = scan.doppler_mps
        fields = [
            point_field(name=name, offset=dtype.fields[name][1], datatype=7, count=1)
            for name in RADAR_FIELDS
        ]
        return self._types["sensor_msgs/msg/PointCloud2"](
            header=self.header(stamp_ns, scan.frame_id or FRAME_RADAR),
            height=1,
            width=len(scan),
            fields=fields,
            is_bigendian=False,
            point_step=dtype.itemsize,
            row_step=dtype.itemsize * len(scan),
            data=points.view(np.uint8).reshape(-1),
            is_dense=bool(np.isfinite(scan.points_xyz_m).all()),
        )

    def image(self, pixels: np.ndarray, encoding: str, stamp_ns: int) -> Any:
        """``sensor_msgs/Image`` of a (H, W) uint8 (mono8) or uint16 (16UC1) array, camera frame."""
        pixels = np.ascontiguousarray(pixels)
        height, width = pixels.shape
        return self._types["sensor_msgs/msg/Image"](
            header=self.header(stamp_ns, FRAME_CAMERA),
            height=height,
            width=width,
            encoding=encoding,
            is_bigendian=False,
            step=width * pixels.itemsize,
            data=pixels.astype(pixels.dtype.newbyteorder("<"), copy=False)
            .view(np.uint8)
            .reshape(-1),
        )

    def depth_image(self, depth_m: np.ndarray, depth_scale: int, stamp_ns: int) -> Any:
        """16UC1 millimetre depth at 1/``depth_scale`` of the (H, W) metres input.

        0 marks no depth (NaN, inf or <= 0); depths beyond 65.535 m are clipped to it.
        """
        height, width = depth_m.shape
        small = np.asarray(depth_m, dtype=np.float32)
        if depth_scale > 1:
            size = (max(width // depth_scale, 1), max(height // depth_scale, 1))
            small = cv2.resize(small, size, interpolation=cv2.INTER_NEAREST)
        valid = np.isfinite(small) & (small > 0.0)
        millimetres = np.clip(np.rint(np.where(valid, small, 0.0) * 1000.0), 0, 65535)
        return self.image(millimetres.astype(np.uint16), "16UC1", stamp_ns)

    def camera_info(self, intrinsics: CameraIntrinsics, stamp_ns: int) -> Any:
        """``sensor_msgs/CameraInfo`` of a distortion-free pinhole camera."""
        k = intrinsics.camera_matrix.reshape(-1)
        p = np.hstack([intrinsics.camera_matrix, np.zeros((3, 1))]).reshape(-1)
        roi = self._types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        )
        matrices = {"D": np.zeros(5), "K": k, "R": np.eye(3).reshape(-1), "P": p}
        if not self.ros1:
            matrices = {key.lower(): value for key, value in matrices.items()}
        return self._types["sensor_msgs/msg/CameraInfo"](
            header=self.header(stamp_ns, FRAME_CAMERA),
            height=intrinsics.height,
            width=intrinsics.width,
            distortion_model="plumb_bob",
            binning_x=0,
            binning_y=0,
            roi=roi,
            **matrices,
        )

    def imu(self, sample: ImuSample, stamp_ns: int) -> Any:
        """``sensor_msgs/Imu`` in base_link with no orientation (covariance[0] = -1)."""
        vector3 = self._types["geometry_msgs/msg/Vector3"]
        unknown = np.zeros(9)
        unknown[0] = -1.0
        return self._types["sensor_msgs/msg/Imu"](
            header=self.header(stamp_ns, FRAME_BASE),
            orientation=self._quaternion(np.array([1.0, 0.0, 0.0, 0.0])),
            orientation_covariance=unknown,
            angular_velocity=vector3(*(float(v) for v in sample.gyro_radps)),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=vector3(*(float(v) for v in sample.accel_mps2)),
            linear_acceleration_covariance=np.zeros(9),
        )

    def pose_stamped(self, pose: GroundTruthPose, stamp_ns: int) -> Any:
        """``geometry_msgs/PoseStamped`` of base_link in the map frame (z = 0)."""
        x_m, y_m, yaw_rad = (float(v) for v in pose.pose_world_base)
        return self._types["geometry_msgs/msg/PoseStamped"](
            header=self.header(stamp_ns, FRAME_MAP), pose=self._pose(x_m, y_m, yaw_rad)
        )

    def occupancy_grid(self, grid: GroundTruthMap, stamp_ns: int) -> Any:
        """``nav_msgs/OccupancyGrid``: row-major ``cells[iy, ix]`` from the lower-left cell."""
        rows, cols = grid.cells.shape
        info = self._types["nav_msgs/msg/MapMetaData"](
            map_load_time=self.time(stamp_ns),
            resolution=float(grid.spec.resolution_m),
            width=cols,
            height=rows,
            origin=self._pose(*grid.spec.origin_xy_m, 0.0),
        )
        data = np.ascontiguousarray(grid.cells, dtype=np.int8).reshape(-1)
        return self._types["nav_msgs/msg/OccupancyGrid"](
            header=self.header(stamp_ns, FRAME_MAP), info=info, data=data
        )

    def tf_static(self, extrinsics: Extrinsics, stamp_ns: int) -> Any:
        """``tf2_msgs/TFMessage`` holding ``base_link -> radar`` and ``base_link -> camera``."""
        transforms = [
            self._transform_stamped(T_base_child, child, stamp_ns)
            for child, T_base_child in (
                (FRAME_RADAR, extrinsics.T_base_radar),
                (FRAME_CAMERA, extrinsics.T_base_camera),
            )
        ]
        return self._types["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def _quaternion(self, q_wxyz: np.ndarray) -> Any:
        x, y, z, w = (float(v) for v in quat_xyzw_from_wxyz(q_wxyz))
        return self._types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def _pose(self, x_m: float, y_m: float, yaw_rad: float) -> Any:
        position = self._types["geometry_msgs/msg/Point"](x=float(x_m), y=float(y_m), z=0.0)
        return self._types["geometry_msgs/msg/Pose"](
            position=position, orientation=self._quaternion(quat_wxyz_from_yaw(yaw_rad))
        )

    def _transform_stamped(self, T_parent_child: np.ndarray, child: str, stamp_ns: int) -> Any:
        translation = self._types["geometry_msgs/msg/Vector3"](
            *(float(v) for v in T_parent_child[:3, 3])
        )
        rotation = self._quaternion(quat_wxyz_from_rotation_matrix(T_parent_child[:3, :3]))
        transform = self._types["geometry_msgs/msg/Transform"](
            translation=translation, rotation=rotation
        )
        return self._types["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp_ns, FRAME_BASE), child_frame_id=child, transform=transform
        )
