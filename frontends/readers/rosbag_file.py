"""A ROS1 or ROS2 log file as messages: opening it, surviving its damage, and its clock.

:class:`RosbagFile` is what :class:`~smokyslam.frontends.readers.rosbag.RosbagReader` reads
its typed frames from. Whatever a damaged file makes rosbags raise (its own errors, but also
UnicodeDecodeError, OverflowError, KeyError, ...) becomes one LogError line naming the file;
a file that cannot be opened because its index is cut off is salvaged (``salvage.py``); a
message that does not decode is skipped and counted; where the file breaks off mid-read, the
messages before the damage are used and the damage is reported (``damage``), as rosbag's own
reindex would. Messages come in log-time order, or in header-stamp order when the log time
itself is broken (``clock.py``).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import weakref
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as ReaderError1
from rosbags.rosbag2 import ReaderError as ReaderError2

from smokyslam.errors import LogError, SmokySlamError
from smokyslam.frontends.readers.base import LogSummary, StreamSummary
from smokyslam.frontends.readers.clock import ClockChoice, in_header_order, log_clock
from smokyslam.frontends.readers.salvage import SalvagedLog
from smokyslam.rosmsg import typestore_for

logger = logging.getLogger(__name__)

_READ_ERRORS = (AnyReaderError, ReaderError1, ReaderError2)
NS = 1e-9


def _closed(reader: AnyReader | None) -> None:
    """Close ``reader`` (if any) and give None, so ``reader = _closed(reader)`` forgets it: a
    reader that failed is not kept for the next use."""
    if reader is not None:
        with contextlib.suppress(Exception):
            reader.close()


def _close_all(readers: list[AnyReader]) -> None:
    while readers:
        _closed(readers.pop())


def format_of(path: Path) -> str:
    if path.is_dir():
        return "ROS2 folder"
    return {".bag": "ROS1 bag", ".mcap": "ROS2 MCAP", ".db3": "ROS2 sqlite3"}.get(
        path.suffix.lower(), "rosbag"
    )


class RosbagFile:
    """One log file; ``types`` (topic -> message type) is read at construction."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.format = format_of(path)
        self.ros1 = path.suffix.lower() == ".bag"
        self._store = typestore_for(ros1=self.ros1)
        self._salvaged: SalvagedLog | None = None
        self._clock: ClockChoice | None = None
        self.damage: str | None = None
        """Where the file breaks off, when it does (what was read before is used)."""
        self.undecodable = 0
        """Messages skipped because they did not decode."""
        self._idle: list[AnyReader] = []  # at most one open reader, kept for the next use
        self._lock = threading.Lock()
        weakref.finalize(self, _close_all, self._idle)
        with self.open() as reader:
            self.types = {topic: info.msgtype or "?" for topic, info in reader.topics.items()}

    @contextmanager
    def open(self) -> Iterator[AnyReader | SalvagedLog]:
        """An open AnyReader (or the salvaged records); every failure is one LogError.

        Opening costs about 55 ms (rosbags parses every message definition and QoS profile
        of the file), and a run asks about ten times (truth, maps, calibration, frames), so
        a reader is kept open for the next use once this one ends; a use while another is
        under way (a generator paused mid-log) opens its own."""
        if self._salvaged is not None:
            yield self._salvaged
            return
        reader, opened = self._take(), False
        try:
            if reader is None:
                reader = AnyReader([self.path], default_typestore=self._store)
                reader.open()
            opened = True
            yield reader
        except SmokySlamError:
            reader = _closed(reader)
            raise
        except FileNotFoundError:
            reader = _closed(reader)
            raise LogError(f"log not found: {self.path}") from None
        except Exception as exc:  # a damaged file can break the parser anywhere
            reader = _closed(reader)
            detail = str(exc) if isinstance(exc, _READ_ERRORS) else type(exc).__name__
            error = LogError(
                f"{self.path}: cannot read {self.format}, truncated or corrupt ({detail})"
            )
            if opened or self.path.is_dir():
                raise error from None
            self._salvage(error)
        finally:
            if reader is not None:
                self._keep(reader)
        if self._salvaged is not None and not opened:
            yield self._salvaged

    def close(self) -> None:
        """Close the reader kept open (the next use opens the file again)."""
        with self._lock:
            _close_all(self._idle)

    def _take(self) -> AnyReader | None:
        with self._lock:
            return self._idle.pop() if self._idle else None

    def _keep(self, reader: AnyReader) -> None:
        with self._lock:
            if not self._idle:
                self._idle.append(reader)
                return
        reader.close()

    def _salvage(self, error: LogError) -> None:
        salvaged = SalvagedLog(self.path, self._store)
        if not salvaged.message_count:
            raise error from None
        self._salvaged = salvaged
        self.damage = f"no index: {salvaged.message_count} messages salvaged in file order"
        if salvaged.cut:
            self.damage += f" up to where the records break off ({salvaged.cut})"
        logger.warning("%s: %s", self.path, self.damage)

    def messages(
        self, topics: Collection[str], clock_topics: Collection[str]
    ) -> Iterator[tuple[str, float, Any]]:
        """(topic, stamp_s from the log start, decoded message) of ``topics``, in order; the
        order's clock is decided once, from ``clock_topics`` (the streams with headers)."""
        if not topics:
            return
        clock = self.clock(clock_topics) if clock_topics else ClockChoice("log")
        read, stamp_s = 0, 0.0
        try:
            with self.open() as reader:
                start_ns = reader.start_time
                wanted = [c for c in reader.connections if c.topic in topics]
                messages = reader.messages(connections=wanted)
                if clock.order == "header":
                    messages = in_header_order(messages, clock.offset_ns, self.ros1)
                for connection, log_ns, raw in messages:
                    stamp_s = (log_ns - start_ns) * NS
                    msg = self._deserialize(reader, raw, connection.msgtype, stamp_s)
                    if msg is not None:
                        read += 1
                        yield connection.topic, stamp_s, msg
        except LogError as exc:
            if read == 0:
                raise
            self.damage = f"damaged after {stamp_s:.2f} s of log ({read} messages read): {exc}"
            logger.warning("%s: %s", self.path, self.damage)

    def time_origin_s(self, clock_topics: Collection[str]) -> float:
        """Seconds since the epoch of ``stamp_s`` 0 on the log's own clock: the first message's
        log time, moved onto the header clock when the log is read in header order (so
        stamps match the messages' header stamps, as TUM files and evo expect)."""
        with self.open() as reader:
            start_ns = reader.start_time if reader.message_count else 0
        clock = self.clock(clock_topics) if clock_topics else ClockChoice("log")
        offset_ns = clock.offset_ns if clock.order == "header" else 0
        return (start_ns + offset_ns) * NS

    def clock(self, topics: Collection[str]) -> ClockChoice:
        """How this log is ordered, decided once from the raw header stamps of ``topics``."""
        if self._clock is None:
            try:
                with self.open() as reader:
                    self._clock = log_clock(reader, topics, self.ros1)
            except LogError:  # a damaged log: read in log order, its damage reported then
                self._clock = ClockChoice("log")
            if self._clock.reason:
                logger.warning("%s: %s", self.path, self._clock.reason)
        return self._clock

    def _deserialize(self, reader: Any, raw: bytes, msgtype: str, stamp_s: float) -> Any:
        """One decoded message, or None (counted, the first one logged) if it is damaged."""
        try:
            return reader.deserialize(raw, msgtype)
        except Exception as exc:  # a damaged message can break the decoder anywhere
            self.undecodable += 1
            if self.undecodable == 1:
                logger.warning(
                    "%s: a %s at %.2f s does not decode (%s); damaged messages are skipped",
                    self.path,
                    msgtype,
                    stamp_s,
                    type(exc).__name__,
                )
            return None

    def summary(self) -> LogSummary:
        """Every topic with its type, count and rate (from its own first/last log time); of a
        damaged log, what can be read before the damage (``damage`` says where)."""
        spans: dict[str, list[int]] = {}
        types: dict[str, str] = {}
        start_ns, damage = 0, None
        try:
            with self.open() as reader:
                start_ns = reader.start_time if reader.message_count else 0
                types = {topic: info.msgtype or "?" for topic, info in reader.topics.items()}
                for connection, log_ns, _ in reader.messages():
                    span = spans.setdefault(connection.topic, [log_ns, log_ns, 0])
                    span[1], span[2] = log_ns, span[2] + 1
        except LogError as exc:
            if not types:
                raise
            read = sum(span[2] for span in spans.values())
            damage = f"damaged: {read} messages read before it breaks off ({exc})"
        streams = []
        for topic, msgtype in sorted(types.items()):
            first, last, count = spans.get(topic, [0, 0, 0])
            rate_hz = (count - 1) / ((last - first) * NS) if last > first else 0.0
            streams.append(StreamSummary(topic, msgtype, count, rate_hz))
        last_ns = max((span[1] for span in spans.values()), default=start_ns)
        return LogSummary(
            path=self.path,
            format=self.format,
            duration_s=(last_ns - start_ns) * NS,
            start_s=start_ns * NS,
            streams=streams,
            damage=damage or (f"damaged: {self.damage}" if self.damage else None),
        )
