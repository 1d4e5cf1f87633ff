"""rosbag2 reading and writing (MCAP or sqlite3) with real ROS 2 message classes.

The only module that touches bag files. Messages are (de)serialised with
``rclpy.serialization`` so that replay, the simulator and the live node all handle the very same
message classes; rosbags provides the container format. Timestamps are integer nanoseconds.
"""
from __future__ import annotations

import importlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def message_class(msgtype: str) -> type:
    """ROS message class for a type name like ``sensor_msgs/msg/Imu``."""
    pkg, _, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


def message_type_name(msg: Any) -> str:
    """Type name like ``sensor_msgs/msg/Imu`` of a ROS message instance or class."""
    cls = msg if isinstance(msg, type) else type(msg)
    pkg = cls.__module__.split('.')[0]
    return f'{pkg}/msg/{cls.__name__}'


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One message read from a bag: topic, type name, log time (ns) and the message."""

    topic: str
    msgtype: str
    log_time_ns: int
    msg: Any


def read_messages(path: str | Path, topics: set[str] | None = None) -> Iterator[BagMessage]:
    """Yield the messages of a rosbag2 bag (directory, .mcap or .db3) in log-time order.

    Types that are not available as ROS message classes on this machine are skipped.
    """
    with Reader(Path(path)) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        classes = {}
        for c in conns:
            try:
                classes[c.id] = message_class(c.msgtype)
            except (ImportError, AttributeError, ValueError):
                continue
        conns = [c for c in conns if c.id in classes]
        if not conns:
            return
        for conn, log_ns, raw in reader.messages(connections=conns):
            yield BagMessage(conn.topic, conn.msgtype, log_ns,
                             deserialize_message(bytes(raw), classes[conn.id]))


def bag_topics(path: str | Path) -> dict[str, str]:
    """Mapping topic -> type name of a bag."""
    with Reader(Path(path)) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def bag_duration_s(path: str | Path) -> float:
    """Duration of a bag from its metadata, s."""
    with Reader(Path(path)) as reader:
        return reader.duration * 1e-9


class BagWriter:
    """Write ROS messages to a new MCAP rosbag2 bag (a directory).

    Use as a context manager; topics are registered on first use.
    """

    def __init__(self, path: str | Path) -> None:
        self._writer = Writer(Path(path), version=9, storage_plugin=StoragePlugin.MCAP)
        self._connections: dict[str, Any] = {}

    def __enter__(self) -> BagWriter:
        self._writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()

    def write(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Serialise ``msg`` and write it on ``topic`` at ``log_time_ns``."""
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, message_type_name(msg),
                                               typestore=_TYPESTORE)
            self._connections[topic] = conn
        self._writer.write(conn, int(log_time_ns), serialize_message(msg))
