"""ROS time stamps <-> integer nanoseconds: ``builtin_interfaces/Time`` at the boundary,
``stamp_ns`` everywhere inside (inputs, outputs, bags)."""
from __future__ import annotations

from typing import Any

from builtin_interfaces.msg import Time

from slip_estimator.ros.msgbuild import build

NS_PER_S = 1_000_000_000


def stamp_to_ns(stamp: Time) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def ns_to_stamp(stamp_ns: int) -> Time:
    """``builtin_interfaces/Time`` of integer nanoseconds (floor division, so negative times
    keep ``0 <= nanosec < 1e9`` as the message requires)."""
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    return build(Time, sec, nanosec)


def header_stamp_ns(msg: Any) -> int:
    """``header.stamp`` of a stamped message, ns."""
    return stamp_to_ns(msg.header.stamp)
