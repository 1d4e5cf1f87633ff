"""Serialized ROS 2 input messages (CDR bytes) -> the fields :mod:`slip_estimator.ros.convert`
turns into core records, without building a Python message object.

The live node (``raw=True`` subscriptions) and the bag replay (the bytes rosbags reads) share
these decoders; :mod:`slip_estimator.ros.convert` holds the conversion semantics (checks,
rotation into the body frame, rejection reasons) for both the message objects and these fields.
No rclpy, no rosbags: the standard library (``struct``) and numpy.

Layout (XCDR1 as rmw_fastrtps writes it, OMG DDS-XTypes 7.4.3): a 4-byte encapsulation
header (``00 01``: CDR little endian; ``00 00``: big endian), then the fields, each primitive
aligned to its size counted from the end of that header. ``std_msgs/Header`` is ``int32 sec,
uint32 nanosec, string frame_id`` (uint32 length including the NUL, then the bytes), so the
doubles after it start at the next multiple of 8: the frame_id's length decides the padding.
A sequence is a uint32 count, then its elements (an empty sequence of doubles has no
padding). Bytes past the last field (writers pad the buffer) are ignored.

Anything that is not little-endian CDR is rejected as :data:`REASON_BIG_ENDIAN` (a valid but
unsupported encoding; no ROS 2 middleware on a little-endian machine writes it) and anything
that does not fit the layout (truncated, a string running past the end) as
:data:`REASON_MALFORMED`: the callers count these reasons as they count the other rejections.
"""
from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

REASON_BIG_ENDIAN = 'big_endian_cdr'
REASON_MALFORMED = 'malformed_cdr'

NS_PER_S = 1_000_000_000
_DATA = 4  # the encapsulation header; alignment counts from here
_HEADER = struct.Struct('<iII')  # stamp.sec, stamp.nanosec, frame_id length (with its NUL)
_UINT32 = struct.Struct('<I')
IMU_DOUBLES = 37
"""orientation (x, y, z, w), its covariance (9), angular_velocity (3), covariance (9),
linear_acceleration (3), covariance (9)."""
_IMU_BYTES = 8 * IMU_DOUBLES
# Columns of the IMU doubles.
IMU_Q_XYZW = slice(0, 4)
IMU_ORIENTATION_COV0 = 4
IMU_OMEGA = slice(13, 16)
IMU_OMEGA_COV = slice(16, 25)
IMU_ACCEL = slice(25, 28)
IMU_ACCEL_COV = slice(28, 37)
# nav_msgs/Odometry after child_frame_id: pose (position 3, orientation 4, covariance 36),
# then twist.linear (3), twist.angular (3): linear.x and angular.z.
_ODOM_TWIST = struct.Struct('<344xd32xd')


class CdrError(ValueError):
    """Bytes that are not a decodable message; ``reason`` is the rejection reason."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f'{reason}: {detail}')
        self.reason = reason


def _align8(pos: int) -> int:
    return (pos + 7) & ~7


def _check_encapsulation(raw: bytes | memoryview) -> None:
    if len(raw) < _DATA + _HEADER.size:
        raise CdrError(REASON_MALFORMED, f'{len(raw)} bytes, shorter than a header')
    if raw[0] != 0 or raw[1] not in (0, 1):
        raise CdrError(REASON_MALFORMED, f'encapsulation {bytes(raw[:2]).hex()} is not CDR')
    if raw[1] == 0:
        raise CdrError(REASON_BIG_ENDIAN, 'big-endian CDR is not supported')


def header(raw: bytes | memoryview) -> tuple[int, int]:
    """(``header.stamp`` in ns, offset of the first field after ``frame_id`` from the start of
    ``raw``) of a message that begins with a ``std_msgs/Header``; :class:`CdrError` else."""
    _check_encapsulation(raw)
    sec, nanosec, n = _HEADER.unpack_from(raw, _DATA)
    end = _DATA + _HEADER.size + n
    if end > len(raw):
        raise CdrError(REASON_MALFORMED, f'frame_id of {n} bytes runs past the end')
    return sec * NS_PER_S + nanosec, end


def stamp_ns(raw: bytes | memoryview) -> int:
    """``header.stamp`` of a serialized stamped message, ns; :class:`CdrError` if malformed."""
    return header(raw)[0]


# --- sensor_msgs/Imu ------------------------------------------------------------------------------
IMU_STRUCT = struct.Struct(f'<{IMU_DOUBLES}d')


def imu_start(raw: bytes | memoryview) -> tuple[int, int]:
    """(stamp ns, offset of the 37 doubles in ``raw``) of a serialized ``sensor_msgs/Imu``;
    :class:`CdrError` if it does not decode."""
    stamp, end = header(raw)
    start = _DATA + _align8(end - _DATA)
    if start + _IMU_BYTES > len(raw):
        raise CdrError(REASON_MALFORMED, f'{len(raw)} bytes, too short for an Imu')
    return stamp, start


def imu_values(raws: Sequence[bytes | memoryview]) -> tuple[list[int | str], np.ndarray]:
    """Stamps (ns; the rejection reason for a message that does not decode) and an
    ``(N, 37)`` array of the doubles of serialized ``sensor_msgs/Imu`` messages (a row of
    zeros where the message did not decode)."""
    stamps: list[int | str] = []
    blocks = []
    zeros = bytes(_IMU_BYTES)
    for raw in raws:
        try:
            stamp, start = imu_start(raw)
            block = raw[start:start + _IMU_BYTES]
        except CdrError as exc:
            stamp, block = exc.reason, zeros
        except struct.error:
            stamp, block = REASON_MALFORMED, zeros
        stamps.append(stamp)
        blocks.append(block)
    values = np.frombuffer(b''.join(blocks), dtype='<f8').reshape(len(raws), IMU_DOUBLES)
    return stamps, values


# --- sensor_msgs/JointState -----------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class JointStateFields:
    """What the wheel conversion reads of a ``sensor_msgs/JointState``."""

    stamp_ns: int
    name: list[str]
    position: list[float]
    velocity: list[float]


def _doubles(raw: bytes | memoryview, pos: int) -> tuple[list[float], int]:
    """A ``sequence<double>`` at ``pos`` (offset in ``raw``): (values, offset after it)."""
    pos = _DATA + ((pos - _DATA + 3) & ~3)
    (n,) = _UINT32.unpack_from(raw, pos)
    pos += 4
    if n == 0:
        return [], pos
    pos = _DATA + _align8(pos - _DATA)
    if pos + 8 * n > len(raw):
        raise CdrError(REASON_MALFORMED, f'sequence of {n} doubles runs past the end')
    return list(struct.unpack_from(f'<{n}d', raw, pos)), pos + 8 * n


def joint_state_fields(raw: bytes | memoryview) -> JointStateFields:
    """The stamp, names, positions and velocities of a serialized ``sensor_msgs/JointState``;
    :class:`CdrError` if it does not decode."""
    try:
        stamp, pos = header(raw)
        pos = _DATA + ((pos - _DATA + 3) & ~3)
        (count,) = _UINT32.unpack_from(raw, pos)
        pos += 4
        if count > (len(raw) - pos) // 5:  # each name takes at least 4 + 1 bytes
            raise CdrError(REASON_MALFORMED, f'{count} joint names cannot fit')
        names = []
        for _ in range(count):
            pos = _DATA + ((pos - _DATA + 3) & ~3)
            (n,) = _UINT32.unpack_from(raw, pos)
            pos += 4
            if pos + n > len(raw):
                raise CdrError(REASON_MALFORMED, 'a joint name runs past the end')
            names.append(bytes(raw[pos:pos + n]).rstrip(b'\0').decode())
            pos += n
        position, pos = _doubles(raw, pos)
        velocity, pos = _doubles(raw, pos)
    except struct.error as exc:
        raise CdrError(REASON_MALFORMED, str(exc)) from None
    except UnicodeDecodeError:
        raise CdrError(REASON_MALFORMED, 'a joint name is not UTF-8') from None
    return JointStateFields(stamp, names, position, velocity)


# --- nav_msgs/Odometry ----------------------------------------------------------------------------
def odometry_twist(raw: bytes | memoryview) -> tuple[int, float, float]:
    """(stamp ns, ``twist.twist.linear.x``, ``twist.twist.angular.z``) of a serialized
    ``nav_msgs/Odometry``; :class:`CdrError` if it does not decode."""
    try:
        stamp, pos = header(raw)
        pos = _DATA + ((pos - _DATA + 3) & ~3)
        (n,) = _UINT32.unpack_from(raw, pos)  # child_frame_id
        pos = _DATA + _align8(pos + 4 + n - _DATA)
        v, w = _ODOM_TWIST.unpack_from(raw, pos)
    except struct.error as exc:
        raise CdrError(REASON_MALFORMED, str(exc)) from None
    return stamp, v, w

