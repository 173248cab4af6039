"""Which clock orders a log: the time it was logged (normal), or its header stamps.

A log is read in log (receive) time. Header stamps are not trusted by default because real
logs mix clocks (the TI radar driver leaves them at 0, the demo bag's IMU runs days off).
But when the log time itself is broken (messages logged out of order, so that a stream's
header stamps run backwards in log order) while every stream's header stamps exist and keep
one offset to the log time, the header stamps are the sane order: the log is then read by
them, and the reader says so.

The decision is made from the raw bytes of every message (no decoding): the sensor messages
smokyslam reads all start with a ``std_msgs/Header`` (ROS1: seq, secs, nsecs; ROS2 CDR: a
4-byte encapsulation, then sec, nanosec).
"""

from __future__ import annotations

import struct
from collections.abc import Collection, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

BACKWARDS_NS = 500_000_000
"""A stream's header stamps running back more than this in log order: the log time is off."""

SAME_CLOCK_NS = 1_000_000_000
"""Streams whose header-minus-log offsets differ by more than this run on different clocks."""


def raw_header_stamp_ns(raw: bytes | memoryview, ros1: bool) -> int:
    """The header stamp of a serialized message that starts with a Header, ns (0 if none)."""
    try:
        if ros1:
            secs, nsecs = struct.unpack_from("<II", raw, 4)
        else:
            order = "<" if bytes(raw[1:2]) in (b"\x01", b"\x03") else ">"
            secs, nsecs = struct.unpack_from(order + "iI", raw, 4)
    except struct.error:
        return 0
    return int(secs) * 1_000_000_000 + int(nsecs)


@dataclass(frozen=True)
class ClockChoice:
    """``order``: "log" or "header". ``offset_ns``: header minus log time (header order).
    ``reason``: why, for the log."""

    order: str
    offset_ns: int = 0
    reason: str = ""


def choose_clock(stamps: dict[str, tuple[np.ndarray, np.ndarray]]) -> ClockChoice:
    """The clock to read a log by, from each topic's (log ns, header ns) in log order."""
    backwards = []
    offsets = []
    for topic, (log_ns, header_ns) in stamps.items():
        if len(header_ns) < 2:
            continue
        if not header_ns.all():
            return ClockChoice("log")  # a stream without header stamps: log time only
        offsets.append(float(np.median(header_ns - log_ns)))
        drops = np.maximum.accumulate(header_ns) - header_ns
        if drops.max() > BACKWARDS_NS:
            at = int(np.argmax(drops))
            backwards.append(
                f"{topic} header stamps run {drops[at] * 1e-9:.1f} s backwards at "
                f"{(log_ns[at] - log_ns[0]) * 1e-9:.2f} s of log time"
            )
    if not backwards:
        return ClockChoice("log")
    if max(offsets) - min(offsets) > SAME_CLOCK_NS:
        return ClockChoice(
            "log", reason=f"{backwards[0]}, but the streams' header clocks disagree: log order"
        )
    return ClockChoice(
        "header",
        int(np.median(offsets)),
        f"{backwards[0]} while the log time runs on: read in header-stamp order instead",
    )


def log_clock(reader: Any, topics: Collection[str], ros1: bool) -> ClockChoice:
    """The clock of an open log (an ``AnyReader``), from the raw messages of ``topics``."""
    stamps: dict[str, tuple[list[int], list[int]]] = {t: ([], []) for t in topics}
    wanted = [c for c in reader.connections if c.topic in stamps]
    for connection, log_ns, raw in reader.messages(connections=wanted):
        stamps[connection.topic][0].append(log_ns)
        stamps[connection.topic][1].append(raw_header_stamp_ns(raw, ros1))
    return choose_clock(
        {t: (np.array(a, np.int64), np.array(b, np.int64)) for t, (a, b) in stamps.items()}
    )


def in_header_order(messages: Iterator, offset_ns: int, ros1: bool) -> Iterator:
    """``(connection, log ns, raw)`` messages re-timed by their header stamps (minus the
    log's header offset) and sorted by them. They are held in memory, which only a log whose
    log time is broken costs."""
    held = [
        (raw_header_stamp_ns(raw, ros1) - offset_ns, index, connection, raw)
        for index, (connection, _, raw) in enumerate(messages)
    ]
    held.sort(key=lambda item: (item[0], item[1]))
    for header_ns, _, connection, raw in held:
        yield connection, header_ns, raw
