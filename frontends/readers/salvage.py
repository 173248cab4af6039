"""Salvage a log whose index is gone (a recording cut off): read its records in file order.

ROS1 bags and MCAP files both store messages as a sequence of records (chunks of them, in
time order) and put the index at the end, which a crash or a full disk never writes. This
reads the records from the start, as ``rosbag reindex`` does, up to the first one that is cut
off or damaged, and offers them through the few parts of rosbags' ``AnyReader`` that
:class:`~smokyslam.frontends.readers.rosbag.RosbagReader` uses. Chunks stored without
compression or with lz4 are read; a compression this machine cannot undo ends the salvage
there. Messages are decoded with the same typestore as an intact log.
"""

from __future__ import annotations

import bz2
import logging
import mmap
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

logger = logging.getLogger(__name__)

ROS1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True)
class Connection:
    """A topic's messages: what ``AnyReader.connections`` holds, for the fields used."""

    id: int
    topic: str
    msgtype: str


@dataclass(frozen=True)
class TopicInfo:
    msgtype: str


class _CutOffError(Exception):
    """The records stop being readable here."""


def _decompress(data: bytes, compression: str) -> bytes:
    if compression in ("", "none"):
        return data
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.decompress(data)
    if compression == "bz2":
        return bz2.decompress(data)
    raise _CutOffError(f"chunk compression '{compression}' cannot be read here")


def _ros1_fields(header: memoryview | bytes) -> dict[str, bytes]:
    header, fields, pos = bytes(header), {}, 0
    while pos < len(header):
        (size,) = struct.unpack_from("<I", header, pos)
        name, _, value = header[pos + 4 : pos + 4 + size].partition(b"=")
        fields[name.decode()] = value
        pos += 4 + size
    return fields


def _ros1_records(data: memoryview | bytes, pos: int) -> Iterator[tuple[dict[str, bytes], bytes]]:
    """(header fields, payload) of each record; an uncompressed chunk cut off is still given,
    up to the cut (its own records stop there), as rosbag reindex reads it."""
    while pos + 4 <= len(data):
        (header_size,) = struct.unpack_from("<I", data, pos)
        header_end = pos + 4 + header_size
        if header_end + 4 > len(data):
            raise _CutOffError("record header cut off")
        (data_size,) = struct.unpack_from("<I", data, header_end)
        fields = _ros1_fields(data[pos + 4 : header_end])
        end = header_end + 4 + data_size
        if end > len(data):
            if fields.get("op") == b"\x05" and fields.get("compression") == b"none":
                yield fields, data[header_end + 4 :]
            raise _CutOffError("record cut off")
        yield fields, data[header_end + 4 : end]
        pos = end


def _mcap_string(data: memoryview | bytes, pos: int) -> tuple[str, int]:
    (size,) = struct.unpack_from("<I", data, pos)
    return bytes(data[pos + 4 : pos + 4 + size]).decode(), pos + 4 + size


def _mcap_records(data: memoryview | bytes, pos: int) -> Iterator[tuple[int, bytes]]:
    """(opcode, content) of each record; a chunk cut off is still given, up to the cut."""
    while pos + 9 <= len(data):
        op, size = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        end = pos + 9 + size
        if end > len(data):
            if op == 0x06:
                yield op, data[pos + 9 :]
            raise _CutOffError("record cut off")
        yield op, data[pos + 9 : end]
        pos = end


class SalvagedLog:
    """The readable start of a damaged ROS1 bag or MCAP file (an ``AnyReader`` stand-in)."""

    def __init__(self, path: Path, typestore: Any) -> None:
        self.path = path
        self._store = typestore
        self.connections: list[Connection] = []
        self._schemas: dict[int, str] = {}
        # (connection id, log ns, raw): raw is a view into the mapped file where the chunk is
        # stored plainly, so salvaging a big log does not copy it into memory.
        self._messages: list[tuple[int, int, memoryview | bytes]] = []
        self.cut = ""
        with path.open("rb") as stream:
            self._file = mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ)
        data = memoryview(self._file)
        self._ros1 = bytes(data[: len(ROS1_MAGIC)]) == ROS1_MAGIC
        try:
            if self._ros1:
                self._ros1_records(data, len(ROS1_MAGIC))
            else:
                self._mcap_records(data, len(MCAP_MAGIC))
        except (
            _CutOffError,
            struct.error,
            UnicodeDecodeError,
            ValueError,
            KeyError,
            OSError,
        ) as exc:
            self.cut = str(exc) or type(exc).__name__
        self._messages.sort(key=lambda m: m[1])  # chunks are in time order; within them too
        by_id = {c.id: c for c in self.connections}
        self._messages = [m for m in self._messages if m[0] in by_id]
        self._by_id = by_id

    # --------------------------------------------------------------- AnyReader's surface

    @property
    def topics(self) -> dict[str, TopicInfo]:
        return {c.topic: TopicInfo(c.msgtype) for c in self.connections}

    @property
    def message_count(self) -> int:
        return len(self._messages)

    @property
    def start_time(self) -> int:
        return self._messages[0][1] if self._messages else 0

    def messages(
        self, connections: list[Connection] | None = None
    ) -> Iterator[tuple[Connection, int, bytes]]:
        wanted = None if connections is None else {c.id for c in connections}
        for connection_id, log_ns, raw in self._messages:
            if wanted is None or connection_id in wanted:
                yield self._by_id[connection_id], log_ns, raw

    def deserialize(self, raw: memoryview | bytes, msgtype: str) -> Any:
        if self._ros1:
            return self._store.deserialize_ros1(bytes(raw), msgtype)
        return self._store.deserialize_cdr(bytes(raw), msgtype)

    # --------------------------------------------------------------- formats

    def _ros1_records(self, data: memoryview | bytes, pos: int) -> None:
        for fields, payload in _ros1_records(data, pos):
            op = fields.get("op", b"\xff")[0]
            if op == 0x05:  # chunk: its records, decompressed
                compression = fields.get("compression", b"none").decode()
                self._ros1_records(_decompress(bytes(payload), compression), 0)
            elif op == 0x07:  # connection
                (conn,) = struct.unpack("<I", fields["conn"])
                msgtype = _ros1_fields(bytes(payload))["type"].decode()
                if "/msg/" not in msgtype:
                    package, _, name = msgtype.partition("/")
                    msgtype = f"{package}/msg/{name}"
                self._add_connection(Connection(conn, fields["topic"].decode(), msgtype))
            elif op == 0x02:  # message data
                (conn,) = struct.unpack("<I", fields["conn"])
                secs, nsecs = struct.unpack("<II", fields["time"])
                self._messages.append((conn, secs * 10**9 + nsecs, payload))

    def _mcap_records(self, data: memoryview | bytes, pos: int) -> None:
        for op, record in _mcap_records(data, pos):
            if op == 0x06:  # chunk
                compression, at = _mcap_string(record, 28)
                (size,) = struct.unpack_from("<Q", record, at)
                records = record[at + 8 : at + 8 + size]
                if compression:
                    records = _decompress(bytes(records), compression)
                self._mcap_records(records, 0)  # a chunk cut off: its records up to the cut
            elif op == 0x03:  # schema
                (schema_id,) = struct.unpack_from("<H", record, 0)
                self._schemas[schema_id], _ = _mcap_string(record, 2)
            elif op == 0x04:  # channel
                channel_id, schema_id = struct.unpack_from("<HH", record, 0)
                topic, _ = _mcap_string(record, 4)
                msgtype = self._schemas.get(schema_id, "")
                self._add_connection(Connection(channel_id, topic, msgtype))
            elif op == 0x05:  # message
                channel_id, _, log_ns = struct.unpack_from("<HIQ", record, 0)
                self._messages.append((channel_id, log_ns, record[22:]))

    def _add_connection(self, connection: Connection) -> None:
        if all(c.id != connection.id for c in self.connections):
            self.connections.append(connection)

    # --------------------------------------------------------------- context manager

    def __enter__(self) -> SalvagedLog:
        return self

    def __exit__(self, *exc: object) -> None:
        pass
