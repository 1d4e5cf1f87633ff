"""Bag reading (rosbag2 MCAP/sqlite3 and ROS 1 ``.bag``) and MCAP writing with ROS 2 classes.

The only module that touches bag files. Messages are deserialised with
``rclpy.serialization`` so that the simulator, the reports and the live node all handle the very
same message classes (the replay reads the serialized bytes, :func:`read_raw`, and decodes them
with :mod:`slip_estimator.ros.cdr`); they are serialised with
:func:`slip_estimator.ros.cdr_out.serialize` (the node's outputs written directly, other types
through rclpy); rosbags provides the container formats. A ROS 1 bag's messages are converted on
the fly to ROS 2 CDR with rosbags' Jazzy typestore (``ros1_to_cdr``: the ROS 1 header's ``seq``
dropped; Imu, JointState, Odometry have the same fields otherwise). Timestamps are integer
nanoseconds. A path that is not a readable bag raises :class:`BagError` with a one-line message
naming the path and what is wrong.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.rosbag2 import ReaderError as Reader2Error

from slip_estimator.ros.cdr_out import serialize

ROS1_MAGIC = b'#ROSBAG V2.0'


@cache
def _typestore() -> Any:
    """rosbags' Jazzy typestore (about 0.2 s to build: made when a ROS 1 bag or a writer
    first needs it)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


class BagError(Exception):
    """A path that cannot be read as a bag; the message is one line for the user."""


def ros1_bag(path: Path) -> bool:
    """True for a ROS 1 bag file (its magic line, whatever its suffix)."""
    if not path.is_file():
        return False
    with path.open('rb') as f:
        return f.read(len(ROS1_MAGIC)) == ROS1_MAGIC


def _check_bag_path(path: Path) -> None:
    """Raise :class:`BagError` for what is plainly not a bag (before rosbags sees it)."""
    if not path.exists():
        raise BagError(f'{path}: no such file or folder')
    if path.is_dir():
        entries = list(path.iterdir())
        if not entries:
            raise BagError(f'{path}: empty folder, not a bag')
        if not (path / 'metadata.yaml').is_file() and not any(
                p.suffix in ('.mcap', '.db3') for p in entries):
            raise BagError(f'{path}: not a rosbag2 bag (no metadata.yaml, .mcap or .db3 in it)')
    elif path.suffix not in ('.mcap', '.db3', '.bag') and not ros1_bag(path):
        raise BagError(f'{path}: not a bag (expected a rosbag2 folder, .mcap, .db3 or a '
                       'ROS 1 .bag)')


@contextmanager
def open_bag(path: str | Path) -> Iterator[Any]:
    """An open rosbags reader (rosbag2 or ROS 1) for ``path``; :class:`BagError` otherwise."""
    path = Path(path)
    _check_bag_path(path)
    errors: tuple[type[Exception], ...] = (Reader2Error, OSError, ValueError, KeyError)
    if ros1_bag(path):  # rosbags.rosbag1 is imported for ROS 1 bags only
        from rosbags.rosbag1 import Reader as Reader1
        from rosbags.rosbag1 import ReaderError as Reader1Error
        reader, errors = Reader1(path), (Reader1Error, *errors)
    else:
        reader = Reader(path)
    try:
        reader.open()
    except errors as exc:
        raise BagError(f'{path}: cannot read the bag ({str(exc) or type(exc).__name__})'
                       ) from None
    try:
        yield reader
    finally:
        reader.close()


def _is_ros1(reader: Any) -> bool:
    return not isinstance(reader, Reader)


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


def _to_cdr(reader: Any, msgtype: str) -> Callable[[Any], bytes]:
    """Raw bytes -> ROS 2 CDR for this reader's format."""
    if _is_ros1(reader):
        to_cdr = _typestore().ros1_to_cdr
        return lambda raw: bytes(to_cdr(raw, msgtype))
    return bytes


def read_raw(path: str | Path, topics: set[str] | None = None
             ) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield (topic, type name, log time ns, ROS 2 CDR bytes) of the messages of a bag in
    log-time order, without deserializing them (a ROS 1 bag's messages converted to CDR).

    Types that a ROS 1 bag cannot convert (not in the Jazzy typestore) are skipped.
    """
    with open_bag(path) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        ros1 = _is_ros1(reader)
        if ros1:
            conns = [c for c in conns if c.msgtype in _typestore().types]
        if not conns:
            return
        if not ros1:
            for conn, log_ns, raw in reader.messages(connections=conns):
                yield conn.topic, conn.msgtype, log_ns, raw
            return
        to_cdr = _typestore().ros1_to_cdr
        for conn, log_ns, raw in reader.messages(connections=conns):
            yield conn.topic, conn.msgtype, log_ns, bytes(to_cdr(raw, conn.msgtype))


def read_messages(path: str | Path, topics: set[str] | None = None) -> Iterator[BagMessage]:
    """Yield the messages of a bag (rosbag2 folder, .mcap, .db3 or ROS 1 .bag) in log-time
    order.

    Types that are not available as ROS 2 message classes on this machine are skipped.
    """
    from rclpy.serialization import deserialize_message

    with open_bag(path) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        decode = {}
        for c in conns:
            try:
                cls = message_class(c.msgtype)
                if _is_ros1(reader) and c.msgtype not in _typestore().types:
                    continue
            except (ImportError, AttributeError, ValueError):
                continue
            decode[c.id] = (cls, _to_cdr(reader, c.msgtype))
        conns = [c for c in conns if c.id in decode]
        if not conns:
            return
        for conn, log_ns, raw in reader.messages(connections=conns):
            cls, to_cdr = decode[conn.id]
            yield BagMessage(conn.topic, conn.msgtype, log_ns,
                             deserialize_message(to_cdr(raw), cls))


def bag_topics(path: str | Path) -> dict[str, str]:
    """Mapping topic -> type name of a bag."""
    with open_bag(path) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def bag_duration_s(path: str | Path) -> float:
    """Duration of a bag from its metadata, s."""
    with open_bag(path) as reader:
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
                                               typestore=_typestore())
            self._connections[topic] = conn
        self._writer.write(conn, int(log_time_ns), serialize(msg))
