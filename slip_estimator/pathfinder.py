"""Import of WVU Pathfinder logs (``.mat``, MATLAB v7.3 = HDF5) into a bag and a params file.

The logs are the seed paper authors' exports (``wvu-navLab/corenav-GP``); see
``shared/data/pathfinder/README.md``. Everything below was checked against the data itself
(``slip-estimator import-pathfinder`` prints the same figures for any log):

Time bases
    * ``tTimu`` and ``tTodom`` are Unix seconds. IMU: 250 Hz (median dt 4.000 ms, min 2.8 ms,
      max 4.95 ms, no gaps). Wheels (joint states): 10 Hz, dt 0.0999-0.1001 s.
    * test17run: the GNSS time (``gpsECEF.time``) is GPS time of week. The GPS week follows from
      the IMU Unix time (week 2068, starts 2019-08-25 00:00 UTC = Unix 1566691200, as in the
      README) and Unix = week start + TOW - 18 s. The record has 705 epochs over 72.4 s
      (8 gaps of 0.2 s, 6 of 0.3 s), so aligning it with the 705 wheel samples by index would be
      off by up to 1.8 s; after conversion GNSS spans [-0.14 s, +1.82 s] around the IMU record.
    * s5t1: ``tTGPS`` (identical to ``gpsECEF.time`` within 1e-5 s) is already Unix time. It is a
      jittery receive time (dt between 0.03 and 0.30 s, mean 0.0999 s, no missing epochs), so
      per-sample GNSS velocities of s5t1 are meaningless even apart from its single-point noise.
    * ``ENUGPS``/``llhGPS`` equal ``gpsECEF`` converted (checked to 5e-5 m, 4e-9 m); ``llhGPS``
      height is ellipsoidal. The Novatel ``Height`` of s5t1 is 33.30 m above it (it is the
      orthometric/MSL height; geoid undulation about -33.3 m), so NavSatFix altitude uses
      ``llhGPS``.
    * Wheel stamps lag the IMU: the cross-correlation of the gyro yaw rate with the wheel
      differential yaw rate peaks at IMU time = wheel stamp - 0.085 s (s5t1, r = 0.97) and
      -0.165 s (test17run, straight drive, r = 0.64); forward acceleration Ax vs d(wheel
      speed)/dt gives -0.13 s / -0.20 s; GNSS speed vs wheel speed (test17run, RTK) gives
      wheel stamp = GNSS time + 0.18 s. IMU and GNSS agree with each other; the joint states are
      about 0.1-0.2 s late. Timestamps are written as recorded; the estimator should allow for
      this latency (``wheel_latency_s``) and may want a wheel time offset.

IMU axes and sign
    Raw axes are the sensor's x forward, y right, z down (FRD). At rest Az = -9.79 / -9.80 m/s^2
    and |f| = 9.810 m/s^2: that is the specific force (reaction to gravity, pointing up) resolved
    in a z-down frame, i.e. REP-145 compliant already; only the frame is not FLU. The mounting is
    therefore declared as ``imu_to_base_rpy = [pi, 0, 0]`` (imu_link = base_link rolled by 180
    deg), after which base z reads +9.80 at rest. Verified: Gz < 0 in the long left (counter-
    clockwise) arcs of s5t1 (GNSS course and wheel differential agree: mean Gz = -0.24 rad/s
    where the right wheels are faster), Ax correlates positively with d(wheel speed)/dt, Ay is
    negatively correlated with v * yaw_rate_FLU (centripetal force to the left, y right).
    At rest the tilt is roll 2.0 / 0.9 deg, pitch -2.8 / -2.1 deg (test17run / s5t1, FRD).
    Gyro turn-on bias up to 1.4e-3 rad/s (s5t1 x). Measured noise at rest (std / sqrt(250 Hz)):
    gyro 5.2e-5 rad/s/sqrt(Hz) (datasheet ARW 2.9e-5), accelerometer 1.0e-3 m/s^2/sqrt(Hz)
    (datasheet VRW 1.3e-4, i.e. ~8x lower): the rover vibrates or its electronics add noise even
    at rest. The params file uses the datasheet values unless ``measured_noise=True``.

Wheels
    The left wheels read negative when driving forward: they are negated here so that every
    joint is forward positive. The four wheels agree within ~0.5-1 rad/s. ``*Vel`` is quantised
    in steps of 0.0075 rad/s and exactly 0 at rest. Integrating ``*Vel`` over time gives 1.9 %
    more rotation than the change of ``*Pos`` on all four wheels of both logs: the velocity field
    is scaled by ~1.019 relative to the positions. test17run (straight, RTK): GNSS speed / (0.12 m
    * mean wheel ``Vel``) = 0.966 (ratio of sums while moving; r_eff = 0.116 m; 0.118 m if based on
    ``Pos``). The rover's own odometry ``lin_x`` corresponds to r = 0.110 m. So "zero slip" with
    the nominal 0.12 m radius reads s = +0.034 on this firm-ground run: part effective radius,
    part genuine longitudinal slip - the two cannot be separated from one run.

Runs and initial heading
    test17run: motion from 5.4 s to 54.6 s (of 70.4 s); the gyro shows the drive is not straight
    (heading wanders by +-6 deg). GNSS (RTK) course over the first 1.7 m: 2.3 deg; net displacement
    34.3 m at 2.8 deg. s5t1: motion from 13.4 s to 146.6 s (of 176.9 s); first straight ~2.7 m,
    GNSS (single point) course 317-318 deg vs the authors' hand-set 313 deg.
    :func:`estimate_initial_heading` fits the GNSS track of the first straight drive and corrects
    by the gyro heading change since standstill.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slip_estimator.core.params import Params
from slip_estimator.core.planet import EARTH, llh_to_local_enu

GPS_EPOCH_UNIX_S = 315964800.0
"""Unix time of the GPS epoch, 1980-01-06 00:00 UTC."""
GPS_UTC_LEAP_S = 18.0
"""GPS - UTC since 2017-01-01 (valid for both logs, 2019 and 2020)."""
SECONDS_PER_WEEK = 604800.0

WHEEL_FIELDS = ('frontLeft', 'frontRight', 'rearLeft', 'rearRight')
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


@dataclass(frozen=True)
class PathfinderLog:
    """A Pathfinder log as plain arrays (SI units, Unix seconds).

    Attributes
    ----------
    name : log name (file stem).
    imu_t_s : IMU sample times, Unix s, shape (N,).
    f_ib_imu : specific force in the IMU's own frame (x fwd, y right, z down), m/s^2, (N, 3).
    omega_ib_imu : angular rate in the IMU frame, rad/s, (N, 3).
    wheel_t_s : joint-state times, Unix s, (M,).
    wheel_rate_rps : wheel angular velocities, forward positive, rad/s, (M, 4), order
        :data:`WHEEL_JOINT_NAMES`.
    wheel_angle_rad : wheel angles, forward positive, rad, (M, 4).
    gnss_t_s : GNSS epoch times, Unix s, (K,).
    gnss_llh : latitude (rad), longitude (rad), ellipsoidal height (m), (K, 3).
    gnss_sigma_enu_m : reported 1-sigma east, north, up (m), (K, 3), or None.
    gnss_time_base : 'gps_tow' or 'unix' (how the file stored the GNSS time).
    """

    name: str
    imu_t_s: np.ndarray
    f_ib_imu: np.ndarray
    omega_ib_imu: np.ndarray
    wheel_t_s: np.ndarray
    wheel_rate_rps: np.ndarray
    wheel_angle_rad: np.ndarray
    gnss_t_s: np.ndarray
    gnss_llh: np.ndarray
    gnss_sigma_enu_m: np.ndarray | None
    gnss_time_base: str


@dataclass(frozen=True)
class HeadingEstimate:
    """Initial heading from the GNSS track of the first straight drive.

    Attributes
    ----------
    heading_deg : heading of base_link x at standstill, clockwise from north, deg [0, 360).
    course_deg : GNSS course of the fitted segment, deg.
    gyro_heading_change_deg : gyro heading change from standstill to the segment midpoint, deg.
    t_start_s, t_end_s : fitted segment (Unix s).
    distance_m : GNSS distance covered by the segment, m.
    n_fixes : number of GNSS fixes in the fit.
    """

    heading_deg: float
    course_deg: float
    gyro_heading_change_deg: float
    t_start_s: float
    t_end_s: float
    distance_m: float
    n_fixes: int


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


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
def _vec(h5, key: str) -> np.ndarray:
    return np.asarray(h5[key][()], dtype=float).squeeze()


def read_matlab_table(h5, name: str) -> dict[str, np.ndarray]:
    """Columns of a MATLAB ``table`` saved in a v7.3 file (columns reached through ``#refs#``).

    MATLAB stores the table's data as a cell of column arrays and its variable names as a cell
    of char arrays, both under ``#refs#``; the table object itself is an opaque MCOS handle, so
    the two cells are recognised by shape (same count, numeric columns of one length, char names).
    """
    if name not in h5:
        raise KeyError(f'no variable {name!r}')
    refs = h5['#refs#']
    cells = []
    for key in refs:
        d = refs[key]
        if getattr(d, 'dtype', None) == object and d.attrs.get('MATLAB_class') == b'cell':
            cells.append([h5[r] for r in d[()].ravel()])
    names = data = None
    for cell in cells:
        if all(getattr(i, 'attrs', {}).get('MATLAB_class') == b'char' for i in cell):
            names = [''.join(chr(int(c)) for c in np.asarray(i[()]).ravel()) for i in cell]
    for cell in cells:
        if names and len(cell) == len(names) and all(
                getattr(i, 'attrs', {}).get('MATLAB_class') == b'double' for i in cell):
            data = [np.asarray(i[()], dtype=float).squeeze() for i in cell]
    if names is None or data is None:
        raise ValueError(f'could not decode MATLAB table {name!r}')
    return dict(zip(names, data))


def gps_tow_to_unix(tow_s: np.ndarray, near_unix_s: float) -> np.ndarray:
    """Unix time of GPS times of week; the week is the one containing ``near_unix_s``.

    ``Unix = GPS epoch + week * 604800 + TOW - leap seconds`` (leap = 18 s since 2017).
    """
    gps_s = near_unix_s - GPS_EPOCH_UNIX_S + GPS_UTC_LEAP_S
    week = math.floor(gps_s / SECONDS_PER_WEEK)
    # A run near a week boundary: choose the week that puts the TOW closest to the reference.
    tow_ref = gps_s - week * SECONDS_PER_WEEK
    if np.median(tow_s) - tow_ref > SECONDS_PER_WEEK / 2:
        week -= 1
    elif tow_ref - np.median(tow_s) > SECONDS_PER_WEEK / 2:
        week += 1
    return GPS_EPOCH_UNIX_S + week * SECONDS_PER_WEEK + np.asarray(tow_s) - GPS_UTC_LEAP_S


def read_pathfinder_mat(path: str | Path) -> PathfinderLog:
    """Read a Pathfinder ``.mat`` log into plain arrays (see the module docstring for the facts).

    The GNSS time base is detected from the values: times below one week are GPS time of week
    (test17run), otherwise Unix seconds (s5t1).
    """
    import h5py

    path = Path(path)
    with h5py.File(path, 'r') as h5:
        imu_t = _vec(h5, 'tTimu')
        f = np.column_stack([_vec(h5, k) for k in ('Ax', 'Ay', 'Az')])
        w = np.column_stack([_vec(h5, k) for k in ('Gx', 'Gy', 'Gz')])
        wheel_t = _vec(h5, 'tTodom')
        # Left wheels read negative when driving forward: make every joint forward positive.
        sign = np.array([-1.0, 1.0, -1.0, 1.0])
        rate = np.column_stack([_vec(h5, k + 'Vel') for k in WHEEL_FIELDS]) * sign
        angle = np.column_stack([_vec(h5, k + 'Pos') for k in WHEEL_FIELDS]) * sign
        llh = np.asarray(h5['llhGPS'][()], dtype=float)
        if llh.shape[0] == 3 and llh.shape[1] != 3:
            llh = llh.T
        if 'tTGPS' in h5:
            gnss_t = _vec(h5, 'tTGPS')
        else:
            gnss_t = read_matlab_table(h5, 'gpsECEF')['time']
        sigma = None
        if all(k in h5 for k in ('LatSigma', 'LonSigma', 'HeightSigma')):
            sigma = np.column_stack([_vec(h5, 'LonSigma'), _vec(h5, 'LatSigma'),
                                     _vec(h5, 'HeightSigma')])
    if len(gnss_t) != len(llh):
        raise ValueError(f'{path.name}: {len(gnss_t)} GNSS times for {len(llh)} positions')
    if np.nanmax(gnss_t) < SECONDS_PER_WEEK:
        gnss_t = gps_tow_to_unix(gnss_t, float(imu_t[0]))
        base = 'gps_tow'
    else:
        base = 'unix'
    return PathfinderLog(path.stem, imu_t, f, w, wheel_t, rate, angle, gnss_t, llh, sigma, base)


# --------------------------------------------------------------------------------------------
# Checks on the data
# --------------------------------------------------------------------------------------------
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
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (gz[1:] + gz[:-1]) * np.diff(ti))])
    psi -= np.interp(t0, ti, psi)
    enu = gnss_enu(log)
    tg = log.gnss_t_s
    after = np.where(tg >= t0)[0]
    i_end = after[0]
    for i in after:
        d = np.linalg.norm(enu[i, :2] - enu[after[0], :2])
        turned = abs(math.degrees(np.interp(tg[i], ti, psi))) > max_turn_deg
        if d > max_distance_m or (turned and d >= min_distance_m):
            break
        i_end = i
    seg = after[after <= i_end]
    xy = enu[seg, :2]
    _, _, vt = np.linalg.svd(xy - xy.mean(axis=0))
    direction = vt[0] if np.dot(xy[-1] - xy[0], vt[0]) >= 0 else -vt[0]
    course = math.degrees(math.atan2(direction[0], direction[1])) % 360.0
    t_mid = 0.5 * (tg[seg[0]] + tg[seg[-1]])
    dpsi = math.degrees(float(np.interp(t_mid, ti, psi)))
    return HeadingEstimate((course - dpsi) % 360.0, course, dpsi, float(tg[seg[0]]),
                           float(tg[seg[-1]]), float(np.linalg.norm(xy[-1] - xy[0])), len(seg))


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


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
def pathfinder_params(log: PathfinderLog, heading_deg: float | None = None,
                      measured_noise: bool = False) -> Params:
    """Estimator parameters for a Pathfinder log (geometry, mounting, start pose, IMU noise).

    IMU noise is the ADIS16495-2 datasheet (ARW, VRW; bias PSDs from the in-run bias
    instability reached over :data:`BIAS_CORRELATION_TIME_S`) unless ``measured_noise``, then
    the white-noise densities measured at rest are used.
    """
    if heading_deg is None:
        heading_deg = estimate_initial_heading(log).heading_deg
    gyro_n, accel_n = GYRO_ARW_RAD_PER_SQRT_S, ACCEL_VRW_MPS_PER_SQRT_S
    if measured_noise:
        gyro_n, accel_n = measured_noise_density(log)
    lat, lon, h = log.gnss_llh[0]
    return Params(
        wheel_radius=WHEEL_RADIUS_M, track_width=TRACK_WIDTH_M, wheel_input='joint_states',
        wheel_joint_names=list(WHEEL_JOINT_NAMES), imu_to_base_rpy=list(IMU_TO_BASE_RPY),
        initial_latitude_deg=math.degrees(lat), initial_longitude_deg=math.degrees(lon),
        initial_height_m=float(h), initial_heading_deg=float(heading_deg) % 360.0,
        planet='earth', gyro_noise_density_rps_rthz=gyro_n,
        accel_noise_density_mps2_rthz=accel_n,
        gyro_bias_psd_rad2ps3=GYRO_BIAS_INSTABILITY_RPS ** 2 / BIAS_CORRELATION_TIME_S,
        accel_bias_psd_m2ps5=ACCEL_BIAS_INSTABILITY_MPS2 ** 2 / BIAS_CORRELATION_TIME_S)


def params_notes(facts: LogFacts, measured_noise: bool = False,
                 measured_lag: bool = False) -> list[str]:
    """What the params file takes from the measurements of the log, and why not where it keeps
    a default (written as comments at the top of the file)."""
    lag = facts.wheel_lag_s
    notes = [f'Wheel stamps lag the IMU by {lag:.3f} s on this log (yaw-rate cross-correlation '
             f'r = {facts.wheel_lag_corr:.2f}).']
    if measured_lag:
        notes.append(f'wheel_latency_s = {lag:.3f}: that measured lag.')
    else:
        notes.append('wheel_latency_s stays 0: compensating a constant lag did not improve the '
                     'model on the Pathfinder logs (the lag drifts through a log, 0.095-0.165 s '
                     'on s5t1; docs/validation.md, effect E); the node measures it online and '
                     'names it in /diagnostics. import-pathfinder --measured-lag writes it.')
    measured = (f'gyro {facts.gyro_noise_density_rps_rthz:.2e} rad/s/sqrt(Hz), accel '
                f'{facts.accel_noise_density_mps2_rthz:.2e} m/s^2/sqrt(Hz)')
    names = 'gyro_noise_density_rps_rthz, accel_noise_density_mps2_rthz'
    if measured_noise:
        notes.append(f'{names}: measured at rest ({measured}).')
    else:
        notes.append(f'{names}: ADIS16495-2 datasheet, not the '
                     f'values measured at rest ({measured}): the excess at rest is vibration, '
                     'carried by vibration_noise_fraction (docs/validation.md, effect B). '
                     'import-pathfinder --measured-noise writes the measured values.')
    return notes


def _stamp(msg_header, t_s: float) -> int:
    from slip_estimator.ros.convert import ns_to_stamp

    ns = round(t_s * 1e9)
    msg_header.stamp = ns_to_stamp(ns)
    return ns


def write_bag(log: PathfinderLog, bag_path: str | Path, progress: bool = False) -> dict[str, int]:
    """Write ``/imu/data``, ``/joint_states`` and ``/gnss/fix`` with the recorded stamps.

    Messages are written in time order; the log time equals the header stamp.
    Returns the message count per topic.
    """
    from sensor_msgs.msg import Imu, JointState, NavSatFix, NavSatStatus

    from slip_estimator.bagio import BagWriter
    from slip_estimator.progress import Progress

    line = Progress(progress)
    dt_imu = float(np.median(np.diff(log.imu_t_s)))
    gyro_var = GYRO_ARW_RAD_PER_SQRT_S ** 2 / dt_imu
    accel_var = ACCEL_VRW_MPS_PER_SQRT_S ** 2 / dt_imu
    events = ([(t, 0, i) for i, t in enumerate(log.imu_t_s)]
              + [(t, 1, i) for i, t in enumerate(log.wheel_t_s)]
              + [(t, 2, i) for i, t in enumerate(log.gnss_t_s)])
    events.sort()
    counts = {'/imu/data': 0, '/joint_states': 0, '/gnss/fix': 0}
    with BagWriter(bag_path) as bag:
        for n, (t, kind, i) in enumerate(events):
            if kind == 0:
                msg = Imu()
                msg.header.frame_id = 'imu_link'
                ns = _stamp(msg.header, t)
                msg.orientation_covariance[0] = -1.0  # no orientation estimate
                w, f = log.omega_ib_imu[i], log.f_ib_imu[i]
                av, la = msg.angular_velocity, msg.linear_acceleration
                av.x, av.y, av.z = (float(x) for x in w)
                la.x, la.y, la.z = (float(x) for x in f)
                for k in (0, 4, 8):
                    msg.angular_velocity_covariance[k] = gyro_var
                    msg.linear_acceleration_covariance[k] = accel_var
                topic = '/imu/data'
            elif kind == 1:
                msg = JointState()
                ns = _stamp(msg.header, t)
                msg.name = list(WHEEL_JOINT_NAMES)
                msg.position = [float(x) for x in log.wheel_angle_rad[i]]
                msg.velocity = [float(x) for x in log.wheel_rate_rps[i]]
                topic = '/joint_states'
            else:
                msg = NavSatFix()
                msg.header.frame_id = 'gnss_link'
                ns = _stamp(msg.header, t)
                msg.status.status = NavSatStatus.STATUS_FIX
                msg.status.service = NavSatStatus.SERVICE_GPS
                lat, lon, h = log.gnss_llh[i]
                msg.latitude, msg.longitude, msg.altitude = (math.degrees(lat),
                                                             math.degrees(lon), float(h))
                if log.gnss_sigma_enu_m is not None:
                    sig = log.gnss_sigma_enu_m[i]
                    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
                else:
                    sig = RTK_SIGMA_M
                    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_APPROXIMATED
                # NavSatFix covariance is in ENU order (east, north, up).
                for k, s in zip((0, 4, 8), sig):
                    msg.position_covariance[k] = float(s) ** 2
                topic = '/gnss/fix'
            bag.write(topic, msg, ns)
            counts[topic] += 1
            if n % 5000 == 0:
                line.show(f'  writing {n}/{len(events)} messages')
    line.done(f'  wrote {len(events)} messages')
    return counts


def import_pathfinder(mat_path: str | Path, bag_path: str | Path,
                      params_path: str | Path | None = None, *, measured_noise: bool = False,
                      measured_lag: bool = False, heading_deg: float | None = None,
                      progress: bool = False) -> tuple[PathfinderLog, LogFacts, Params]:
    """Convert a Pathfinder ``.mat`` log to an MCAP bag (and a params file when requested,
    with :func:`params_notes` as its header comments).

    Returns the log, its checked facts and the parameters written. ``heading_deg`` overrides
    the initial heading estimated from GNSS.
    """
    from slip_estimator.paramfile import save_params

    log = read_pathfinder_mat(mat_path)
    facts = log_facts(log)
    heading = facts.heading.heading_deg if heading_deg is None else heading_deg
    params = pathfinder_params(log, heading, measured_noise)
    if measured_lag:
        params = params.replace(wheel_latency_s=facts.wheel_lag_s)
    write_bag(log, bag_path, progress=progress)
    if params_path is not None:
        save_params(params, params_path,
                    comments=params_notes(facts, measured_noise, measured_lag))
    return log, facts, params
