"""Core records -> ROS messages: odometry, slip and health diagnostics, the slip vector.

Pure functions: no rclpy node, no I/O. Outputs are in ROS conventions already
(``OdometryEstimate`` is odom/ENU, base_link/FLU). Diagnostic values are formatted so that no
'nan'/'inf' text is ever produced (``'unknown'`` instead); every message still passes
:func:`slip_estimator.ros.finite.message_is_finite` before it goes out.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
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
from std_msgs.msg import Header

from slip_estimator.core.types import Health, OdometryEstimate, SlipEstimate
from slip_estimator.ros import msgbuild
from slip_estimator.ros.msgbuild import build
from slip_estimator.ros.stamps import ns_to_stamp

SLIP_STATUS_NAME = 'slip_estimator: wheel slip'
HEALTH_STATUS_NAME = 'slip_estimator: estimator'
UNKNOWN = 'unknown'

_SLIP_LEVEL_BY_CLASS = {
    0: DiagnosticStatus.OK, 1: DiagnosticStatus.OK, 2: DiagnosticStatus.WARN,
    3: DiagnosticStatus.ERROR, 4: DiagnosticStatus.ERROR,
}


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
        'p_medium_or_worse': est.p_medium_or_worse,
        'slip_resolved': est.resolved,
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
