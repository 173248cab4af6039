"""Write smokyslam frames into a ROS log: ROS2 MCAP, ROS1 bag or ROS2 sqlite3, by suffix.

What lands on disk
------------------
- ``X.mcap``: ONE file, a rosbag2 MCAP (profile ``ros2``, CDR messages, message definitions
  embedded, rosbag2 metadata stored inside as an MCAP metadata record). rosbags' writer always
  makes a directory (``X.mcap/X.mcap.mcap`` + ``metadata.yaml``); since ``AnyReader`` reads a bare
  ``.mcap`` file (the standard single-file MCAP layout that MCAP viewers open), the writer
  works in a hidden temporary folder beside the target and moves the ``.mcap`` file into
  place, so the user gets the single file they named.
- ``X.bag``: a ROS1 bag (v2.0, uncompressed chunks).
- ``X.db3``: a bare rosbag2 sqlite3 file, made the same way as ``.mcap``.

The target appears only when the writer closes without error: a failed run leaves nothing
half-written (only a killed process can leave its hidden ``.X.mcap.*`` work folder behind).
An existing target is refused with LogError unless ``overwrite=True``, in which case it is
replaced at close.

Time: frames carry ``stamp_s`` in seconds from log start; header stamps and bag receive times
are ``EPOCH_OFFSET_NS + stamp_s`` in nanoseconds so the log looks like a real recording.
Each stream goes to the FIRST topic of its ``TopicsConfig`` list; topics are created on first
use, so a log holds only the streams that were written. ``/tf_static`` and the map are latched
(ROS1) / transient-local (ROS2), as ``rosbag record`` would store them.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from types import TracebackType
from typing import Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
from rosbags.interfaces import QosTime as _QosTime
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag1 import WriterError as WriterError1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.rosbag2 import WriterError as WriterError2

from smokyslam.config import TopicsConfig
from smokyslam.errors import LogError
from smokyslam.rosmsg import STREAM_MSGTYPES, MessageBuilder
from smokyslam.types import (
    CameraFrame,
    Extrinsics,
    GroundTruthMap,
    GroundTruthPose,
    ImuSample,
    RadarScan,
)

EPOCH_OFFSET_NS = 1_700_000_000 * 1_000_000_000
"""Log start on the wall clock (2023-11-14 22:13:20 UTC), added to every ``stamp_s``."""

_ROS2_PLUGINS = {".mcap": StoragePlugin.MCAP, ".db3": StoragePlugin.SQLITE3}
_LATCHED_STREAMS = frozenset({"tf_static", "ground_truth_map", "ground_truth_map_observed"})
_ZERO_TIME = _QosTime(0, 0)
_LATCHED_QOS = Qos(
    QosHistory.KEEP_LAST,
    1,
    QosReliability.RELIABLE,
    QosDurability.TRANSIENT_LOCAL,
    _ZERO_TIME,
    _ZERO_TIME,
    QosLiveliness.AUTOMATIC,
    _ZERO_TIME,
    False,
)


def stamp_ns_from_s(stamp_s: float) -> int:
    """Wall-clock nanoseconds of a log-relative stamp in seconds."""
    return EPOCH_OFFSET_NS + round(stamp_s * 1e9)


class LogWriter:
    """Context manager writing typed frames to ``path`` (``.mcap``, ``.bag`` or ``.db3``).

    Raises LogError for an unknown suffix, an existing target (without ``overwrite``) or a
    missing parent folder.
    """

    def __init__(self, path: Path | str, topics: TopicsConfig, overwrite: bool = False) -> None:
        self.path = Path(path)
        self.topics = topics
        self.overwrite = overwrite
        suffix = self.path.suffix.lower()
        if suffix != ".bag" and suffix not in _ROS2_PLUGINS:
            raise LogError(f"{self.path}: unknown log format '{suffix}' (use .mcap, .bag or .db3)")
        if self.path.exists() and not overwrite:
            raise LogError(f"{self.path} exists already (--overwrite replaces it)")
        if not self.path.parent.is_dir():
            raise LogError(f"{self.path}: folder {self.path.parent} does not exist")
        self._ros1 = suffix == ".bag"
        self._builder = MessageBuilder(ros1=self._ros1)
        self._connections: dict[str, Any] = {}
        self._tmpdir: Path | None = None
        self._writer: Writer1 | Writer2 | None = None

    # ------------------------------------------------------------ lifecycle

    def __enter__(self) -> LogWriter:
        self._tmpdir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        if self._ros1:
            self._writer = Writer1(self._tmpdir / self.path.name)
        else:
            plugin = _ROS2_PLUGINS[self.path.suffix.lower()]
            # rosbags names the storage file after the folder: <stem>/<stem>.mcap
            folder = self._tmpdir / self.path.stem
            self._writer = Writer2(folder, version=9, storage_plugin=plugin)
        self._writer.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self._abort()

    def close(self) -> None:
        """Finish the log and move it to ``path`` (replacing an old one if ``overwrite``)."""
        assert self._writer is not None and self._tmpdir is not None, "writer is not open"
        try:
            self._writer.close()
            if self._ros1:
                written = self._tmpdir / self.path.name
            else:
                stem = self.path.stem
                written = self._tmpdir / stem / f"{stem}{self.path.suffix.lower()}"
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
            written.replace(self.path)
        except (WriterError1, WriterError2, OSError) as exc:
            raise LogError(f"{self.path}: could not write log ({exc})") from exc
        finally:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._writer = None

    def _abort(self) -> None:
        if self._writer is not None:
            self._writer.abort()
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
        self._writer = None

    # ------------------------------------------------------------ one verb per stream

    def write_radar(self, scan: RadarScan) -> None:
        """One PointCloud2 (x, y, z, intensity, velocity as float32) on the radar topic."""
        stamp_ns = stamp_ns_from_s(scan.stamp_s)
        self._write("radar", self._builder.pointcloud2(scan, stamp_ns), stamp_ns)

    def write_camera(self, frame: CameraFrame, depth_scale: int) -> None:
        """Image (mono8), CameraInfo (when intrinsics are set) and depth (16UC1 mm, at
        1/``depth_scale`` resolution, when ``frame.depth_m`` is set), all at one stamp."""
        stamp_ns = stamp_ns_from_s(frame.stamp_s)
        self._write("camera_image", self._builder.image(frame.image, "mono8", stamp_ns), stamp_ns)
        if frame.intrinsics is not None:
            info = self._builder.camera_info(frame.intrinsics, stamp_ns)
            self._write("camera_info", info, stamp_ns)
        if frame.depth_m is not None:
            depth = self._builder.depth_image(frame.depth_m, depth_scale, stamp_ns)
            self._write("camera_depth", depth, stamp_ns)

    def write_imu(self, sample: ImuSample) -> None:
        """One sensor_msgs/Imu (gyro rad/s, accel m/s^2) in base_link."""
        stamp_ns = stamp_ns_from_s(sample.stamp_s)
        self._write("imu", self._builder.imu(sample, stamp_ns), stamp_ns)

    def write_ground_truth_pose(self, pose: GroundTruthPose) -> None:
        """One PoseStamped of base_link in map."""
        stamp_ns = stamp_ns_from_s(pose.stamp_s)
        self._write("ground_truth_pose", self._builder.pose_stamped(pose, stamp_ns), stamp_ns)

    def write_ground_truth_map(self, map: GroundTruthMap, observed: bool = False) -> None:
        """The ground-truth OccupancyGrid (100 / 0 / -1) in map; ``observed``: the one a lidar
        recorded along the walk (``sim/observed.py``), on its own topic."""
        stamp_ns = stamp_ns_from_s(map.stamp_s)
        stream = "ground_truth_map_observed" if observed else "ground_truth_map"
        self._write(stream, self._builder.occupancy_grid(map, stamp_ns), stamp_ns)

    def write_tf_static(self, extrinsics: Extrinsics, stamp_s: float) -> None:
        """base_link -> radar and base_link -> camera on /tf_static."""
        stamp_ns = stamp_ns_from_s(stamp_s)
        self._write("tf_static", self._builder.tf_static(extrinsics, stamp_ns), stamp_ns)

    # ------------------------------------------------------------ internals

    def _write(self, stream: str, msg: Any, stamp_ns: int) -> None:
        if self._writer is None:
            raise LogError(f"{self.path}: writer is not open (use it as a context manager)")
        connection = self._connections.get(stream) or self._add_connection(stream)
        self._writer.write(connection, stamp_ns, self._builder.serialize(msg))

    def _add_connection(self, stream: str) -> Any:
        candidates = getattr(self.topics, stream)
        if not candidates:
            raise LogError(f"no topic configured for stream '{stream}' (topics.{stream})")
        msgtype, latched = STREAM_MSGTYPES[stream], stream in _LATCHED_STREAMS
        store = self._builder.typestore
        assert self._writer is not None
        if isinstance(self._writer, Writer1):
            connection = self._writer.add_connection(
                candidates[0], msgtype, typestore=store, latching=int(latched)
            )
        else:
            qos = [_LATCHED_QOS] if latched else []
            connection = self._writer.add_connection(
                candidates[0], msgtype, typestore=store, offered_qos_profiles=qos
            )
        self._connections[stream] = connection
        return connection
