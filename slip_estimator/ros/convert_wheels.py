"""Wheel messages -> :class:`~slip_estimator.core.types.WheelSample` (rim speeds, m/s, forward
positive): ``sensor_msgs/JointState`` (wheel joint velocities, or positions differentiated) and
wheel-odometry ``nav_msgs/Odometry`` (differential-drive model), each from a message object or
its serialized bytes; every path ends in :func:`wheel_from_joints` or :func:`wheel_from_twist`.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

from slip_estimator.core.types import WheelSample
from slip_estimator.ros import cdr
from slip_estimator.ros.rejections import (REASON_ABSURD_SPEED, REASON_FIRST_POSITION,
                                           REASON_NO_VELOCITY, REASON_NO_WHEEL_JOINTS,
                                           REASON_NON_FINITE, REASON_POSITION_RESET,
                                           REASON_ZERO_STAMP)
from slip_estimator.ros.stamps import header_stamp_ns
from slip_estimator.streams import wheel_side


class JointRatesFromPositions:
    """Wheel rates from the position differences of consecutive joint states, for drivers
    that publish positions only (``velocity`` empty).

    A difference of about a full turn is a position wrapped to +-pi crossing the cut; a jump
    no wheel can turn in the interval (beyond ``max_rate_rps``) is a reset of the encoder
    count: that sample is rejected and differencing restarts from it.
    """

    def __init__(self, max_rate_rps: float) -> None:
        self.max_rate_rps = max_rate_rps
        self._last: tuple[int, dict[str, float]] | None = None

    def rates(self, stamp_ns: int, positions: dict[str, float]) -> dict[str, float] | str:
        last, self._last = self._last, (stamp_ns, positions)
        if last is None or not set(positions) & set(last[1]) or stamp_ns <= last[0]:
            return REASON_FIRST_POSITION
        dt_s = (stamp_ns - last[0]) * 1e-9
        out = {}
        for name, pos in positions.items():
            if name not in last[1]:
                continue
            d_rad = pos - last[1][name]
            if abs(abs(d_rad) - 2.0 * math.pi) <= self.max_rate_rps * dt_s:
                d_rad -= math.copysign(2.0 * math.pi, d_rad)  # wrapped at +-pi
            if abs(d_rad) > self.max_rate_rps * dt_s:
                return REASON_POSITION_RESET
            out[name] = d_rad / dt_s
        return out


def wheel_from_joint_state(msg: JointState, names: Sequence[str], wheel_radius_m: float, *,
                           max_speed_mps: float = math.inf,
                           from_positions: JointRatesFromPositions | None = None
                           ) -> WheelSample | str:
    """Rim speeds ``r * omega`` from the wheel joint velocities of a ``sensor_msgs/JointState``.

    ``names`` are the driven wheels (rad/s, forward positive). Wheels listed in ``names`` but
    absent from the message are left out of the means (several publishers may share
    ``/joint_states``); a message without any of them is rejected as ``'no_wheel_joints'``.
    The per-side means use the joints whose name contains 'left' / 'right'. Without
    velocities, ``from_positions`` (when given) differentiates the positions.
    """
    return wheel_from_joints(header_stamp_ns(msg), msg.name, msg.position, msg.velocity,
                             names, wheel_radius_m, max_speed_mps=max_speed_mps,
                             from_positions=from_positions)


def wheel_from_cdr_joint_state(raw: bytes | memoryview, names: Sequence[str],
                               wheel_radius_m: float, *, max_speed_mps: float = math.inf,
                               from_positions: JointRatesFromPositions | None = None
                               ) -> WheelSample | str:
    """:func:`wheel_from_joint_state` of a serialized ``sensor_msgs/JointState``; a message
    that does not decode gives its :mod:`cdr` rejection reason."""
    try:
        js = cdr.joint_state_fields(raw)
    except cdr.CdrError as exc:
        return exc.reason
    return wheel_from_joints(js.stamp_ns, js.name, js.position, js.velocity, names,
                             wheel_radius_m, max_speed_mps=max_speed_mps,
                             from_positions=from_positions)


def wheel_from_joints(stamp_ns: int, joint_names: Sequence[str], position: Sequence[float],
                      velocity: Sequence[float], names: Sequence[str], wheel_radius_m: float, *,
                      max_speed_mps: float = math.inf,
                      from_positions: JointRatesFromPositions | None = None
                      ) -> WheelSample | str:
    """:func:`wheel_from_joint_state` of the fields of a ``sensor_msgs/JointState``."""
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    index = {n: i for i, n in enumerate(joint_names)}
    present = [n for n in names if n in index]
    if not present:
        return REASON_NO_WHEEL_JOINTS
    if len(velocity) == len(joint_names):
        speeds_mps = [wheel_radius_m * float(velocity[index[n]]) for n in present]
    elif from_positions is not None and len(position) == len(joint_names):
        positions = {n: float(position[index[n]]) for n in present}
        if not all(math.isfinite(v) for v in positions.values()):
            return REASON_NON_FINITE
        rates_rps = from_positions.rates(stamp_ns, positions)
        if isinstance(rates_rps, str):
            return rates_rps
        present = [n for n in present if n in rates_rps]
        speeds_mps = [wheel_radius_m * rates_rps[n] for n in present]
    else:
        return REASON_NO_VELOCITY
    if not all(math.isfinite(v) for v in speeds_mps):
        return REASON_NON_FINITE
    if max(abs(v) for v in speeds_mps) > max_speed_mps:
        return REASON_ABSURD_SPEED
    left_mps = [v for n, v in zip(present, speeds_mps) if wheel_side(n) == 'left']
    right_mps = [v for n, v in zip(present, speeds_mps) if wheel_side(n) == 'right']
    return WheelSample(stamp_ns=stamp_ns,
                       rim_speed_mps=sum(speeds_mps) / len(speeds_mps),
                       rim_speed_left_mps=sum(left_mps) / len(left_mps) if left_mps else None,
                       rim_speed_right_mps=(sum(right_mps) / len(right_mps) if right_mps
                                            else None))


def wheel_from_odometry(msg: Odometry, track_width_m: float, *,
                        max_speed_mps: float = math.inf) -> WheelSample | str:
    """Rim speeds from a wheel-odometry ``nav_msgs/Odometry`` (differential-drive model).

    ``twist.twist.linear.x`` is the mean rim speed v (m/s) and ``angular.z`` the yaw rate w
    (rad/s, FLU so counter-clockwise positive): ``v_left = v - w*track_width_m/2``,
    ``v_right = v + w*track_width_m/2``.
    """
    return wheel_from_twist(header_stamp_ns(msg), msg.twist.twist.linear.x,
                            msg.twist.twist.angular.z, track_width_m,
                            max_speed_mps=max_speed_mps)


def wheel_from_cdr_odometry(raw: bytes | memoryview, track_width_m: float, *,
                            max_speed_mps: float = math.inf) -> WheelSample | str:
    """:func:`wheel_from_odometry` of a serialized ``nav_msgs/Odometry``; a message that does
    not decode gives its :mod:`cdr` rejection reason."""
    try:
        stamp_ns, v_mps, yaw_rate_flu_rps = cdr.odometry_twist(raw)
    except cdr.CdrError as exc:
        return exc.reason
    return wheel_from_twist(stamp_ns, v_mps, yaw_rate_flu_rps, track_width_m,
                            max_speed_mps=max_speed_mps)


def wheel_from_twist(stamp_ns: int, v_mps: float, yaw_rate_flu_rps: float,
                     track_width_m: float, *, max_speed_mps: float = math.inf
                     ) -> WheelSample | str:
    """:func:`wheel_from_odometry` of the stamp, forward speed and yaw rate of the message."""
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    v_mps, yaw_rate_flu_rps = float(v_mps), float(yaw_rate_flu_rps)
    if not (math.isfinite(v_mps) and math.isfinite(yaw_rate_flu_rps)):
        return REASON_NON_FINITE
    v_left_mps = v_mps - 0.5 * yaw_rate_flu_rps * track_width_m
    v_right_mps = v_mps + 0.5 * yaw_rate_flu_rps * track_width_m
    if max(abs(v_mps), abs(v_left_mps), abs(v_right_mps)) > max_speed_mps:
        return REASON_ABSURD_SPEED
    return WheelSample(stamp_ns=stamp_ns, rim_speed_mps=v_mps, rim_speed_left_mps=v_left_mps,
                       rim_speed_right_mps=v_right_mps)
