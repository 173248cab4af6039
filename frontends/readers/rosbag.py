"""ROS1 bags and ROS2 logs (MCAP or sqlite3, bare file or rosbag2 folder) via rosbags.

Streams and topics: every stream of ``TopicsConfig`` lists candidate topics; the first one
present in the log with the expected message type is used.

Time: every frame is stamped with its message's log (receive) time minus the log's first
message time, so ``stamp_s`` starts at 0. Header stamps are not used for time because real
logs mix clocks (the TI radar driver leaves them at 0; the IMU of the demo bag runs 4 days off
the bag clock), except where the log time itself is broken (``clock.py``). smokyslam's own
logs write header stamp = log time, so nothing is lost.

Camera: images carry the intrinsics of the latest ``CameraInfo`` (the first one in the log
before any arrives) and are paired with their depth images (``camera_pairing.py``). Messages
are decoded one at a time as the log is read (``rosbag_file.py``: damage, salvage, clock);
what cannot be used (NaN samples, images of the wrong size) is dropped and counted at this
boundary (``checks.py``), and time jumps reported.
"""

from __future__ import annotations

import logging
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from smokyslam.config import TopicsConfig
from smokyslam.errors import MessageError, TopicError
from smokyslam.frontends.readers.base import SENSOR_STREAMS, LogSummary
from smokyslam.frontends.readers.camera_pairing import FrameAssembler
from smokyslam.frontends.readers.checks import StreamChecks
from smokyslam.frontends.readers.rosbag_file import NS, RosbagFile
from smokyslam.rosmsg import STREAM_MSGTYPES, header_stamp_ns
from smokyslam.rosmsg_decode import (
    extrinsics_from_tf,
    ground_truth_map_from_msg,
    ground_truth_pose_from_msg,
    imu_from_msg,
    intrinsics_from_camera_info,
    radar_scan_from_pointcloud2,
)
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    Frame,
    GroundTruthMap,
    GroundTruthPose,
    GroundTruthTrajectory,
)

logger = logging.getLogger(__name__)


class RosbagReader:
    """A ROS1/ROS2 log opened for replay (see the module docstring for time and pairing)."""

    def __init__(
        self,
        path: Path | str,
        topics: TopicsConfig,
        extrinsics: Extrinsics | None = None,
        max_gap_s: float | None = None,
    ) -> None:
        """``extrinsics``: the sensor mounting to report instead of the log's /tf_static
        (e.g. from a radar calibration YAML). ``max_gap_s``: log-time jumps within a stream
        longer than this are reported (``log.max_gap_s``; None: not checked)."""
        self.path = Path(path)
        self.topics = topics
        self._extrinsics = extrinsics
        self._file = RosbagFile(self.path)
        self.format = self._file.format
        self.max_gap_s = max_gap_s
        self.checks: StreamChecks | None = None
        """The checks of the latest ``frames()`` pass (what was dropped, time anomalies)."""
        self._intrinsics: CameraIntrinsics | None = None
        self._intrinsics_read = False
        self._truth: tuple[GroundTruthTrajectory | None] | None = None  # read once, then kept
        self._time_origin_s: float | None = None
        self._log_types = self._file.types
        self.stream_topics = self._resolve_streams()

    def _resolve_streams(self) -> dict[str, str]:
        streams = {}
        for stream, msgtype in STREAM_MSGTYPES.items():
            for topic in getattr(self.topics, stream):
                if self._log_types.get(topic) == msgtype:
                    streams[stream] = topic
                    break
                if topic in self._log_types:
                    logger.warning(
                        "%s: topic %s has type %s, not %s; skipped for %s",
                        self.path,
                        topic,
                        self._log_types[topic],
                        msgtype,
                        stream,
                    )
        return streams

    def require(self, *streams: str) -> None:
        """Raise TopicError unless the log holds every named stream (``TopicsConfig`` names)."""
        for stream in streams:
            if stream not in STREAM_MSGTYPES:
                raise TopicError(f"unknown stream '{stream}' (one of {', '.join(STREAM_MSGTYPES)})")
            if stream in self.stream_topics:
                continue
            wanted = ", ".join(getattr(self.topics, stream)) or "none configured"
            have = ", ".join(f"{t} ({m})" for t, m in sorted(self._log_types.items())) or "none"
            raise TopicError(
                f"{self.path}: no {stream} topic of type {STREAM_MSGTYPES[stream]} "
                f"(looked for: {wanted}; log has: {have})"
            )

    def _messages(self, *streams: str) -> Iterator[tuple[str, float, Any]]:
        """(stream, stamp_s from the log start, decoded message) of the named streams."""
        by_topic = {self.stream_topics[s]: s for s in streams if s in self.stream_topics}
        once = {"tf_static", "ground_truth_map", "ground_truth_map_observed"}
        clock_topics = [] if set(streams) <= once else self._clock_topics()
        for topic, stamp_s, msg in self._file.messages(by_topic, clock_topics):
            yield by_topic[topic], stamp_s, msg

    def _clock_topics(self) -> list[str]:
        """The topics whose header stamps decide the log's clock."""
        clocked = (*SENSOR_STREAMS, "ground_truth_pose")
        return [self.stream_topics[s] for s in clocked if s in self.stream_topics]

    # ------------------------------------------------------------ LogReader protocol

    def summary(self) -> LogSummary:
        """Every topic with its type, count and rate; of a damaged log, what can be read."""
        return self._file.summary()

    def log_time_s(self, stamps_s: np.ndarray) -> np.ndarray:
        """Stamps from the log start on the log's own clock (seconds since the epoch)."""
        if self._time_origin_s is None:
            self._time_origin_s = self._file.time_origin_s(self._clock_topics())
        return np.asarray(stamps_s, dtype=float) + self._time_origin_s

    @property
    def damage(self) -> str | None:
        """Where the file breaks off, when it does (what was read before is used)."""
        return self._file.damage

    def problems(self) -> dict[str, object]:
        counts = self.checks.counts if self.checks is not None else {}
        found: dict[str, object] = {kind: n for kind, n in counts.items() if n}
        if self._file.undecodable:
            found["undecodable_messages"] = self._file.undecodable
        if self.damage:
            found["damage"] = self.damage
        return found

    def camera_intrinsics(self) -> CameraIntrinsics | None:
        """Intrinsics of the first usable CameraInfo message, or None without one."""
        if not self._intrinsics_read:
            self._intrinsics_read = True
            for _, stamp_s, msg in self._messages("camera_info"):
                try:
                    self._intrinsics = intrinsics_from_camera_info(msg)
                    break
                except MessageError as exc:
                    logger.warning("%s: camera_info at %.2f s skipped: %s", self.path, stamp_s, exc)
        return self._intrinsics

    def extrinsics(self) -> Extrinsics:
        """Sensor mounting rebuilt from /tf_static; identity for frames it does not hold. The
        mounting given at construction, if any, replaces it."""
        if self._extrinsics is not None:
            return self._extrinsics
        transforms = [t for _, _, msg in self._messages("tf_static") for t in msg.transforms]
        if not transforms:
            logger.info("%s: no static transforms; sensors taken at base_link", self.path)
        try:
            self._extrinsics = extrinsics_from_tf(transforms)
        except MessageError as exc:
            raise MessageError(f"{self.path}: /tf_static: {exc}") from None
        return self._extrinsics

    def ground_truth_map(self) -> GroundTruthMap | None:
        """The last usable ground-truth OccupancyGrid in the log, or None (an unusable one, e.g.
        with a NaN resolution, is left out with a warning)."""
        return self._last_map("ground_truth_map")

    def observed_ground_truth_map(self) -> GroundTruthMap | None:
        """The ground truth a lidar recorded along the walk (``/ground_truth/map_observed``),
        or None (real and older logs)."""
        return self._last_map("ground_truth_map_observed")

    def _last_map(self, stream: str) -> GroundTruthMap | None:
        latest = None
        for _, stamp_s, msg in self._messages(stream):  # any damage: MessageError
            try:
                latest = ground_truth_map_from_msg(msg, stamp_s)
            except MessageError as exc:
                logger.warning(
                    "%s: ground-truth map at %.2f s left out: %s", self.path, stamp_s, exc
                )
        return latest

    def ground_truth_trajectory(self) -> GroundTruthTrajectory | None:
        """Every finite ground-truth pose of the log, sorted by stamp (repeated stamps kept
        once), or None when it has none; non-finite or malformed poses are dropped with a
        warning."""
        if self._truth is None:
            self._truth = (self._read_ground_truth(),)
        return self._truth[0]

    def _read_ground_truth(self) -> GroundTruthTrajectory | None:
        stamps, poses = [], []
        for _, stamp_s, msg in self._messages("ground_truth_pose"):
            try:
                pose = ground_truth_pose_from_msg(msg, stamp_s)
            except MessageError:
                pose = GroundTruthPose(stamp_s, np.full(3, np.nan))  # dropped below
            stamps.append(pose.stamp_s)
            poses.append(pose.pose_world_base)
        if not stamps:
            return None
        poses_array = np.asarray(poses, dtype=float).reshape(-1, 3)
        finite = np.isfinite(poses_array).all(axis=1)
        if not finite.all():
            logger.warning(
                "%s: %d ground-truth poses with NaN/inf values or malformed dropped",
                self.path,
                (~finite).sum(),
            )
        if not finite.any():
            return None
        stamps_s, first = np.unique(np.asarray(stamps, dtype=float)[finite], return_index=True)
        return GroundTruthTrajectory(stamps_s, poses_array[finite][first])

    def frames(self, streams: Collection[str] | None = None) -> Iterator[Frame]:
        """Radar, camera (with intrinsics and paired depth) and IMU frames; ``streams``: only
        these (``SENSOR_STREAMS`` names; None: all). Never ground truth."""
        wanted = set(SENSOR_STREAMS if streams is None else streams)
        if unknown := wanted - set(SENSOR_STREAMS):
            raise TopicError(f"unknown sensor streams {sorted(unknown)}: {SENSOR_STREAMS}")
        if "camera_image" in wanted:
            wanted.add("camera_info")
        else:
            wanted.discard("camera_depth")
        has_depth = "camera_depth" in wanted and "camera_depth" in self.stream_topics
        if not has_depth:
            wanted.discard("camera_depth")
        assembler = FrameAssembler(self.camera_intrinsics(), has_depth)
        checks = StreamChecks(self.path, self.max_gap_s)
        self.checks = checks
        streams = [s for s in STREAM_MSGTYPES if s in wanted]
        for stream, stamp_s, msg in self._messages(*streams):
            topic = self.stream_topics[stream]
            try:
                checks.time(topic, stamp_s, header_stamp_ns(msg) * NS)
                self._dispatch(assembler, checks, stream, stamp_s, msg)
            except MessageError as exc:
                checks.bad_message(topic, f"{topic} at {stamp_s:.3f} s: {exc}")
            else:
                checks.good_message(topic)
            yield from assembler.release(stamp_s)
        yield from assembler.release(float("inf"))
        checks.report()
        if unusable := checks.unusable_topic():
            raise MessageError(f"{self.path}: no {unusable} message could be used")

    def _dispatch(
        self,
        assembler: FrameAssembler,
        checks: StreamChecks,
        stream: str,
        stamp_s: float,
        msg: Any,
    ) -> None:
        if stream == "radar":
            assembler.push(checks.radar(*radar_scan_from_pointcloud2(msg, stamp_s)))
        elif stream == "camera_info":
            assembler.intrinsics = intrinsics_from_camera_info(msg)
        elif stream == "camera_image":
            assembler.push_image(msg, stamp_s, checks)
        elif stream == "camera_depth":
            assembler.push_depth(msg, stamp_s)
        elif (sample := checks.imu(imu_from_msg(msg, stamp_s))) is not None:
            assembler.push(sample)
