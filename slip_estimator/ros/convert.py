"""ROS messages -> core records: the one place where input messages become records.

Pure functions: no rclpy node, no I/O. The live node, the bag replay and the tests share them
(records -> messages: :mod:`slip_estimator.ros.publish`; the no-NaN guard of every output:
:mod:`slip_estimator.ros.finite`). The parts, each re-exported here:

* :mod:`~slip_estimator.ros.convert_imu`: ``sensor_msgs/Imu`` -> ``ImuSample`` in the core body
  frame b (FRD). REP-145: ``linear_acceleration`` is the specific force (at rest and level a
  z-up IMU reads about +9.81 m/s^2 on z) and ``angular_velocity`` the body rate, both resolved
  in the IMU frame, rotated with ``C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)``
  (frame conventions: :mod:`slip_estimator.core.frames`).
* :mod:`~slip_estimator.ros.convert_wheels`: ``sensor_msgs/JointState`` and wheel-odometry
  ``nav_msgs/Odometry`` -> ``WheelSample`` (rim speeds).
* :mod:`~slip_estimator.ros.stamps`: ``builtin_interfaces/Time`` <-> integer nanoseconds.
* :mod:`~slip_estimator.ros.rejections`: the rejection reasons.

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

from slip_estimator.ros.convert_imu import (imu_from_cdr, imu_from_msg, imu_from_values,
                                            imu_samples_from_cdr)
from slip_estimator.ros.convert_wheels import (JointRatesFromPositions, wheel_from_cdr_joint_state,
                                               wheel_from_cdr_odometry, wheel_from_joint_state,
                                               wheel_from_joints, wheel_from_odometry,
                                               wheel_from_twist, wheel_side)
from slip_estimator.ros.rejections import (REASON_ABSURD_IMU, REASON_ABSURD_SPEED,
                                           REASON_FIRST_POSITION, REASON_NO_VELOCITY,
                                           REASON_NO_WHEEL_JOINTS, REASON_NON_FINITE,
                                           REASON_POSITION_RESET, REASON_ZERO_STAMP)
from slip_estimator.ros.stamps import NS_PER_S, header_stamp_ns, ns_to_stamp, stamp_to_ns

__all__ = [
    'NS_PER_S', 'REASON_ABSURD_IMU', 'REASON_ABSURD_SPEED', 'REASON_FIRST_POSITION',
    'REASON_NON_FINITE', 'REASON_NO_VELOCITY', 'REASON_NO_WHEEL_JOINTS', 'REASON_POSITION_RESET',
    'REASON_ZERO_STAMP', 'JointRatesFromPositions', 'header_stamp_ns', 'imu_from_cdr',
    'imu_from_msg', 'imu_from_values', 'imu_samples_from_cdr', 'ns_to_stamp', 'stamp_to_ns',
    'wheel_from_cdr_joint_state', 'wheel_from_cdr_odometry', 'wheel_from_joint_state',
    'wheel_from_joints', 'wheel_from_odometry', 'wheel_from_twist', 'wheel_side',
]
