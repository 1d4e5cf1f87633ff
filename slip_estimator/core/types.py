"""Plain records exchanged between the ROS/bag boundary and the estimation core.

Frames (see :mod:`slip_estimator.core.frames` for the full convention):

* ``b``  -- the rover body frame in Groves' FRD convention (x forward, y right, z down),
  co-located with the IMU. ``base_link`` (ROS FLU) differs by a 180 deg roll.
* ``n``  -- local-level navigation frame, NED (north, east, down).
* ``o``  -- ROS ``odom`` frame: ENU axes, origin at the initial base_link position.

Everything here is SI. Times are integer nanoseconds (``stamp_ns``), as at the ROS boundary.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SLIP_CLASS_NAMES = ('none', 'low', 'medium', 'high', 'extreme')
"""Slip classes by index: 0 none (rover not moving), 1 low 0<|s|<=0.2, 2 medium <=0.4,
3 high <=0.7, 4 extreme <=1.0."""

SLIP_CLASS_UPPER_BOUNDS = (0.2, 0.4, 0.7)

MAX_SPECIFIC_FORCE_MPS2 = 1000.0
"""IMU samples beyond this specific-force norm (about 100 g) are physically absurd for a rover."""
MAX_ANGULAR_RATE_RPS = 100.0
"""IMU samples beyond this angular-rate norm are physically absurd for a rover."""
"""Upper |s| bounds of classes low, medium and high; anything larger is extreme."""


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One IMU sample, already rotated into the body frame ``b`` (FRD).

    Attributes
    ----------
    stamp_ns : sample time, ns.
    f_ib_b : specific force of b w.r.t. inertial space, resolved in b, m/s^2 (at rest on a level
        surface approximately (0, 0, -g) in FRD).
    omega_ib_b : angular rate of b w.r.t. inertial space, resolved in b, rad/s.
    tilt_rp_rad : roll and pitch of b (FRD in NED), rad, from the IMU's own orientation when
        its message says it provides one (``orientation_covariance[0] != -1``); else None.
    """

    stamp_ns: int
    f_ib_b: np.ndarray
    omega_ib_b: np.ndarray
    tilt_rp_rad: tuple[float, float] | None = None
    noise_var: tuple[float, float] | None = None
    """Per-sample noise variances (accelerometer m^2/s^4, gyro rad^2/s^2) from the message's
    covariances when it gives them (largest diagonal element > 0), else None."""


@dataclass(frozen=True, slots=True)
class WheelSample:
    """One wheel-encoder sample, reduced to rim speeds.

    Attributes
    ----------
    stamp_ns : sample time, ns.
    rim_speed_mps : mean forward rim speed r*omega of all wheels, m/s (forward positive).
    rim_speed_left_mps, rim_speed_right_mps : mean rim speed of the left / right wheels, m/s,
        or None when the side is unknown.
    """

    stamp_ns: int
    rim_speed_mps: float
    rim_speed_left_mps: float | None = None
    rim_speed_right_mps: float | None = None

    @property
    def rim_difference_mps(self) -> float | None:
        """Right minus left mean rim speed, m/s (None without per-side speeds)."""
        if self.rim_speed_left_mps is None or self.rim_speed_right_mps is None:
            return None
        return self.rim_speed_right_mps - self.rim_speed_left_mps


@dataclass(frozen=True, slots=True)
class SlipEstimate:
    """Slip at one wheel sample time (paper eq. 1, 29).

    Attributes
    ----------
    stamp_ns : the wheel sample time the estimate refers to, ns.
    slip_ratio : s in [-1, 1]; NaN when unknown (then ``slip_class`` is -1).
    slip_ratio_std : 1-sigma of s from the filter velocity covariance, the wheel noise and the
        slip change the step test cannot see (:mod:`slip_estimator.core.slip_confidence`).
    slip_class : 0..4, index into SLIP_CLASS_NAMES, or -1 when unknown.
    body_speed_mps : forward body velocity v_x at the wheel contact point, from the INS, m/s.
    body_speed_std_mps : its 1-sigma, m/s.
    wheel_speed_mps : rim speed r*omega, m/s.
    slip_ratio_left, slip_ratio_right : per-side slip when the sides are known, else None.
    p_medium_or_worse : probability that the slip is medium or worse (beyond 0.2 on the
        reading's side), allowing for a wrong reading
        (:mod:`slip_estimator.core.slip_confidence`); NaN when unknown.
    resolved : the class is one the slip and its 1-sigma resolve; False where a medium-or-worse
        reading is within its error (the filter's, or the published one where that is wider
        than the medium class; or the rim's timing) of the low class and no resolved hold
        supports it (then ``slip_class`` is low).
    """

    stamp_ns: int
    slip_ratio: float
    slip_ratio_std: float
    slip_class: int
    body_speed_mps: float
    body_speed_std_mps: float
    wheel_speed_mps: float
    slip_ratio_left: float | None = None
    slip_ratio_right: float | None = None
    p_medium_or_worse: float = float('nan')
    resolved: bool = True

    @property
    def class_name(self) -> str:
        """Class name, or 'unknown'."""
        return SLIP_CLASS_NAMES[self.slip_class] if self.slip_class >= 0 else 'unknown'


@dataclass(frozen=True, slots=True)
class OdometryEstimate:
    """Fused pose and twist of base_link in the ROS odom frame (REP-103/105 conventions).

    Attributes
    ----------
    stamp_ns : time of the IMU sample this solution belongs to, ns.
    p_ob_o : base_link position in odom (ENU axes, origin at the start), m.
    q_ob_wxyz : orientation of base_link (FLU) in odom (ENU), unit quaternion (w, x, y, z).
    v_ob_b : base_link linear velocity resolved in base_link (FLU), m/s.
    omega_ob_b : base_link angular velocity resolved in base_link (FLU), rad/s.
    pose_covariance : 6x6, order (x, y, z, rot_x, rot_y, rot_z) in odom, m^2 / rad^2.
    twist_covariance : 6x6, order (vx, vy, vz, wx, wy, wz) in base_link.
    """

    stamp_ns: int
    p_ob_o: np.ndarray
    q_ob_wxyz: np.ndarray
    v_ob_b: np.ndarray
    omega_ob_b: np.ndarray
    pose_covariance: np.ndarray
    twist_covariance: np.ndarray


@dataclass(frozen=True, slots=True)
class Health:
    """Self-diagnosis of the estimator for ``/diagnostics``.

    Attributes
    ----------
    level : 0 OK, 1 WARN, 2 ERROR (diagnostic_msgs/DiagnosticStatus levels).
    message : one-line summary (state and any suspected fault).
    values : named figures (rates, counters, NIS statistics, bias estimates), already SI.
    """

    level: int
    message: str
    values: dict


def imu_values_usable(f_ib_b: list[float], omega_ib_b: list[float]) -> bool:
    """Finite, and within :data:`MAX_SPECIFIC_FORCE_MPS2` / :data:`MAX_ANGULAR_RATE_RPS` (a
    finite but absurd sample would wreck the INS in one step)."""
    f, w = f_ib_b, omega_ib_b
    if not math.isfinite(sum(f) + sum(w)):  # NaN/Inf anywhere
        return False
    return not (f[0] * f[0] + f[1] * f[1] + f[2] * f[2] > MAX_SPECIFIC_FORCE_MPS2 ** 2
                or w[0] * w[0] + w[1] * w[1] + w[2] * w[2] > MAX_ANGULAR_RATE_RPS ** 2)


def wheel_speeds(sample: WheelSample) -> list[float]:
    """The rim speeds a wheel sample carries (mean, and left/right when known), m/s."""
    return [v for v in (sample.rim_speed_mps, sample.rim_speed_left_mps,
                        sample.rim_speed_right_mps) if v is not None]
