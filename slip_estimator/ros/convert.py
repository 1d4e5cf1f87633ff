"""ROS message <-> core record conversions: the one place where messages become records.

Pure functions: no rclpy node, no I/O. The live node, the bag replay and the tests share them.

Frames and conventions (see :mod:`slip_estimator.core.frames`):

* ``sensor_msgs/Imu`` follows REP-145: ``linear_acceleration`` is the specific force (at rest
  and level a z-up IMU reads about +9.81 m/s^2 on z) and ``angular_velocity`` the body rate,
  both resolved in the IMU frame. :func:`imu_from_msg` rotates them into the core body frame b
  (FRD) with ``C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)``.
* Outputs are in ROS conventions already (``OdometryEstimate`` is odom/ENU, base_link/FLU).

Input converters return either a record or a short *reason* string (``'non_finite'``,
``'zero_stamp'``, ...) that the caller counts; they never raise on bad data. Output converters
format diagnostic values so that no 'nan'/'inf' text is ever produced (``'unknown'`` instead).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from operator import attrgetter
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Twist,
    TwistWithCovariance,
    Vector3,
    Vector3Stamped,
)
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header

from slip_estimator.core.alignment import tilt_from_orientation
from slip_estimator.core.types import (
    MAX_ANGULAR_RATE_RPS,
    MAX_SPECIFIC_FORCE_MPS2,
    Health,
    ImuSample,
    OdometryEstimate,
    SlipEstimate,
    WheelSample,
)
from slip_estimator.ros import msgbuild
from slip_estimator.ros.msgbuild import build, fields_getter, slot_of
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

SLIP_STATUS_NAME = 'slip_estimator: wheel slip'
HEALTH_STATUS_NAME = 'slip_estimator: estimator'
UNKNOWN = 'unknown'

_SLIP_LEVEL_BY_CLASS = {
    0: DiagnosticStatus.OK, 1: DiagnosticStatus.OK, 2: DiagnosticStatus.WARN,
    3: DiagnosticStatus.ERROR, 4: DiagnosticStatus.ERROR,
}


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
    """Body-frame IMU sample from a REP-145 ``sensor_msgs/Imu``, or a rejection reason.

    ``f_ib_b = C_imu_b @ f_ib_imu`` and ``omega_ib_b = C_imu_b @ omega_ib_imu``: the lever arm
    does not matter for rates, and for the specific force it is ignored (rover body rates are
    small; the mounting offset is the core's business if ever needed).
    """
    sec, nanosec, ax, ay, az, wx, wy, wz = _IMU_FIELDS(msg)  # this runs at the IMU rate
    stamp_ns = int(sec) * NS_PER_S + int(nanosec)
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    f_ib_imu = (ax, ay, az)
    omega_ib_imu = (wx, wy, wz)
    # A finite sum has finite terms; a non-finite one may be an overflow of finite terms.
    if (not math.isfinite(sum(f_ib_imu) + sum(omega_ib_imu))
            and not all(map(math.isfinite, f_ib_imu + omega_ib_imu))):
        return REASON_NON_FINITE
    if (math.hypot(*f_ib_imu) > MAX_SPECIFIC_FORCE_MPS2
            or math.hypot(*omega_ib_imu) > MAX_ANGULAR_RATE_RPS):
        return REASON_ABSURD_IMU
    cov, *q_wxyz = _IMU_ORIENTATION(msg)
    # orientation_covariance[0] = -1: no orientation (REP-145); anything else: provided.
    tilt = None if cov[0] == -1.0 else tilt_from_orientation(q_wxyz, C_imu_b)
    return ImuSample(stamp_ns=stamp_ns,
                     f_ib_b=C_imu_b @ np.array(f_ib_imu),
                     omega_ib_b=C_imu_b @ np.array(omega_ib_imu), tilt_rp_rad=tilt,
                     noise_var=_noise_variances(*_IMU_COVARIANCES(msg)))


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
    stamp_ns = header_stamp_ns(msg)
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    index = {n: i for i, n in enumerate(msg.name)}
    present = [n for n in names if n in index]
    if not present:
        return REASON_NO_WHEEL_JOINTS
    velocity = msg.velocity
    if len(velocity) == len(msg.name):
        speeds = [radius * float(velocity[index[n]]) for n in present]
    elif from_positions is not None and len(msg.position) == len(msg.name):
        positions = {n: float(msg.position[index[n]]) for n in present}
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
    stamp_ns = header_stamp_ns(msg)
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    v = float(msg.twist.twist.linear.x)
    w = float(msg.twist.twist.angular.z)
    if not (math.isfinite(v) and math.isfinite(w)):
        return REASON_NON_FINITE
    left, right = v - 0.5 * w * track, v + 0.5 * w * track
    if max(abs(v), abs(left), abs(right)) > max_speed_mps:
        return REASON_ABSURD_SPEED
    return WheelSample(stamp_ns=stamp_ns, rim_speed_mps=v, rim_speed_left_mps=left,
                       rim_speed_right_mps=right)


# --- outputs --------------------------------------------------------------------------------------
def format_value(value: Any) -> str:
    """Text of a diagnostic value: numbers as '%.6g', non-finite numbers as 'unknown'.

    Sequences and arrays become '[a, b, c]' element-wise; None becomes 'unknown'.
    """
    if value is None:
        return UNKNOWN
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return f'{float(value):.6g}' if math.isfinite(value) else UNKNOWN
    if isinstance(value, str):
        return value
    if isinstance(value, (np.ndarray, list, tuple)):
        return '[' + ', '.join(format_value(v) for v in np.asarray(value).ravel().tolist()) + ']'
    return str(value)


def key_values(values: Mapping[str, Any]) -> list[KeyValue]:
    """KeyValues of a mapping, values formatted with :func:`format_value`."""
    return [build(KeyValue, str(k), format_value(v)) for k, v in values.items()]


def _stamped_header(stamp_ns: int, frame_id: str = '') -> Header:
    return build(Header, ns_to_stamp(stamp_ns), frame_id)


def odometry_to_msg(odo: OdometryEstimate, odom_frame: str, base_frame: str) -> Odometry:
    """``nav_msgs/Odometry`` of the fused solution (pose in odom, twist in base_link)."""
    x, y, z = np.asarray(odo.p_ob_o, dtype=float).tolist()
    qw, qx, qy, qz = np.asarray(odo.q_ob_wxyz, dtype=float).tolist()
    vx, vy, vz = np.asarray(odo.v_ob_b, dtype=float).tolist()
    wx, wy, wz = np.asarray(odo.omega_ob_b, dtype=float).tolist()
    pose = build(Pose, build(Point, x, y, z), build(Quaternion, qx, qy, qz, qw))
    twist = build(Twist, build(Vector3, vx, vy, vz), build(Vector3, wx, wy, wz))
    return build(Odometry, _stamped_header(odo.stamp_ns, odom_frame), base_frame,
                 build(PoseWithCovariance, pose,
                       np.asarray(odo.pose_covariance, dtype=float).reshape(36)),
                 build(TwistWithCovariance, twist,
                       np.asarray(odo.twist_covariance, dtype=float).reshape(36)))


def _diagnostic_array(stamp_ns: int, level: bytes, name: str, message: str, hardware_id: str,
                      values: Mapping[str, Any]) -> DiagnosticArray:
    """A one-status ``DiagnosticArray``, values formatted with :func:`format_value`."""
    status = build(DiagnosticStatus, level, name, message, hardware_id, key_values(values))
    return build(DiagnosticArray, _stamped_header(stamp_ns), [status])


def slip_level(slip_class: int) -> bytes:
    """Diagnostic level of a slip class: OK none/low, WARN medium, ERROR high/extreme,
    STALE unknown."""
    return _SLIP_LEVEL_BY_CLASS.get(slip_class, DiagnosticStatus.STALE)


def slip_to_diagnostic_array(est: SlipEstimate, hardware_id: str) -> DiagnosticArray:
    """One-status ``DiagnosticArray`` stamped with the wheel sample time of ``est``."""
    values: dict[str, Any] = {
        'slip_ratio': est.slip_ratio,
        'slip_class': est.slip_class if est.slip_class >= 0 else None,
        'slip_ratio_std': est.slip_ratio_std,
        'body_speed': est.body_speed_mps,
        'body_speed_std': est.body_speed_std_mps,
        'wheel_speed': est.wheel_speed_mps,
    }
    if est.slip_ratio_left is not None:
        values['slip_ratio_left'] = est.slip_ratio_left
    if est.slip_ratio_right is not None:
        values['slip_ratio_right'] = est.slip_ratio_right
    return _diagnostic_array(est.stamp_ns, slip_level(est.slip_class), SLIP_STATUS_NAME,
                             est.class_name, hardware_id, values)


def slip_is_known(est: SlipEstimate) -> bool:
    """True when the estimate has a class and finite slip ratio and 1-sigma."""
    return (est.slip_class >= 0 and math.isfinite(est.slip_ratio)
            and math.isfinite(est.slip_ratio_std))


def slip_to_vector3(est: SlipEstimate, frame_id: str) -> Vector3Stamped | None:
    """Numeric companion of the slip status: x = slip ratio, y = its 1-sigma, z = class index.

    None when the estimate is unknown (nothing is published then).
    """
    if not slip_is_known(est):
        return None
    return build(Vector3Stamped, _stamped_header(est.stamp_ns, frame_id),
                 build(Vector3, float(est.slip_ratio), float(est.slip_ratio_std),
                       float(est.slip_class)))


def health_to_diagnostic_array(health: Health, stamp_ns: int, hardware_id: str,
                               extra_values: Mapping[str, Any] | None = None, *,
                               name: str = HEALTH_STATUS_NAME) -> DiagnosticArray:
    """``/diagnostics`` message: the estimator's Health plus ``extra_values`` (node counters)."""
    values = dict(health.values)
    if extra_values:
        values.update(extra_values)
    level = max(DiagnosticStatus.OK[0], min(int(health.level), DiagnosticStatus.STALE[0]))
    return _diagnostic_array(stamp_ns, bytes([level]), name, health.message, hardware_id,
                             values)


def stale_diagnostic_array(message: str, stamp_ns: int, hardware_id: str,
                           values: Mapping[str, Any] | None = None) -> DiagnosticArray:
    """A STALE ``/diagnostics`` status (live node: no IMU data)."""
    return _diagnostic_array(stamp_ns, DiagnosticStatus.STALE, HEALTH_STATUS_NAME, message,
                             hardware_id, values or {})


# --- output guard ---------------------------------------------------------------------------------
_INT_TYPES = frozenset({'boolean', 'octet', 'char', 'byte', 'int8', 'uint8', 'int16', 'uint16',
                        'int32', 'uint32', 'int64', 'uint64', 'builtin_interfaces/Time',
                        'builtin_interfaces/Duration'})


@dataclass(frozen=True, slots=True)
class _GuardPlan:
    """Where a message class can hold a float or a string (integers, stamps and durations
    cannot be NaN). Fields of nested messages are flattened into dotted paths, so that one
    ``attrgetter`` call fetches all scalar floats (or all strings) of the message."""

    floats: Callable[[Any], tuple] | None
    texts: Callable[[Any], tuple] | None
    arrays: tuple[Callable[[Any], Any], ...]
    sequences: tuple[Callable[[Any], Any], ...]

    @property
    def texts_only(self) -> bool:
        """Only strings to check (e.g. ``KeyValue``)."""
        return self.floats is None and not self.arrays and not self.sequences


_GUARD_PLANS: dict[type, _GuardPlan] = {}


def _getter(paths: list[str]) -> Callable[[Any], tuple] | None:
    """``attrgetter`` of the dotted paths that always returns a tuple (None for no path)."""
    if not paths:
        return None
    if len(paths) == 1:
        get = attrgetter(paths[0])
        return lambda msg: (get(msg),)
    return attrgetter(*paths)


def _collect_fields(cls: type, prefix: str, kinds: dict[str, list[str]]) -> None:
    sample = cls()  # field kinds are static per class: read them off a default instance
    for name, kind in cls.get_fields_and_field_types().items():
        if kind.split('[')[0].removeprefix('sequence<').rstrip('>') in _INT_TYPES:
            continue
        slot = slot_of(cls, name)
        value, path = getattr(sample, slot), prefix + slot
        if isinstance(value, float):
            kinds['floats'].append(path)
        elif isinstance(value, str):
            kinds['texts'].append(path)
        elif isinstance(value, np.ndarray):
            kinds['arrays'].append(path)
        elif isinstance(value, (list, tuple)) or type(value).__name__ == 'array':
            kinds['sequences'].append(path)
        elif hasattr(value, 'get_fields_and_field_types'):
            _collect_fields(type(value), path + '.', kinds)


def _guard_plan(cls: type) -> _GuardPlan:
    """The :class:`_GuardPlan` of ``cls``, made once per message class: the guard runs on
    every output."""
    plan = _GUARD_PLANS.get(cls)
    if plan is None:
        kinds: dict[str, list[str]] = {'floats': [], 'texts': [], 'arrays': [], 'sequences': []}
        _collect_fields(cls, '', kinds)
        plan = _GuardPlan(_getter(kinds['floats']), _getter(kinds['texts']),
                          tuple(attrgetter(p) for p in kinds['arrays']),
                          tuple(attrgetter(p) for p in kinds['sequences']))
        _GUARD_PLANS[cls] = plan
    return plan


def message_is_finite(msg: Any) -> bool:
    """True when no float field of a ROS message (recursively, arrays included) is NaN/Inf and
    no string field spells a non-finite number ('nan', 'inf', ...).

    The last line of defence before publishing: whatever the core returns, no NaN goes out.
    """
    plan = _GUARD_PLANS.get(type(msg)) or _guard_plan(type(msg))
    if plan.floats is not None:
        values = plan.floats(msg)
        # A finite sum means every term is finite (inf and NaN propagate); a non-finite sum
        # may also be an overflow of finite terms, so then each term is checked.
        if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
            return False
    if plan.texts is not None:
        for text in plan.texts(msg):
            if not text_is_finite(text):
                return False
    for get in plan.arrays:
        value = get(msg)
        if isinstance(value, np.ndarray) and value.dtype.kind == 'f':
            # As above: a finite sum (of Python floats, which overflow without a warning)
            # means finite elements; otherwise each element is checked.
            flat = value.reshape(-1)
            if not math.isfinite(sum(flat.tolist())) and not np.isfinite(flat).all():
                return False
        elif not _items_are_finite(value):
            return False
    for get in plan.sequences:
        if not _items_are_finite(get(msg)):
            return False
    return True


def _items_are_finite(items: Any) -> bool:
    for item in items:
        if isinstance(item, float):
            if not math.isfinite(item):
                return False
        elif isinstance(item, str):
            if not text_is_finite(item):
                return False
        else:
            plan = _GUARD_PLANS.get(type(item))
            if plan is None:
                if not hasattr(item, 'get_fields_and_field_types'):
                    continue
                plan = _guard_plan(type(item))
            if plan.texts_only:  # diagnostic KeyValues: check the strings here
                for text in plan.texts(item):
                    if not text_is_finite(text):
                        return False
            elif not message_is_finite(item):
                return False
    return True


def text_is_finite(text: str) -> bool:
    """False when ``text`` parses as a non-finite number ('nan', '-inf', '1e999', ...)."""
    if len(text) > 12 or not text:
        return True
    # float() parses only what starts (after blanks) with a sign, a point, a digit or the
    # n/i of nan/inf: skip the parse (and its exception) for names like 'odom'.
    first = text.lstrip()[:1]
    if not first or (first not in '+-.nNiI' and not first.isdecimal()):
        return True
    try:
        return math.isfinite(float(text))
    except ValueError:
        return True


def _sample_outputs() -> list[Any]:
    """Every output converter once, for :func:`msgbuild.enable_fast_build`'s check."""
    odo = OdometryEstimate(1_234_567_890_123, np.array([1.0, -2.0, 3.0]),
                           np.array([0.5, 0.5, -0.5, 0.5]), np.array([0.1, 0.2, 0.3]),
                           np.array([-0.01, 0.02, -0.03]), np.arange(36.0).reshape(6, 6),
                           -np.arange(36.0).reshape(6, 6))
    slip = SlipEstimate(-1_500_000_000, 0.25, 0.01, 2, 0.4, 0.01, 0.55, 0.2, 0.3)
    health = Health(1, 'running', {'a': 1.5, 'b': [0.1, 0.2], 'c': None})
    return [odometry_to_msg(odo, 'odom', 'base_link'),
            slip_to_diagnostic_array(slip, 'base_link'), slip_to_vector3(slip, 'base_link'),
            health_to_diagnostic_array(health, 7, 'base_link', {'n': 3}),
            stale_diagnostic_array('no IMU data', 8, 'base_link')]


msgbuild.enable_fast_build(_sample_outputs)
