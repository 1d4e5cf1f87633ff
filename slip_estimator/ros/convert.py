"""ROS messages -> core records: the one place where input messages become records.

Pure functions: no rclpy node, no I/O. The live node, the bag replay and the tests share them
(records -> messages: :mod:`slip_estimator.ros.publish`; the no-NaN guard of every output:
:mod:`slip_estimator.ros.finite`).

Frames and conventions (see :mod:`slip_estimator.core.frames`):

* ``sensor_msgs/Imu`` follows REP-145: ``linear_acceleration`` is the specific force (at rest
  and level a z-up IMU reads about +9.81 m/s^2 on z) and ``angular_velocity`` the body rate,
  both resolved in the IMU frame. :func:`imu_from_msg` rotates them into the core body frame b
  (FRD) with ``C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)``.
Input converters return either a record or a short *reason* string (``'non_finite'``,
``'zero_stamp'``, ...) that the caller counts; they never raise on bad data. Each input has one
conversion of its fields (``imu_from_values``, ``wheel_from_joints``, ``wheel_from_twist``),
fed either from a message object (``*_from_msg``, ``wheel_from_joint_state``,
``wheel_from_odometry``) or from the serialized bytes (``*_cdr*``, decoded by
:mod:`slip_estimator.ros.cdr` without a message object: the live node's raw subscriptions and
the bag replay); serialized input that does not decode is rejected as ``'malformed_cdr'`` or
``'big_endian_cdr'``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core.alignment import tilt_from_orientation
from slip_estimator.core.types import (
    MAX_ANGULAR_RATE_RPS,
    MAX_SPECIFIC_FORCE_MPS2,
    ImuSample,
    WheelSample,
)
from slip_estimator.ros import cdr
from slip_estimator.ros.msgbuild import build, fields_getter
from slip_estimator.streams import wheel_side

NS_PER_S = 1_000_000_000

# Rejection reasons (the keys of the node's per-topic rejection counters).
REASON_ZERO_STAMP = 'zero_stamp'
REASON_NON_FINITE = 'non_finite'
REASON_ABSURD_IMU = 'absurd_imu'
REASON_ABSURD_SPEED = 'absurd_wheel_speed'
REASON_NO_WHEEL_JOINTS = 'no_wheel_joints'
REASON_NO_VELOCITY = 'no_velocity'
REASON_FIRST_POSITION = 'first_position'  # positions only: a rate needs the next message
REASON_POSITION_RESET = 'position_reset'  # positions only: a jump no wheel can turn


# --- stamps ---------------------------------------------------------------------------------------
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


# --- inputs ---------------------------------------------------------------------------------------
def imu_from_msg(msg: Imu, C_imu_b: np.ndarray) -> ImuSample | str:
    """Body-frame IMU sample from a REP-145 ``sensor_msgs/Imu``, or a rejection reason
    (:func:`imu_from_values`)."""
    sec, nanosec, *f_w = _IMU_FIELDS(msg)
    cov, *q_wxyz = _IMU_ORIENTATION(msg)
    return imu_from_values(int(sec) * NS_PER_S + int(nanosec), tuple(f_w[:3]), tuple(f_w[3:]),
                           cov[0], q_wxyz, *_IMU_COVARIANCES(msg), C_imu_b)


def imu_from_values(stamp_ns: int, f_ib_imu: tuple[float, float, float],
                    omega_ib_imu: tuple[float, float, float], orientation_cov0: float,
                    q_imu_wxyz: Sequence[float], accel_cov: Sequence[float],
                    gyro_cov: Sequence[float], C_imu_b: np.ndarray) -> ImuSample | str:
    """Body-frame IMU sample from the fields of a REP-145 ``sensor_msgs/Imu`` (however they
    were read: :func:`imu_from_msg`, :func:`imu_from_cdr`, :func:`imu_samples_from_cdr`), or a
    rejection reason.

    ``f_ib_b = C_imu_b @ f_ib_imu`` and ``omega_ib_b = C_imu_b @ omega_ib_imu``: the lever arm
    does not matter for rates, and for the specific force it is ignored (rover body rates are
    small; the mounting offset is the core's business if ever needed).
    """
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    # A finite sum has finite terms; a non-finite one may be an overflow of finite terms.
    if (not math.isfinite(sum(f_ib_imu) + sum(omega_ib_imu))
            and not all(map(math.isfinite, f_ib_imu + omega_ib_imu))):
        return REASON_NON_FINITE
    if (math.hypot(*f_ib_imu) > MAX_SPECIFIC_FORCE_MPS2
            or math.hypot(*omega_ib_imu) > MAX_ANGULAR_RATE_RPS):
        return REASON_ABSURD_IMU
    # orientation_covariance[0] = -1: no orientation (REP-145); anything else: provided.
    tilt = (None if orientation_cov0 == -1.0
            else tilt_from_orientation(tuple(q_imu_wxyz), C_imu_b))
    return ImuSample(stamp_ns=stamp_ns,
                     f_ib_b=C_imu_b @ np.array(f_ib_imu),
                     omega_ib_b=C_imu_b @ np.array(omega_ib_imu), tilt_rp_rad=tilt,
                     noise_var=_noise_variances(accel_cov, gyro_cov))


def imu_from_cdr(raw: bytes | memoryview, C_imu_b: np.ndarray) -> ImuSample | str:
    """:func:`imu_from_values` of one serialized ``sensor_msgs/Imu`` (the live node's raw
    subscription); a message that does not decode gives its :mod:`cdr` rejection reason."""
    try:
        stamp_ns, start = cdr.imu_start(raw)
    except cdr.CdrError as exc:
        return exc.reason
    v = cdr.IMU_STRUCT.unpack_from(raw, start)
    return imu_from_values(stamp_ns, v[25:28], v[13:16], v[4], (v[3], v[0], v[1], v[2]),
                           v[28:37], v[16:25], C_imu_b)


_PLAIN_MARGIN = 0.99
"""Rows of :func:`imu_samples_from_cdr` this far inside the absurd-value limits take the
vectorised path; rows nearer a limit, or with anything unusual, take :func:`imu_from_values`."""


def imu_samples_from_cdr(raws: Sequence[bytes | memoryview], C_imu_b: np.ndarray
                         ) -> list[tuple[int, ImuSample | str]]:
    """(stamp ns or 0, :func:`imu_from_values`) of each serialized ``sensor_msgs/Imu``: the
    replay's batch decode, identical to one :func:`imu_from_cdr` per message.

    The rows of usual samples (a positive stamp, finite, well inside the limits, no
    orientation, finite covariance diagonals) are rotated in one stacked ``matmul`` (per row
    the very ``C_imu_b @ v`` product: bit-identical, checked by the tests); the others go
    through :func:`imu_from_values` one by one.
    """
    stamps, A = cdr.imu_values(raws)
    if not raws:
        return []
    f_imu, w_imu = A[:, cdr.IMU_ACCEL], A[:, cdr.IMU_OMEGA]
    diag_a, diag_g = A[:, [28, 32, 36]], A[:, [16, 20, 24]]
    with np.errstate(over='ignore', invalid='ignore'):  # the rows with these take the other path
        F = np.matmul(C_imu_b, np.ascontiguousarray(f_imu)[:, :, None])[:, :, 0]
        W = np.matmul(C_imu_b, np.ascontiguousarray(w_imu)[:, :, None])[:, :, 0]
        plain = (np.isfinite(A[:, 13:28]).all(axis=1)  # omega, its covariance, accel
                 & np.isfinite(diag_a).all(axis=1)
                 & (A[:, cdr.IMU_ORIENTATION_COV0] == -1.0)
                 & ((f_imu * f_imu).sum(axis=1)
                    < (_PLAIN_MARGIN * MAX_SPECIFIC_FORCE_MPS2) ** 2)
                 & ((w_imu * w_imu).sum(axis=1) < (_PLAIN_MARGIN * MAX_ANGULAR_RATE_RPS) ** 2))
        var_a, var_g = diag_a.max(axis=1), diag_g.max(axis=1)
        noise_ok = ((var_a > 0.0) & (var_g > 0.0) & np.isfinite(var_a + var_g)).tolist()
    noise = list(zip(var_a.tolist(), var_g.tolist()))
    out: list[tuple[int, ImuSample | str]] = []
    for i, (stamp_ns, is_plain) in enumerate(zip(stamps, plain.tolist())):
        if isinstance(stamp_ns, str):  # did not decode
            out.append((0, stamp_ns))
        elif is_plain and stamp_ns > 0:
            out.append((stamp_ns, ImuSample(stamp_ns, F[i], W[i], None,
                                            noise[i] if noise_ok[i] else None)))
        else:
            v = A[i].tolist()
            out.append((stamp_ns, imu_from_values(
                stamp_ns, tuple(v[25:28]), tuple(v[13:16]), v[4], (v[3], v[0], v[1], v[2]),
                v[28:37], v[16:25], C_imu_b)))
    return out


def _noise_variances(accel_cov: Sequence[float], gyro_cov: Sequence[float]
                     ) -> tuple[float, float] | None:
    """The largest diagonal accelerometer and gyro variances of an Imu message, or None when
    either is not given (all zero: unknown; -1: not measured) or not finite."""
    var_a = max(accel_cov[0], accel_cov[4], accel_cov[8])
    var_g = max(gyro_cov[0], gyro_cov[4], gyro_cov[8])
    if var_a > 0.0 and var_g > 0.0 and math.isfinite(var_a + var_g):
        return float(var_a), float(var_g)
    return None


_IMU_FIELDS = fields_getter(Imu, 'header.stamp.sec', 'header.stamp.nanosec',
                            'linear_acceleration.x', 'linear_acceleration.y',
                            'linear_acceleration.z', 'angular_velocity.x', 'angular_velocity.y',
                            'angular_velocity.z')
_IMU_COVARIANCES = fields_getter(Imu, 'linear_acceleration_covariance',
                                 'angular_velocity_covariance')
_IMU_ORIENTATION = fields_getter(Imu, 'orientation_covariance', 'orientation.w', 'orientation.x',
                                 'orientation.y', 'orientation.z')


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
        dt = (stamp_ns - last[0]) * 1e-9
        out = {}
        for name, pos in positions.items():
            if name not in last[1]:
                continue
            d = pos - last[1][name]
            if abs(abs(d) - 2.0 * math.pi) <= self.max_rate_rps * dt:
                d -= math.copysign(2.0 * math.pi, d)  # wrapped at +-pi
            if abs(d) > self.max_rate_rps * dt:
                return REASON_POSITION_RESET
            out[name] = d / dt
        return out


def wheel_from_joint_state(msg: JointState, names: Sequence[str], radius: float, *,
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
                             names, radius, max_speed_mps=max_speed_mps,
                             from_positions=from_positions)


def wheel_from_cdr_joint_state(raw: bytes | memoryview, names: Sequence[str], radius: float, *,
                               max_speed_mps: float = math.inf,
                               from_positions: JointRatesFromPositions | None = None
                               ) -> WheelSample | str:
    """:func:`wheel_from_joint_state` of a serialized ``sensor_msgs/JointState``; a message
    that does not decode gives its :mod:`cdr` rejection reason."""
    try:
        js = cdr.joint_state_fields(raw)
    except cdr.CdrError as exc:
        return exc.reason
    return wheel_from_joints(js.stamp_ns, js.name, js.position, js.velocity, names, radius,
                             max_speed_mps=max_speed_mps, from_positions=from_positions)


def wheel_from_joints(stamp_ns: int, joint_names: Sequence[str], position: Sequence[float],
                      velocity: Sequence[float], names: Sequence[str], radius: float, *,
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
        speeds = [radius * float(velocity[index[n]]) for n in present]
    elif from_positions is not None and len(position) == len(joint_names):
        positions = {n: float(position[index[n]]) for n in present}
        if not all(math.isfinite(v) for v in positions.values()):
            return REASON_NON_FINITE
        rates = from_positions.rates(stamp_ns, positions)
        if isinstance(rates, str):
            return rates
        present = [n for n in present if n in rates]
        speeds = [radius * rates[n] for n in present]
    else:
        return REASON_NO_VELOCITY
    if not all(math.isfinite(v) for v in speeds):
        return REASON_NON_FINITE
    if max(abs(v) for v in speeds) > max_speed_mps:
        return REASON_ABSURD_SPEED
    left = [v for n, v in zip(present, speeds) if wheel_side(n) == 'left']
    right = [v for n, v in zip(present, speeds) if wheel_side(n) == 'right']
    return WheelSample(stamp_ns=stamp_ns,
                       rim_speed_mps=sum(speeds) / len(speeds),
                       rim_speed_left_mps=sum(left) / len(left) if left else None,
                       rim_speed_right_mps=sum(right) / len(right) if right else None)


def wheel_from_odometry(msg: Odometry, track: float, *,
                        max_speed_mps: float = math.inf) -> WheelSample | str:
    """Rim speeds from a wheel-odometry ``nav_msgs/Odometry`` (differential-drive model).

    ``twist.twist.linear.x`` is the mean rim speed v (m/s) and ``angular.z`` the yaw rate w
    (rad/s, FLU so counter-clockwise positive): ``v_left = v - w*track/2``,
    ``v_right = v + w*track/2``.
    """
    return wheel_from_twist(header_stamp_ns(msg), msg.twist.twist.linear.x,
                            msg.twist.twist.angular.z, track, max_speed_mps=max_speed_mps)


def wheel_from_cdr_odometry(raw: bytes | memoryview, track: float, *,
                            max_speed_mps: float = math.inf) -> WheelSample | str:
    """:func:`wheel_from_odometry` of a serialized ``nav_msgs/Odometry``; a message that does
    not decode gives its :mod:`cdr` rejection reason."""
    try:
        stamp_ns, v, w = cdr.odometry_twist(raw)
    except cdr.CdrError as exc:
        return exc.reason
    return wheel_from_twist(stamp_ns, v, w, track, max_speed_mps=max_speed_mps)


def wheel_from_twist(stamp_ns: int, v: float, w: float, track: float, *,
                     max_speed_mps: float = math.inf) -> WheelSample | str:
    """:func:`wheel_from_odometry` of the stamp, forward speed and yaw rate of the message."""
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    v, w = float(v), float(w)
    if not (math.isfinite(v) and math.isfinite(w)):
        return REASON_NON_FINITE
    left, right = v - 0.5 * w * track, v + 0.5 * w * track
    if max(abs(v), abs(left), abs(right)) > max_speed_mps:
        return REASON_ABSURD_SPEED
    return WheelSample(stamp_ns=stamp_ns, rim_speed_mps=v, rim_speed_left_mps=left,
                       rim_speed_right_mps=right)
