"""What ``slip-estimator setup`` measures on a robot's log (pure: numpy and the core).

Each figure comes with its spread (the standard error over independent parts of the log) and
the samples it rests on:

* IMU white noise and gyro bias at rest (wheels stopped; each stop's mean removed): density =
  per-sample std x sqrt(sample interval), as the Pathfinder importer measures it;
* the lag of the wheel stamps behind the IMU: the yaw rate about up against the wheel
  differential in turns (:func:`slip_estimator.core.timing.best_lag`), per quarter of the log;
* the effective track ``v_R - v_L = B_eff * omega`` (:class:`~slip_estimator.core.track_width.
  TrackWidthEstimator`) over the turns;
* the effective wheel radius ratio: GNSS speed over rim speed on straight runs (the speed of a
  straight-line fit to the fixes over each run); the median run is taken, so that runs through
  soft ground (a few) do not set it;
* the start: the first fix and the heading from the first straight drive's track
  (:func:`~slip_estimator.robot_setup.heading.heading_from_track`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slip_estimator.core.timing import best_lag
from slip_estimator.core.track_width import MIN_CORRELATION, MIN_RATE_RPS, MIN_SAMPLES
from slip_estimator.robot_setup.heading import HeadingEstimate, heading_from_track
from slip_estimator.robot_setup.mounting import (
    ImuCheck,
    Mounting,
    check_imu,
    find_mounting,
    turn_axis,
)
from slip_estimator.robot_setup.signals import (
    Figure,
    GnssSeries,
    ImuSeries,
    WheelSeries,
    blocks,
    inside,
    missing,
    rest_intervals,
    spread_of,
    window_mean,
)

MIN_LAG_CORRELATION = 0.8
"""Below this correlation of yaw rate and wheel differential the lag is not measured."""
STRAIGHT_DEG = 10.0
"""A piece of drive turning less than this is straight."""
MIN_RUN_S = 4.0
HEADING_MIN_DISTANCE_M = 1.0
"""The course of the first straight drive is fitted over at least this much track (a gyro
bias not yet known may end the straight early; a consumer GNSS needs the length)."""
LAG_GRID_S = 0.002
"""Grid of the interpolated yaw rate for the lag (the lag's resolution is its step, 5 ms)."""
MIN_RUN_SPEED_MPS = 0.2


@dataclass(frozen=True)
class Noise:
    """White-noise densities and the gyro bias measured at rest."""

    accel_density_mps2_rthz: Figure
    gyro_density_rps_rthz: Figure
    gyro_bias_imu_rps: tuple[float, float, float] | None
    rest_s: float


@dataclass(frozen=True)
class Start:
    """Initial position (first fix) and heading (first straight drive), or None."""

    llh_deg_deg_m: tuple[float, float, float] | None
    heading: HeadingEstimate | None
    why: str = ''


@dataclass(frozen=True)
class Measured:
    """Everything measured on one log (see the module docstring)."""

    duration_s: float
    imu_dt_s: float
    imu: ImuCheck
    mounting: Mounting
    noise: Noise
    lag_s: Figure
    track_m: Figure
    radius_ratio: Figure
    start: Start


def measure_noise(imu: ImuSeries, rest: list[tuple[float, float]]) -> Noise:
    """White-noise densities (mean over axes) and the gyro bias over the rest intervals."""
    parts_a, parts_g, means_g = [], [], []
    for a, b in rest:
        m = (imu.t_s >= a) & (imu.t_s <= b)
        if m.sum() < 10:
            continue
        parts_a.append(imu.f_imu_mps2[m] - imu.f_imu_mps2[m].mean(axis=0))
        parts_g.append(imu.omega_imu_rps[m] - imu.omega_imu_rps[m].mean(axis=0))
        means_g.append(imu.omega_imu_rps[m].mean(axis=0) * m.sum())
    if not parts_a:
        why = 'no rest (wheels stopped >= 1.6 s)'
        return Noise(missing(why), missing(why), None, 0.0)
    fa, fg = np.vstack(parts_a), np.vstack(parts_g)
    root_dt = math.sqrt(imu.dt_s)

    def density(x: np.ndarray) -> Figure:
        parts = [float(np.mean(x[b].std(axis=0)) * root_dt) for b in blocks(len(x))]
        return Figure(float(np.mean(x.std(axis=0)) * root_dt), spread_of(parts), len(x))

    bias = np.sum(means_g, axis=0) / len(fg)
    return Noise(density(fa), density(fg), tuple(float(x) for x in bias),
                 float(sum(b - a for a, b in rest)))


def yaw_rate_up(imu: ImuSeries, up_imu: np.ndarray, bias_imu: np.ndarray | None) -> np.ndarray:
    """Counter-clockwise yaw rate about up, rad/s (gyro bias at rest removed when known)."""
    w = imu.omega_imu_rps if bias_imu is None else imu.omega_imu_rps - bias_imu
    return w @ (up_imu / np.linalg.norm(up_imu))


def measure_lag(imu: ImuSeries, wheels: WheelSeries, yaw_rps: np.ndarray) -> Figure:
    """Mean age of the wheel speeds behind the IMU (s) from turns, with its spread over
    quarters of the log.

    A wheel speed is a count difference over its period T: the gyro yaw rate, interpolated on
    a ``LAG_GRID_S`` grid, is averaged over T around ``t - lag`` and correlated with the wheel
    differential (:func:`~slip_estimator.core.timing.best_lag`); the peak is the speed's mean
    age (T/2 for an ideal encoder) plus any stamp offset."""
    ok = np.isfinite(wheels.diff_mps)
    t, d = wheels.t_s[ok], wheels.diff_mps[ok]
    inner = (t > imu.t_s[0] + 1.0) & (t < imu.t_s[-1] - 1.0)
    t, d = t[inner], d[inner]
    if len(t) < 50 or np.std(yaw_rps) < 0.02:
        return missing('no turns')
    period = float(np.median(np.diff(t)))
    grid = np.arange(imu.t_s[0], imu.t_s[-1], LAG_GRID_S)
    yaw = np.interp(grid, imu.t_s, yaw_rps)

    def lag_of(idx: np.ndarray) -> tuple[float, float]:
        return best_lag(grid, yaw, t[idx], d[idx], window_s=max(period, LAG_GRID_S))

    lag, corr = lag_of(np.arange(len(t)))
    if not corr >= MIN_LAG_CORRELATION:
        return missing(f'yaw rate and wheel differential correlate at r = {corr:.2f} only')
    parts = [lag_of(b) for b in blocks(len(t), 4)]
    return Figure(lag, spread_of([p for p, c in parts if c >= MIN_LAG_CORRELATION]),
                  int(np.sum(np.abs(d) > 1e-3)))


def measure_track(imu: ImuSeries, wheels: WheelSeries, yaw_rps: np.ndarray, lag_s: float,
                  declared_m: float) -> Figure:
    """Effective track (m): ``v_R - v_L = B_eff * omega`` in least squares over the whole
    log's turns (:data:`~slip_estimator.core.track_width.MIN_RATE_RPS` and up), with its
    jackknife spread over eighths of the turns; none below the online fit's correlation."""
    ok = np.isfinite(wheels.diff_mps)
    t, d = wheels.t_s[ok], wheels.diff_mps[ok]
    w = window_mean(imu.t_s, yaw_rps, t - lag_s, 0.1)
    turning = np.isfinite(w) & (np.abs(w) >= MIN_RATE_RPS)
    d, w = d[turning], w[turning]
    if len(w) < MIN_SAMPLES:
        return missing(f'{len(w)} turning samples (yaw rate >= {MIN_RATE_RPS} rad/s)')
    corr = float(w @ d / math.sqrt((w @ w) * (d @ d)))
    if corr < MIN_CORRELATION:
        return missing(f'wheel differential vs yaw rate in turns: r = {corr:.2f}')
    width = float(w @ d / (w @ w))
    parts = blocks(len(w))
    jack = np.array([float(np.delete(w, b) @ np.delete(d, b) / (np.delete(w, b) @
                                                               np.delete(w, b)))
                     for b in parts])
    spread = math.sqrt((len(jack) - 1) / len(jack) * float(np.sum((jack - jack.mean()) ** 2)))
    return Figure(width, spread, len(w))


def straight_runs(wheels: WheelSeries, imu: ImuSeries, yaw_rps: np.ndarray
                  ) -> list[tuple[float, float]]:
    """Pieces of about ``MIN_RUN_S`` driving above ``MIN_RUN_SPEED_MPS`` whose heading
    changes by less than ``STRAIGHT_DEG`` (the chord of such an arc is within 0.2 % of it)."""
    tq = np.arange(wheels.t_s[0], wheels.t_s[-1], 0.1)
    v = window_mean(wheels.t_s, wheels.v_mps, tq, 0.5)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (yaw_rps[1:] + yaw_rps[:-1])
                                           * np.diff(imu.t_s))])
    moving = v > MIN_RUN_SPEED_MPS
    runs, start = [], None
    for k, good in enumerate(moving):
        if good and start is None:
            start = tq[k]
        elif not good and start is not None:
            runs.append((start, tq[k - 1]))
            start = None
    if start is not None:
        runs.append((start, tq[-1]))
    pieces = [(a + k * (b - a) / n, a + (k + 1) * (b - a) / n) for a, b in runs
              for n in [int((b - a) // MIN_RUN_S)] for k in range(n)]
    turn = [abs(math.degrees(float(np.interp(b, imu.t_s, psi) - np.interp(a, imu.t_s, psi))))
            for a, b in pieces]
    return [p for p, deg in zip(pieces, turn) if deg < STRAIGHT_DEG]


def measure_radius_ratio(wheels: WheelSeries, gnss: GnssSeries | None,
                         runs: list[tuple[float, float]]) -> Figure:
    """GNSS speed over rim speed on straight runs: the median run and its spread."""
    if gnss is None or len(gnss.t_s) < 10:
        return missing('no GNSS fix (no speed reference)')
    ratios = []
    for a, b in runs:
        m = (gnss.t_s >= a) & (gnss.t_s <= b)
        if m.sum() < 5:
            continue
        t = gnss.t_s[m] - gnss.t_s[m].mean()
        vel = np.linalg.lstsq(np.column_stack([t, np.ones_like(t)]), gnss.enu_m[m, :2],
                              rcond=None)[0][0]
        rim = wheels.v_mps[(wheels.t_s >= a) & (wheels.t_s <= b)].mean()
        ratios.append(float(np.linalg.norm(vel) / rim))
    if len(ratios) < 3:
        return missing(f'{len(ratios)} straight runs of >= {MIN_RUN_S:.0f} s with GNSS')
    r = np.array(ratios)
    mad = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    return Figure(float(np.median(r)), 1.25 * mad / math.sqrt(len(r)), len(r))


def measure_start(imu: ImuSeries, wheels: WheelSeries, gnss: GnssSeries | None,
                  yaw_rps: np.ndarray | None) -> Start:
    """First fix and the heading at the first IMU sample."""
    if gnss is None or not len(gnss.t_s):
        return Start(None, None, 'no GNSS fix')
    lat, lon, h = gnss.llh0
    llh = (math.degrees(lat), math.degrees(lon), float(h))
    moving = np.flatnonzero(np.abs(wheels.v_mps) > 0.02)
    if yaw_rps is None or not len(moving):
        return Start(llh, None, 'no motion or no yaw axis for the heading')
    t_motion = float(max(wheels.t_s[moving[0]], gnss.t_s[0]))
    if not np.any(gnss.t_s >= t_motion):
        return Start(llh, None, 'no fix after the robot starts moving')
    try:
        heading = heading_from_track(imu.t_s, -yaw_rps, gnss.t_s, gnss.enu_m, t_motion,
                                     t_ref_s=float(imu.t_s[0]),
                                     min_distance_m=HEADING_MIN_DISTANCE_M)
    except (ValueError, np.linalg.LinAlgError, IndexError):
        return Start(llh, None, 'the first drive has too few fixes for a course')
    if heading.distance_m < 1.0:
        return Start(llh, None, f'the first straight drive covers {heading.distance_m:.1f} m '
                     'of GNSS track only')
    return Start(llh, heading)


def measure(imu: ImuSeries, wheels: WheelSeries, gnss: GnssSeries | None,
            declared_track_m: float) -> Measured:
    """Every figure ``setup`` takes from a log (see the module docstring)."""
    rest = rest_intervals(wheels, imu)
    noise = measure_noise(imu, rest)
    rest_mask = inside(imu.t_s, rest)
    k0, turns = turn_axis(imu, wheels, 0.0)
    bias = np.array(noise.gyro_bias_imu_rps) if noise.gyro_bias_imu_rps else None
    lag = missing('no yaw axis')
    if k0 is not None:
        lag = measure_lag(imu, wheels, yaw_rate_up(imu, k0, bias))
    lag_s = lag.value if lag.ok else 0.0
    k, turns = turn_axis(imu, wheels, lag_s) if k0 is not None else (None, 0)
    track_turn = Figure(1.0 / float(np.linalg.norm(k)), n=turns) if k is not None else \
        missing('no turns')
    check = check_imu(imu, rest_mask, track_turn, declared_track_m)
    mounting = find_mounting(imu, wheels, check, k, turns, lag_s)
    up = np.array(mounting.up_imu) if mounting.up_imu else None
    yaw = yaw_rate_up(imu, up, bias) if up is not None else None
    track = (measure_track(imu, wheels, yaw, lag_s, declared_track_m) if yaw is not None
             else missing('no yaw axis'))
    runs = straight_runs(wheels, imu, yaw) if yaw is not None else []
    return Measured(float(imu.t_s[-1] - imu.t_s[0]), imu.dt_s, check, mounting, noise, lag, track,
                    measure_radius_ratio(wheels, gnss, runs),
                    measure_start(imu, wheels, gnss, yaw))
