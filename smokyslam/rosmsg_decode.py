"""Conversions from ROS messages (rosbags message objects) to smokyslam frames.

Plain functions that accept messages from a ROS1 or a ROS2 typestore (field names are the same
except ``CameraInfo.K`` in ROS1 versus ``k`` in ROS2). Layouts, as :mod:`smokyslam.rosmsg`
writes them and as other publishers may:

- radar ``PointCloud2``: decoding goes by the ``fields`` list (name, offset, datatype), so other
  layouts such as the TI driver's 32-byte points also read. Points with a NaN/inf coordinate
  are dropped and counted (a frame of only such points decodes to an empty scan); a NaN/inf
  velocity is an unknown Doppler (NaN) for that point, a NaN/inf intensity reads 0. A cloud
  without a velocity field has unknown Doppler (NaN) everywhere.
- camera ``Image``: mono8/8UC1, rgb8 or bgr8, decoded to grey.
- depth ``Image``: 16UC1 millimetres (0 = no depth) or 32FC1 metres. It decodes to float32
  metres (NaN where unknown) at the colour image's resolution, upsampled with
  nearest-neighbour ``cv2.resize`` so no depth is blended across an edge.
- ``CameraInfo``, ``Imu``, ``PoseStamped`` (planar pose), ``OccupancyGrid`` (row-major from
  the lower-left origin cell) and ``/tf_static`` transforms (chains composed to ``base_link``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

import cv2
import numpy as np

from smokyslam.errors import MessageError
from smokyslam.geometry import GridSpec, quat_wxyz_from_xyzw, se3_matrix, yaw_from_quat_wxyz
from smokyslam.rosmsg import FRAME_BASE, FRAME_CAMERA, FRAME_RADAR, RADAR_FIELDS
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    GroundTruthMap,
    GroundTruthPose,
    ImuSample,
    RadarScan,
)

T = TypeVar("T")


def _malformed_is_a_message_error(decode: Callable[..., T]) -> Callable[..., T]:
    """A decoder whose message lacks a field or holds nonsense (a damaged log's message
    definitions, absurd sizes) raises MessageError, never AttributeError and the like."""

    @functools.wraps(decode)
    def checked(*args: Any, **kwargs: Any) -> T:
        try:
            return decode(*args, **kwargs)
        except MessageError:
            raise
        except (AttributeError, TypeError, ValueError, IndexError, KeyError, OverflowError) as exc:
            raise MessageError(f"malformed message ({type(exc).__name__}: {exc})") from None

    return checked


# sensor_msgs/PointField datatype codes -> numpy kinds (byte order added per message).
_POINTFIELD_KINDS = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


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


@_malformed_is_a_message_error
def radar_scan_from_pointcloud2(msg: Any, stamp_s: float) -> tuple[RadarScan, int, bool]:
    """Decode a PointCloud2 into a RadarScan; also the number of points dropped for a
    non-finite coordinate, and whether the cloud has a velocity field.

    Fields are found by name in ``msg.fields`` (any offset, datatype, byte order, row padding).
    x and y are required; z and intensity default to 0 when absent, velocity to NaN (unknown).
    Raises MessageError on a truncated buffer, a missing x/y field or a bad field layout.
    """
    dtype = _point_dtype(msg, RADAR_FIELDS)
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

    def column(name: str, missing: float) -> np.ndarray:
        if name not in dtype.names:
            return np.full(len(points), missing)
        values = points[name]
        return np.asarray(values[:, 0] if values.ndim > 1 else values, dtype=np.float64)

    xyz = np.stack([column("x", 0.0), column("y", 0.0), column("z", 0.0)], axis=1)
    intensity, doppler = column("intensity", 0.0), column("velocity", np.nan)
    finite = np.isfinite(xyz).all(axis=1)
    doppler = np.where(np.isfinite(doppler), doppler, np.nan)
    scan = RadarScan(
        stamp_s=stamp_s,
        points_xyz_m=xyz[finite],
        intensity=np.where(np.isfinite(intensity), intensity, 0.0)[finite],
        doppler_mps=doppler[finite],
        frame_id=msg.header.frame_id or FRAME_RADAR,
    )
    return scan, int((~finite).sum()), "velocity" in dtype.names


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


@_malformed_is_a_message_error
def image_from_msg(msg: Any) -> np.ndarray:
    """(H, W) uint8 grey image of a mono8/8UC1, rgb8 or bgr8 ``sensor_msgs/Image``."""
    encoding = msg.encoding.lower()
    if encoding in ("mono8", "8uc1"):
        return _image_pixels(msg, np.dtype(np.uint8), 1).copy()
    if encoding in ("rgb8", "bgr8"):
        code = cv2.COLOR_RGB2GRAY if encoding == "rgb8" else cv2.COLOR_BGR2GRAY
        return cv2.cvtColor(_image_pixels(msg, np.dtype(np.uint8), 3), code)
    raise MessageError(f"unsupported camera image encoding '{msg.encoding}' (mono8, rgb8, bgr8)")


@_malformed_is_a_message_error
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


@_malformed_is_a_message_error
def intrinsics_from_camera_info(msg: Any) -> CameraIntrinsics:
    """Pinhole intrinsics (pixels) from ``CameraInfo.K`` (ROS1) or ``k`` (ROS2)."""
    k = np.asarray(msg.K if hasattr(msg, "K") else msg.k, dtype=float)
    if k.size != 9 or not np.isfinite(k).all() or k[0] <= 0.0 or k[4] <= 0.0:
        raise MessageError(f"CameraInfo has no valid camera matrix (K = {k.tolist()})")
    return CameraIntrinsics(
        width=int(msg.width),
        height=int(msg.height),
        fx=float(k[0]),
        fy=float(k[4]),
        cx=float(k[2]),
        cy=float(k[5]),
    )


@_malformed_is_a_message_error
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


@_malformed_is_a_message_error
def ground_truth_pose_from_msg(msg: Any, stamp_s: float) -> GroundTruthPose:
    """Planar ``[x, y, yaw]`` of a ``geometry_msgs/PoseStamped`` (z, roll, pitch dropped)."""
    pose = msg.pose
    yaw_rad = _yaw_of(pose.orientation)
    return GroundTruthPose(stamp_s, np.array([pose.position.x, pose.position.y, yaw_rad]))


@_malformed_is_a_message_error
def ground_truth_map_from_msg(msg: Any, stamp_s: float) -> GroundTruthMap:
    """``cells[iy, ix]`` int8 and grid geometry of a ``nav_msgs/OccupancyGrid``.

    Raises MessageError on a rotated origin, a resolution or origin that is not a finite
    positive number, or a data length that does not match the size.
    """
    info = msg.info
    rows, cols = int(info.height), int(info.width)
    numbers = [info.resolution, info.origin.position.x, info.origin.position.y]
    if not (np.isfinite(numbers).all() and info.resolution > 0):
        raise MessageError(
            f"OccupancyGrid resolution {info.resolution} / origin "
            f"({info.origin.position.x}, {info.origin.position.y}) is not usable"
        )
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


@_malformed_is_a_message_error
def extrinsics_from_tf(transforms: Iterable[Any]) -> Extrinsics:
    """``T_base_radar`` / ``T_base_camera`` from ``TransformStamped`` messages.

    Chains of static transforms (``base_link -> rig -> radar``) are composed; a sensor frame
    that does not reach ``base_link`` keeps the identity.
    """
    parent_of: dict[str, tuple[str, np.ndarray]] = {}
    for stamped in transforms:
        t, r = stamped.transform.translation, stamped.transform.rotation
        child, parent = stamped.child_frame_id.lstrip("/"), stamped.header.frame_id.lstrip("/")
        translation = np.array([t.x, t.y, t.z], dtype=float)
        q_xyzw = np.array([r.x, r.y, r.z, r.w], dtype=float)
        norm = float(np.linalg.norm(q_xyzw))
        if not (np.isfinite(translation).all() and np.isfinite(q_xyzw).all() and norm > 0.5):
            raise MessageError(
                f"the static transform {parent} -> {child} cannot be used (translation "
                f"{translation.tolist()}, quaternion xyzw {q_xyzw.tolist()})"
            )
        T = se3_matrix(translation, quat_wxyz_from_xyzw(q_xyzw / norm))
        parent_of[child] = (parent, T)

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
