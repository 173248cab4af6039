"""Bad logs crafted from a good one: copy its messages with rosbags, altering some on the way."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer

from smokyslam.rosmsg import typestore_for

Edit = Callable[[str, Any, int], "Any | tuple[Any, int] | None"]
"""(topic, message, log time ns) -> the message (edited in place or new), a (message, new log
time ns) pair, or None to drop it."""


def rewrite(source: Path, target: Path, edit: Edit) -> Path:
    """Copy every message of ``source`` into a new ROS2 MCAP log ``target`` through ``edit``."""
    store = typestore_for(ros1=False)
    with AnyReader([source], default_typestore=store) as reader:
        messages = []
        for connection, log_ns, raw in reader.messages():
            msg = copy.deepcopy(reader.deserialize(raw, connection.msgtype))
            out = edit(connection.topic, msg, log_ns)
            if out is None:
                continue
            msg, log_ns = out if isinstance(out, tuple) else (out, log_ns)
            messages.append((connection.topic, connection.msgtype, log_ns, msg))
    folder = target.parent / f".{target.stem}.tmp"
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {}
        for topic, msgtype, log_ns, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(connections[topic], log_ns, store.serialize_cdr(msg, msgtype))
    (folder / f"{folder.name}.mcap").replace(target)
    for leftover in folder.iterdir():
        leftover.unlink()
    folder.rmdir()
    return target


def every_nth(topic: str, n: int, change: Callable[[Any], Any]) -> Edit:
    """An edit applying ``change`` to every ``n``-th message of ``topic`` (the first one too)."""
    seen = {"count": 0}

    def edit(msg_topic: str, msg: Any, log_ns: int):
        if msg_topic == topic:
            seen["count"] += 1
            if (seen["count"] - 1) % n == 0:
                return change(msg)
        return msg

    return edit


def point_cloud_fields(msg: Any, drop: str) -> Any:
    """A PointCloud2 without the field ``drop`` (the bytes stay; only the description goes)."""
    msg.fields = [field for field in msg.fields if field.name != drop]
    return msg


def nan_field(msg: Any, dotted: str) -> Any:
    """The message with one float field (``"pose.position.x"``) set to NaN."""
    *parents, name = dotted.split(".")
    part = msg
    for parent in parents:
        part = getattr(part, parent)
    setattr(part, name, float("nan"))
    return msg


def float32_points(msg: Any, column: int, value: float) -> Any:
    """A PointCloud2 of float32 fields with one column (x=0, ..., velocity=4) set to ``value``."""
    points = np.frombuffer(bytes(msg.data), dtype=np.float32).reshape(-1, msg.point_step // 4)
    points = points.copy()
    points[:, column] = value
    msg.data = np.frombuffer(points.tobytes(), dtype=np.uint8)
    return msg
