"""The node's output messages -> CDR bytes, without rclpy's Python-to-C conversion.

``nav_msgs/Odometry``, ``geometry_msgs/Vector3Stamped`` and ``diagnostic_msgs/DiagnosticArray``
(everything :mod:`slip_estimator.ros.publish` builds) are written with ``struct`` in the layout
of :mod:`slip_estimator.ros.cdr` (little-endian CDR, the padding zeroed). The live node
publishes the bytes (``Publisher.publish`` of ``bytes`` is rclpy's ``publish_raw``) and the
replay writes them to the bag: rclpy's generic conversion of a message object cost more per
output than building it (measured in docs/performance.md). :func:`serialize` falls back to
``rclpy.serialization.serialize_message`` for any other type.
"""
from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry

_ENCAPSULATION = b'\x00\x01\x00\x00'
_STAMP = struct.Struct('<iI')
_UINT32 = struct.Struct('<I')
_POSE = struct.Struct('<7d')
_TWIST = struct.Struct('<6d')
_VECTOR = struct.Struct('<3d')
_ZEROS = bytes(8)


class _Buffer:
    """CDR writer: parts appended to a list, the position tracked for alignment (counted
    from the end of the encapsulation header)."""

    __slots__ = ('parts', 'pos')

    def __init__(self) -> None:
        self.parts: list[bytes] = [_ENCAPSULATION]
        self.pos = 0

    def align(self, n: int) -> None:
        pad = -self.pos % n
        if pad:
            self.parts.append(_ZEROS[:pad])
            self.pos += pad

    def raw(self, data: bytes) -> None:
        self.parts.append(data)
        self.pos += len(data)

    def uint32(self, value: int) -> None:
        self.align(4)
        self.raw(_UINT32.pack(value))

    def string(self, text: str) -> None:
        data = text.encode()
        pad = -self.pos % 4
        self.parts.append(_ZEROS[:pad] + _UINT32.pack(len(data) + 1) + data + b'\0')
        self.pos += pad + 5 + len(data)

    def header(self, header: Any) -> None:
        stamp = header._stamp
        self.raw(_STAMP.pack(stamp._sec, stamp._nanosec))
        self.string(header._frame_id)

    def bytes(self) -> bytes:
        return b''.join(self.parts)


def _doubles(values: Any, n: int) -> bytes:
    """The bytes of a fixed array of ``n`` doubles (numpy array or sequence)."""
    data = np.asarray(values, dtype='<f8').tobytes()
    if len(data) != 8 * n:
        raise ValueError(f'expected {n} doubles, got {len(data) // 8}')
    return data


def _odometry(msg: Odometry) -> bytes:
    out = _Buffer()
    out.header(msg._header)
    out.string(msg._child_frame_id)
    out.align(8)
    pose, twist = msg._pose, msg._twist
    p, q = pose._pose._position, pose._pose._orientation
    lin, ang = twist._twist._linear, twist._twist._angular
    out.raw(_POSE.pack(p._x, p._y, p._z, q._x, q._y, q._z, q._w))
    out.raw(_doubles(pose._covariance, 36))
    out.raw(_TWIST.pack(lin._x, lin._y, lin._z, ang._x, ang._y, ang._z))
    out.raw(_doubles(twist._covariance, 36))
    return out.bytes()


def _vector3_stamped(msg: Vector3Stamped) -> bytes:
    out = _Buffer()
    out.header(msg._header)
    out.align(8)
    v = msg._vector
    out.raw(_VECTOR.pack(v._x, v._y, v._z))
    return out.bytes()


def _diagnostic_array(msg: DiagnosticArray) -> bytes:
    out = _Buffer()
    out.header(msg._header)
    out.uint32(len(msg._status))
    for status in msg._status:
        out.raw(status._level)  # octet: one byte, no alignment
        out.string(status._name)
        out.string(status._message)
        out.string(status._hardware_id)
        out.uint32(len(status._values))
        for kv in status._values:
            out.string(kv._key)
            out.string(kv._value)
    return out.bytes()


_ENCODERS: dict[type, Callable[[Any], bytes]] = {
    Odometry: _odometry, Vector3Stamped: _vector3_stamped, DiagnosticArray: _diagnostic_array}


def serialize(msg: Any) -> bytes:
    """CDR bytes of ``msg`` (the node's output types here, anything else through rclpy)."""
    encode = _ENCODERS.get(type(msg))
    if encode is not None:
        return encode(msg)
    from rclpy.serialization import serialize_message
    return serialize_message(msg)
