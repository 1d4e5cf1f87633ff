"""The Pathfinder rover's fixed facts: wheel joints and geometry, IMU mounting, IMU datasheet
noise and the assumed RTK accuracy (see :mod:`slip_estimator.pathfinder` for how they were
checked against the logs)."""
from __future__ import annotations

import math

WHEEL_JOINT_NAMES = ('front_left_wheel_joint', 'front_right_wheel_joint',
                     'rear_left_wheel_joint', 'rear_right_wheel_joint')
WHEEL_RADIUS_M = 0.12
TRACK_WIDTH_M = 0.685
IMU_TO_BASE_RPY = (math.pi, 0.0, 0.0)
"""imu_link (x fwd, y right, z down) in base_link (FLU): a 180 deg roll."""

# ADIS16495-2 datasheet figures quoted by the paper (README "Rover facts").
GYRO_ARW_RAD_PER_SQRT_S = math.radians(0.1) / 60.0        # 0.1 deg/sqrt(h)
ACCEL_VRW_MPS_PER_SQRT_S = 0.008 / 60.0                     # 0.008 m/s/sqrt(h)
GYRO_BIAS_INSTABILITY_RPS = math.radians(1.6) / 3600.0     # 1.6 deg/h
ACCEL_BIAS_INSTABILITY_MPS2 = 3.2e-6 * 9.80665              # 3.2 micro-g
BIAS_CORRELATION_TIME_S = 100.0
"""Time over which a bias random walk is allowed to reach the in-run bias instability."""

RTK_SIGMA_M = (0.02, 0.02, 0.04)
"""Assumed 1-sigma (E, N, U) of test17run's RTK-grade fixes; the log carries no sigmas (rest
scatter is 2 / 2 / 4 mm, absolute accuracy of RTK is cm level)."""
