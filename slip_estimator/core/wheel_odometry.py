"""Wheel-only dead reckoning: the degraded mode for an IMU the filter cannot use.

Planar differential-drive kinematics in the odom frame (ENU, origin at the first sample,
heading from ``initial_heading_deg``): forward speed the mean rim speed, yaw rate the wheel
differential over the (effective) track width. Slip is not observable without the IMU: this
gives a pose, with covariances that grow with the distance and the turning, and nothing else.
Only the standard library and numpy are used.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.types import OdometryEstimate, WheelSample

SPEED_STD_FRACTION = 0.1
"""Forward speed 1-sigma as a fraction of the rim speed (unknown slip)."""
_YAW_RATE_STD_FRACTION = 0.3
"""Yaw rate 1-sigma as a fraction of the wheel-differential yaw rate (skid-steer scrub)."""


class WheelDeadReckoning:
    """Integrates wheel samples into a planar pose of base_link in odom (ENU/FLU)."""

    def __init__(self, yaw0_rad: float) -> None:
        self.yaw_rad = yaw0_rad
        self.x_m = self.y_m = 0.0
        self.var_xy_m2 = 0.0
        self.var_yaw_rad2 = 0.0
        self.speed_mps = self.yaw_rate_rps = 0.0
        self.stamp_ns: int | None = None

    def add(self, sample: WheelSample, track_width_m: float,
            yaw_rad: float | None = None) -> None:
        """Integrate up to ``sample``; the heading from the wheel differential, or, given
        ``yaw_rad`` (ENU yaw at the sample, e.g. the gyro's), along it (wheels + gyro)."""
        if sample.rim_speed_left_mps is not None and sample.rim_speed_right_mps is not None:
            rate = (sample.rim_speed_right_mps - sample.rim_speed_left_mps) / track_width_m
        else:
            rate = 0.0
        if self.stamp_ns is not None:
            dt = (sample.stamp_ns - self.stamp_ns) * 1e-9
            if yaw_rad is not None and dt > 0.0:
                # the mean rate to the given heading (wrapped), kept for the next step
                self.yaw_rate_rps = math.remainder(yaw_rad - self.yaw_rad, math.tau) / dt
            if 0.0 < dt < 1.0:
                mid = self.yaw_rad + 0.5 * self.yaw_rate_rps * dt
                self.x_m += self.speed_mps * math.cos(mid) * dt
                self.y_m += self.speed_mps * math.sin(mid) * dt
                self.yaw_rad += self.yaw_rate_rps * dt
                step = abs(self.speed_mps) * dt
                self.var_yaw_rad2 += (_YAW_RATE_STD_FRACTION * self.yaw_rate_rps * dt) ** 2
                self.var_xy_m2 += (SPEED_STD_FRACTION * step) ** 2 + self.var_yaw_rad2 * step ** 2
        if yaw_rad is not None:
            self.yaw_rad, rate = yaw_rad, self.yaw_rate_rps
        self.stamp_ns = sample.stamp_ns
        self.speed_mps, self.yaw_rate_rps = sample.rim_speed_mps, rate

    def estimate(self, stamp_ns: int) -> OdometryEstimate | None:
        if self.stamp_ns is None:
            return None
        half = 0.5 * self.yaw_rad
        pose_cov = np.diag([self.var_xy_m2, self.var_xy_m2, 1.0, 1.0, 1.0,
                            self.var_yaw_rad2])
        twist_cov = np.diag([(SPEED_STD_FRACTION * self.speed_mps) ** 2 + 1e-4, 1e-2, 1e-2,
                             1.0, 1.0,
                             (_YAW_RATE_STD_FRACTION * self.yaw_rate_rps) ** 2 + 1e-4])
        return OdometryEstimate(stamp_ns, np.array([self.x_m, self.y_m, 0.0]),
                                np.array([math.cos(half), 0.0, 0.0, math.sin(half)]),
                                np.array([self.speed_mps, 0.0, 0.0]),
                                np.array([0.0, 0.0, self.yaw_rate_rps]), pose_cov, twist_cov)
