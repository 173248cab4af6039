"""Conversions between smokyslam frames and ROS messages (rosbags message objects).

Encoding goes through :class:`MessageBuilder`, bound to a ROS1 (noetic) or ROS2 (humble)
typestore. Decoding is done by plain functions that accept messages from either store (field
names are the same except ``CameraInfo.K`` in ROS1 versus ``k`` in ROS2).

Message layouts written by smokyslam:

- radar: ``sensor_msgs/PointCloud2``, little-endian float32 fields x, y, z, intensity,
  velocity (``RadarScan.doppler_mps``), 20-byte points, frame ``radar``. Decoding goes by the
  ``fields`` list (name, offset, datatype), so other layouts such as the TI driver's 32-byte
  points also read. Points with a NaN/inf coordinate, intensity or velocity are dropped and
  counted; a frame of only such points decodes to an empty scan.
- camera: ``sensor_msgs/Image`` mono8 plus ``CameraInfo`` (plumb_bob, zero distortion).
- depth: ``sensor_msgs/Image`` 16UC1 in millimetres, usually at reduced resolution; 0 means
  no depth. It decodes to float32 metres (NaN where 0) at the colour image's resolution,
  upsampled with nearest-neighbour ``cv2.resize`` so no depth is blended across an edge.
- IMU: ``sensor_msgs/Imu`` in ``base_link``; orientation unknown (covariance[0] = -1).
- ground truth: ``geometry_msgs/PoseStamped`` of ``base_link`` in ``map`` (planar pose as
  position + yaw quaternion) and ``nav_msgs/OccupancyGrid`` (100/0/-1). The grid's ``data``
  is row-major from the origin cell (lower-left), so it maps onto ``cells[iy, ix]`` directly.
- ``/tf_static``: ``tf2_msgs/TFMessage`` with ``base_link -> radar`` and
  ``base_link -> camera`` (each ``T_base_child``).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Iterable
from functools import cache
from typing import Any

import cv2
import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from smokyslam.errors import MessageError
from smokyslam.geometry import (
    GridSpec,
    quat_wxyz_from_rotation_matrix,
    quat_wxyz_from_xyzw,
    quat_wxyz_from_yaw,
    quat_xyzw_from_wxyz,
    se3_matrix,
    yaw_from_quat_wxyz,
)
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthPose,
    ImuSample,
    RadarScan,
)

logger = logging.getLogger(__name__)

FRAME_MAP, FRAME_BASE, FRAME_RADAR, FRAME_CAMERA = "map", "base_link", "radar", "camera"

STREAM_MSGTYPES: dict[str, str] = {
    "radar": "sensor_msgs/msg/PointCloud2",
    "camera_image": "sensor_msgs/msg/Image",
    "camera_info": "sensor_msgs/msg/CameraInfo",
    "camera_depth": "sensor_msgs/msg/Image",
    "imu": "sensor_msgs/msg/Imu",
    "ground_truth_pose": "geometry_msgs/msg/PoseStamped",
    "ground_truth_map": "nav_msgs/msg/OccupancyGrid",
    "tf_static": "tf2_msgs/msg/TFMessage",
}
"""Message type of every stream named in ``TopicsConfig``."""

# sensor_msgs/PointField datatype codes -> numpy kinds (byte order added per message).
_POINTFIELD_KINDS = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_RADAR_FIELDS = ("x", "y", "z", "intensity", "velocity")
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
        dtype = np.dtype([(name, "<f4") for name in _RADAR_FIELDS])
        points = np.empty(len(scan), dtype=dtype)
        points["x"], points["y"], points["z"] = scan.points_xyz_m.T
        points["intensity"] = scan.intensity
        points["velocity"] = scan.doppler_mps
        fields = [
            point_field(name=name, offset=dtype.fields[name][1], datatype=7, count=1)
            for name in _RADAR_FIELDS
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


# ---------------------------------------------------------------- decoding


def _point_dtype(msg: Any, names: Iterable[str]) -> np.dtype:
    """Structured dtype reading the named PointField entries that the cloud has."""
    order = ">" if msg.is_bigendian else "<"
    formats, offsets, present = [], [], []
    for field in msg.fields:
        if field.name not in names:
            continue
        kind = _POINTFIELD_KINDS.get(int(field.datatype))
        if kind is None:
            raise MessageError(
                f"PointCloud2 field '{field.name}' has unknown datatype {field.datatype}"
            )
        count = max(int(field.count), 1)
        if field.offset + np.dtype(kind).itemsize * count > msg.point_step:
            raise MessageError(
                f"PointCloud2 field '{field.name}' (offset {field.offset}) overruns "
                f"point_step {msg.point_step}"
            )
        present.append(field.name)
        formats.append((order + kind, (count,)) if count > 1 else order + kind)
        offsets.append(int(field.offset))
    return np.dtype(
        {"names": present, "formats": formats, "offsets": offsets, "itemsize": msg.point_step}
    )


def radar_scan_from_pointcloud2(msg: Any, stamp_s: float) -> tuple[RadarScan, int]:
    """Decode a PointCloud2 into a RadarScan, and the number of non-finite points dropped.

    Fields are found by name in ``msg.fields`` (any offset, datatype, byte order, row padding).
    x and y are required; z, intensity and velocity default to 0 when absent.
    Raises MessageError on a truncated buffer, a missing x/y field or a bad field layout.
    """
    dtype = _point_dtype(msg, _RADAR_FIELDS)
    if "x" not in dtype.names or "y" not in dtype.names:
        have = ", ".join(field.name for field in msg.fields) or "none"
        raise MessageError(f"PointCloud2 lacks x/y fields (has: {have})")
    width, height, step = int(msg.width), int(msg.height), int(msg.point_step)
    row_step = int(msg.row_step) if height > 1 else width * step
    needed = (height - 1) * row_step + width * step if width * height else 0
    if row_step < width * step or len(msg.data) < needed:
        raise MessageError(
            f"PointCloud2 data truncated: {len(msg.data)} bytes for {width}x{height} points "
            f"of {step} bytes (row_step {msg.row_step})"
        )
    raw = np.asarray(msg.data, dtype=np.uint8).reshape(-1)[:needed]
    if height > 1:
        raw = np.lib.stride_tricks.as_strided(raw, (height, width * step), (row_step, 1))
    points = np.ascontiguousarray(raw).reshape(-1).view(dtype)

    def column(name: str) -> np.ndarray:
        if name not in dtype.names:
            return np.zeros(len(points))
        values = points[name]
        return np.asarray(values[:, 0] if values.ndim > 1 else values, dtype=np.float64)

    xyz = np.stack([column("x"), column("y"), column("z")], axis=1)
    intensity, doppler = column("intensity"), column("velocity")
    finite = np.isfinite(xyz).all(axis=1) & np.isfinite(intensity) & np.isfinite(doppler)
    scan = RadarScan(
        stamp_s=stamp_s,
        points_xyz_m=xyz[finite],
        intensity=intensity[finite],
        doppler_mps=doppler[finite],
        frame_id=msg.header.frame_id or FRAME_RADAR,
    )
    return scan, int((~finite).sum())


def _image_pixels(msg: Any, dtype: np.dtype, channels: int) -> np.ndarray:
    """(H, W[, C]) array of an Image's rows, honouring ``step`` padding and byte order."""
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row_bytes = width * channels * dtype.itemsize
    if step < row_bytes or len(msg.data) < height * step:
        raise MessageError(
            f"Image data truncated: {len(msg.data)} bytes for {width}x{height} '{msg.encoding}'"
        )
    rows = np.asarray(msg.data, dtype=np.uint8)[: height * step].reshape(height, step)
    order = ">" if msg.is_bigendian else "<"
    pixels = np.ascontiguousarray(rows[:, :row_bytes]).view(dtype.newbyteorder(order))
    shape = (height, width, channels) if channels > 1 else (height, width)
    return pixels.reshape(shape)


def image_from_msg(msg: Any) -> np.ndarray:
    """(H, W) uint8 grey image of a mono8/8UC1, rgb8 or bgr8 ``sensor_msgs/Image``."""
    encoding = msg.encoding.lower()
    if encoding in ("mono8", "8uc1"):
        return _image_pixels(msg, np.dtype(np.uint8), 1).copy()
    if encoding in ("rgb8", "bgr8"):
        code = cv2.COLOR_RGB2GRAY if encoding == "rgb8" else cv2.COLOR_BGR2GRAY
        return cv2.cvtColor(_image_pixels(msg, np.dtype(np.uint8), 3), code)
    raise MessageError(f"unsupported camera image encoding '{msg.encoding}' (mono8, rgb8, bgr8)")


def depth_from_msg(msg: Any, shape_hw: tuple[int, int]) -> np.ndarray:
    """(H, W) float32 depth in metres (NaN where unknown) at ``shape_hw``.

    Accepts 16UC1/mono16 millimetres (0 = unknown) and 32FC1 metres; a depth image of another
    size is resized with nearest-neighbour interpolation.
    """
    encoding = msg.encoding.lower()
    if encoding in ("16uc1", "mono16"):
        millimetres = _image_pixels(msg, np.dtype(np.uint16), 1)
        depth_m = np.where(millimetres > 0, millimetres * np.float32(1e-3), np.nan)
    elif encoding == "32fc1":
        depth_m = _image_pixels(msg, np.dtype(np.float32), 1)
    else:
        raise MessageError(f"unsupported depth encoding '{msg.encoding}' (16UC1, 32FC1)")
    depth_m = depth_m.astype(np.float32)
    if depth_m.shape != tuple(shape_hw):
        size = (int(shape_hw[1]), int(shape_hw[0]))
        depth_m = cv2.resize(depth_m, size, interpolation=cv2.INTER_NEAREST)
    return depth_m


def intrinsics_from_camera_info(msg: Any) -> CameraIntrinsics:
    """Pinhole intrinsics (pixels) from ``CameraInfo.K`` (ROS1) or ``k`` (ROS2)."""
    k = np.asarray(msg.K if hasattr(msg, "K") else msg.k, dtype=float)
    if k.size != 9 or k[0] <= 0.0 or k[4] <= 0.0:
        raise MessageError(f"CameraInfo has no valid camera matrix (K = {k.tolist()})")
    return CameraIntrinsics(
        width=int(msg.width),
        height=int(msg.height),
        fx=float(k[0]),
        fy=float(k[4]),
        cx=float(k[2]),
        cy=float(k[5]),
    )


def imu_from_msg(msg: Any, stamp_s: float) -> ImuSample:
    """ImuSample (rad/s, m/s^2) of a ``sensor_msgs/Imu``."""
    w, a = msg.angular_velocity, msg.linear_acceleration
    return ImuSample(
        stamp_s=stamp_s,
        gyro_radps=np.array([w.x, w.y, w.z], dtype=float),
        accel_mps2=np.array([a.x, a.y, a.z], dtype=float),
    )


def _yaw_of(orientation: Any) -> float:
    q_xyzw = np.array([orientation.x, orientation.y, orientation.z, orientation.w], dtype=float)
    return float(yaw_from_quat_wxyz(quat_wxyz_from_xyzw(q_xyzw)))


def ground_truth_pose_from_msg(msg: Any, stamp_s: float) -> GroundTruthPose:
    """Planar ``[x, y, yaw]`` of a ``geometry_msgs/PoseStamped`` (z, roll, pitch dropped)."""
    pose = msg.pose
    yaw_rad = _yaw_of(pose.orientation)
    return GroundTruthPose(stamp_s, np.array([pose.position.x, pose.position.y, yaw_rad]))


def ground_truth_map_from_msg(msg: Any, stamp_s: float) -> GroundTruthMap:
    """``cells[iy, ix]`` int8 and grid geometry of a ``nav_msgs/OccupancyGrid``.

    Raises MessageError on a rotated origin or a data length that does not match the size.
    """
    info = msg.info
    rows, cols = int(info.height), int(info.width)
    data = np.asarray(msg.data, dtype=np.int8)
    if data.size != rows * cols:
        raise MessageError(f"OccupancyGrid has {data.size} cells for {cols}x{rows}")
    if abs(_yaw_of(info.origin.orientation)) > 1e-6:
        raise MessageError("OccupancyGrid with a rotated origin is not supported")
    # resolution is float32 on the wire: its shortest decimal form recovers e.g. 0.1 exactly.
    resolution_m = float(str(np.float32(info.resolution)))
    spec = GridSpec(
        origin_xy_m=(float(info.origin.position.x), float(info.origin.position.y)),
        resolution_m=resolution_m,
        shape=(rows, cols),
    )
    return GroundTruthMap(stamp_s, data.reshape(rows, cols).copy(), spec)


def extrinsics_from_tf(transforms: Iterable[Any]) -> Extrinsics:
    """``T_base_radar`` / ``T_base_camera`` from ``TransformStamped`` messages.

    Chains of static transforms (``base_link -> rig -> radar``) are composed; a sensor frame
    that does not reach ``base_link`` keeps the identity.
    """
    parent_of: dict[str, tuple[str, np.ndarray]] = {}
    for stamped in transforms:
        t, r = stamped.transform.translation, stamped.transform.rotation
        q_wxyz = quat_wxyz_from_xyzw(np.array([r.x, r.y, r.z, r.w], dtype=float))
        T = se3_matrix(np.array([t.x, t.y, t.z]), q_wxyz)
        parent_of[stamped.child_frame_id.lstrip("/")] = (stamped.header.frame_id.lstrip("/"), T)

    def base_from(child: str) -> np.ndarray:
        T, frame, seen = np.eye(4), child, set()
        while frame != FRAME_BASE:
            if frame not in parent_of or frame in seen:
                return np.eye(4)
            seen.add(frame)
            parent, T_parent_frame = parent_of[frame]
            T, frame = T_parent_frame @ T, parent
        return T

    return Extrinsics(T_base_radar=base_from(FRAME_RADAR), T_base_camera=base_from(FRAME_CAMERA))
