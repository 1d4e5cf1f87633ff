"""Figures measured on a Pathfinder log: motion, rim and GNSS speed, wheel/IMU lag, noise at
rest, initial heading (the importer prints them; see :mod:`slip_estimator.pathfinder`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slip_estimator.core.planet import EARTH, llh_to_local_enu
from slip_estimator.pathfinder.log import PathfinderLog
from slip_estimator.robot_setup.heading import HeadingEstimate, heading_from_track
from slip_estimator.pathfinder.rover import (
    ACCEL_VRW_MPS_PER_SQRT_S,
    GYRO_ARW_RAD_PER_SQRT_S,
    WHEEL_JOINT_NAMES,
    WHEEL_RADIUS_M,
)


@dataclass(frozen=True)
class LogFacts:
    """Figures checked on a log (printed by the importer, used by the tests)."""

    imu_rate_hz: float
    wheel_rate_hz: float
    gnss_rate_hz: float
    imu_span_s: tuple[float, float]
    wheel_span_s: tuple[float, float]
    gnss_span_s: tuple[float, float]
    rest_f_ib_imu: tuple[float, float, float]
    motion_start_s: float
    motion_end_s: float
    gnss_over_wheel_speed: float
    wheel_lag_s: float
    wheel_lag_corr: float
    gyro_noise_density_rps_rthz: float
    accel_noise_density_mps2_rthz: float
    heading: HeadingEstimate
    notes: tuple[str, ...] = field(default_factory=tuple)


def rim_speed_mps(log: PathfinderLog, wheel_radius_m: float = WHEEL_RADIUS_M) -> np.ndarray:
    """Mean forward rim speed r * omega of the four wheels at the wheel times, m/s."""
    return wheel_radius_m * log.wheel_rate_rps.mean(axis=1)


def motion_interval(log: PathfinderLog, threshold_mps: float = 0.02) -> tuple[float, float]:
    """First and last wheel time (Unix s) with mean rim speed above ``threshold_mps``."""
    moving = np.abs(rim_speed_mps(log)) > threshold_mps
    if not moving.any():
        return float('nan'), float('nan')
    t = log.wheel_t_s[moving]
    return float(t[0]), float(t[-1])


def _window_mean(t: np.ndarray, x: np.ndarray, tq: np.ndarray, width_s: float) -> np.ndarray:
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    i0 = np.searchsorted(t, tq - width_s / 2)
    i1 = np.searchsorted(t, tq + width_s / 2)
    n = np.maximum(i1 - i0, 1)
    return (c[i1] - c[i0]) / (n if x.ndim == 1 else n[:, None])


def gnss_enu(log: PathfinderLog) -> np.ndarray:
    """GNSS positions in ENU (m) relative to the first fix."""
    return np.array([llh_to_local_enu(EARTH, p, log.gnss_llh[0]) for p in log.gnss_llh])


def wheel_differential_rps(log: PathfinderLog) -> np.ndarray:
    """Right minus left wheel rate (each side summed over its wheels; sides from
    :data:`WHEEL_JOINT_NAMES`), rad/s, at the wheel times: the yaw-rate signal of the wheels."""
    from slip_estimator.streams import wheel_side

    r = log.wheel_rate_rps
    sides = [wheel_side(n) for n in WHEEL_JOINT_NAMES]
    right = [k for k, s in enumerate(sides) if s == 'right']
    diff = r[:, right[0]]
    for k in right[1:]:
        diff = diff + r[:, k]
    for k in (k for k, s in enumerate(sides) if s == 'left'):
        diff = diff - r[:, k]
    return diff


def wheel_imu_lag(log: PathfinderLog, max_lag_s: float = 0.4) -> tuple[float, float]:
    """Lag of the wheel stamps behind the IMU, s, and the correlation at that lag.

    Cross-correlates the gyro yaw rate (0.1 s means) with the wheel differential (right - left)
    rate. A positive result means a wheel sample stamped t describes the motion at IMU time
    t - lag.
    """
    from slip_estimator.core.timing import best_lag

    t = log.wheel_t_s
    inside = (t > log.imu_t_s[0] + 1.0) & (t < log.imu_t_s[-1] - 1.0)
    diff = wheel_differential_rps(log)
    # z down: a left (counter-clockwise) turn is a negative Gz and a positive R - L.
    return best_lag(log.imu_t_s, -log.omega_ib_imu[:, 2], t[inside], diff[inside], max_lag_s)


def gnss_over_wheel_speed(log: PathfinderLog, wheel_radius_m: float = WHEEL_RADIUS_M,
                          window_s: float = 1.0, min_speed_mps: float = 0.3) -> float:
    """Ratio of GNSS ground speed to rim speed while moving (ratio of sums over 1 s windows).

    ``wheel_radius_m * ratio`` is the effective rolling radius (including any steady slip).
    Only meaningful with RTK-grade GNSS on a straight drive (test17run).
    """
    enu = gnss_enu(log)
    tg = log.gnss_t_s
    tq = np.arange(max(tg[0], log.wheel_t_s[0]) + 1.0, min(tg[-1], log.wheel_t_s[-1]) - 1.0, 0.1)

    def pos(t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, tg, enu[:, k]) for k in range(2)])

    v_gnss = np.linalg.norm(pos(tq + window_s / 2) - pos(tq - window_s / 2), axis=1) / window_s
    v_rim = _window_mean(log.wheel_t_s, rim_speed_mps(log, wheel_radius_m), tq, window_s)
    m = v_rim > min_speed_mps
    return float(v_gnss[m].sum() / v_rim[m].sum()) if m.any() else float('nan')


def estimate_initial_heading(log: PathfinderLog, max_turn_deg: float = 2.0,
                             min_distance_m: float = 1.0,
                             max_distance_m: float = 10.0) -> HeadingEstimate:
    """Heading at standstill from the GNSS track of the first straight drive.

    The segment starts when the wheels start turning and ends when the gyro heading has changed
    by ``max_turn_deg`` (or at ``max_distance_m``, but not before ``min_distance_m``). Its course
    is the principal direction of the ENU fixes (sign from the displacement); the heading at
    standstill is that course minus the gyro heading change between standstill and the segment
    midpoint (gyro bias taken from the standstill before motion). Skid-steer crab on the
    straight is assumed zero.
    """
    t0, _ = motion_interval(log)
    ti = log.imu_t_s
    rest = ti < t0 - 0.5
    gz = log.omega_ib_imu[:, 2] - (log.omega_ib_imu[rest, 2].mean() if rest.any() else 0.0)
    # z down: +Gz is a clockwise (heading-increasing) turn.
    return heading_from_track(ti, gz, log.gnss_t_s, gnss_enu(log), t0,
                              max_turn_deg=max_turn_deg, min_distance_m=min_distance_m,
                              max_distance_m=max_distance_m)


def measured_noise_density(log: PathfinderLog) -> tuple[float, float]:
    """Gyro and accelerometer white-noise densities (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)) from the
    standstill before motion: mean over axes of std * sqrt(dt)."""
    t0, _ = motion_interval(log)
    rest = log.imu_t_s < t0 - 0.5
    dt = float(np.median(np.diff(log.imu_t_s)))
    g = float(np.mean(log.omega_ib_imu[rest].std(axis=0)) * math.sqrt(dt))
    a = float(np.mean(log.f_ib_imu[rest].std(axis=0)) * math.sqrt(dt))
    return g, a


def log_facts(log: PathfinderLog) -> LogFacts:
    """The checked figures of a log (rates, spans, rest specific force, timing, heading)."""
    def rate(t: np.ndarray) -> float:
        return float((len(t) - 1) / (t[-1] - t[0]))

    t0, t1 = motion_interval(log)
    rest = log.imu_t_s < t0 - 0.5
    lag, corr = wheel_imu_lag(log)
    g, a = measured_noise_density(log)
    ref = log.imu_t_s[0]
    notes = []
    if log.gnss_time_base == 'gps_tow':
        notes.append('GNSS time was GPS time of week; converted to Unix (leap 18 s).')
    gaps = int(np.sum(np.diff(log.gnss_t_s) > 0.15))
    notes.append(f'GNSS intervals > 0.15 s: {gaps}; dt range '
                 f'{np.diff(log.gnss_t_s).min():.3f}-{np.diff(log.gnss_t_s).max():.3f} s.')
    return LogFacts(
        imu_rate_hz=rate(log.imu_t_s), wheel_rate_hz=rate(log.wheel_t_s),
        gnss_rate_hz=rate(log.gnss_t_s),
        imu_span_s=(0.0, float(log.imu_t_s[-1] - ref)),
        wheel_span_s=(float(log.wheel_t_s[0] - ref), float(log.wheel_t_s[-1] - ref)),
        gnss_span_s=(float(log.gnss_t_s[0] - ref), float(log.gnss_t_s[-1] - ref)),
        rest_f_ib_imu=tuple(float(x) for x in log.f_ib_imu[rest].mean(axis=0)),
        motion_start_s=t0 - ref, motion_end_s=t1 - ref,
        gnss_over_wheel_speed=gnss_over_wheel_speed(log), wheel_lag_s=lag, wheel_lag_corr=corr,
        gyro_noise_density_rps_rthz=g, accel_noise_density_mps2_rthz=a,
        heading=estimate_initial_heading(log),
        notes=tuple(notes))


def format_facts(log: PathfinderLog, facts: LogFacts) -> str:
    """Human-readable summary of :func:`log_facts`."""
    h = facts.heading
    f = facts.rest_f_ib_imu
    lines = [
        f'{log.name}: IMU {facts.imu_rate_hz:.1f} Hz, wheels {facts.wheel_rate_hz:.2f} Hz, '
        f'GNSS {facts.gnss_rate_hz:.2f} Hz ({log.gnss_time_base} time base)',
        f'  spans (s from first IMU sample): IMU {facts.imu_span_s[0]:.2f}..'
        f'{facts.imu_span_s[1]:.2f}, wheels {facts.wheel_span_s[0]:.2f}..'
        f'{facts.wheel_span_s[1]:.2f}, GNSS {facts.gnss_span_s[0]:.2f}..{facts.gnss_span_s[1]:.2f}',
        f'  motion {facts.motion_start_s:.1f}..{facts.motion_end_s:.1f} s; rest specific force '
        f'(imu frame, z down) ({f[0]:.3f}, {f[1]:.3f}, {f[2]:.3f}) m/s^2',
        f'  wheel stamps lag IMU by {facts.wheel_lag_s:.3f} s (yaw-rate correlation '
        f'{facts.wheel_lag_corr:.2f})',
        f'  GNSS speed / rim speed (r={WHEEL_RADIUS_M} m): {facts.gnss_over_wheel_speed:.3f} '
        f'-> effective radius {WHEEL_RADIUS_M * facts.gnss_over_wheel_speed:.4f} m '
        '(valid with RTK only)',
        f'  noise at rest: gyro {facts.gyro_noise_density_rps_rthz:.2e} rad/s/sqrt(Hz) '
        f'(datasheet {GYRO_ARW_RAD_PER_SQRT_S:.2e}), '
        f'accel {facts.accel_noise_density_mps2_rthz:.2e} m/s^2/sqrt(Hz) '
        f'(datasheet {ACCEL_VRW_MPS_PER_SQRT_S:.2e})',
        f'  initial heading {h.heading_deg:.2f} deg (GNSS course {h.course_deg:.2f} deg over '
        f'{h.distance_m:.1f} m / {h.n_fixes} fixes, gyro change to segment middle '
        f'{h.gyro_heading_change_deg:.2f} deg)',
    ]
    lines += ['  ' + n for n in facts.notes]
    return '\n'.join(lines)
