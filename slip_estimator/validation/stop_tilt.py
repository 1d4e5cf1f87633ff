"""Tilt closure at stops: how far the filter's tilt moves when a stop's zero velocity levels it,
the same statistic on the real Pathfinder logs and on simulated drives of their shape (issue 27).

While driving, the filter's roll and pitch carry whatever error the gyro and the wheel aid
leave; at a stop the zero-velocity update (ZUPT) levels the INS again (the updater reopens the
tilt at a stop after driving), and the tilt it moves is the error the drive left. Per stop the
statistic is computed from the filter's state after every IMU sample
(:class:`StopTiltRecorder`, a :func:`slip_estimator.streams.feed` callback) by one pure
function, :func:`stop_closures`:

* a stop is an episode of the updater's stationarity (``Updater.is_stationary``, whose first
  sample is the one whose update applied the stop's first ZUPT) after at least
  :data:`MIN_DRIVE_S` of driving since the previous stop ended (or since the filter aligned):
  a shorter drive is the stationarity flickering within one stop;
* ``first``: roll and pitch after the first ZUPT minus at the sample before it, deg;
* ``level``: roll and pitch :data:`LEVEL_S` after the first ZUPT minus before it, deg, for a
  stop still stationary :data:`LEVEL_S` + :data:`RESTART_MARGIN_S` after it (a stop's last
  half second already carries the restart's real pitching, which the detector sees late);
  NaN otherwise;
* ``v_stop_mps``: the filter's forward speed before the first ZUPT (its innovation: the truth
  is at rest), and ``drive_s``, the driving time before the stop.

:func:`summarize` gives per source the median and 90th percentile of each |delta|, the median
rate |delta| / sqrt(drive), deg/sqrt(s), and the first ZUPT's pitch per m/s of the speed it
removes. Measured (session 21): the first ZUPT's tilt follows the speed at the stop through
the velocity-tilt correlation (2-3 deg per m/s on both sources) and does not shrink with a
shorter drive on the simulator, so a rate per sqrt(s) does not make drives of different shape
comparable: the simulated sources (:data:`SIM_SOURCES`) have each real log's shape.
:func:`submit_closures` runs every source on a worker pool (``slip-estimator validate`` runs
them beside its serial core-level evidence runs); the report's section is
:func:`slip_estimator.validation.sections_evidence.stop_tilt_section`. Only numpy, the core,
the simulator and the log reader are used. Beside the stops, the drives of test17run's shape
and that RTK log give the free INS's 1.5-s reading error, the statistic a change to the
simulated accelerometer must keep (:func:`submit_closures`).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

MIN_DRIVE_S = 5.0
"""Driving before a stationary episode for it to be a stop, s (shorter: a flicker)."""
LEVEL_S = 1.0
"""Span after the first ZUPT over which the stop's levelling is taken, s."""
RESTART_MARGIN_S = 0.5
"""A stop must stay stationary this long past :data:`LEVEL_S` for its ``level`` figure, s."""
GAIN_MIN_SPEED_MPS = 0.003
"""Stops whose speed before the first ZUPT is below this give no gain figure, m/s."""
SIM_SOURCES: dict[str, tuple[str, tuple[int, ...], str]] = {
    'sim Pathfinder IMU, test17run shape': ('straight', (0, 1, 2, 3), 'real test17run'),
    'sim Pathfinder IMU, s5t1 shape': ('stop_and_go', (0, 1, 2), 'real s5t1'),
    'sim Pathfinder IMU motion-bound, test17run shape': ('straight_motion_bound', (0, 1, 2, 3),
                                                         'real test17run'),
    'sim Pathfinder IMU motion-bound, s5t1 shape': ('stop_and_go_motion_bound', (0, 1, 2),
                                                    'real s5t1'),
    'sim consumer IMU 30 Hz (skid_steer_30hz_no_slip)': ('consumer', (0, 1, 2), ''),
}
"""The simulated sources: label -> (drive, seeds, the real log of the same shape or '').
The Pathfinder IMU is the measured grade with the measured chassis rocking
(:func:`~slip_estimator.sim.drives.measured_ground`) over ground without slip, on drives
shaped like each real log (:func:`~slip_estimator.sim.drives.straight_scenario`: one 52-s
leg; :func:`~slip_estimator.sim.drives.stop_and_go_scenario`: nine 10-16-s legs); a drive
ending in ``_motion_bound`` has its vibration without white content at 0 Hz
(:meth:`~slip_estimator.sim.imu_grades.VibrationConfig.pathfinder_measured`); the consumer
robot (vibrating 30-Hz IMU, one 10-s stop after ~240 s) has no real log to be judged against.
The drives of test17run's shape, like that RTK log, also give the free INS's 1.5-s reading
error (:func:`~slip_estimator.validation.sim_vs_real.reading_error_mps`)."""


def stop_closures(t_s: np.ndarray, roll_rad: np.ndarray, pitch_rad: np.ndarray,
                  stationary: np.ndarray, v_fwd_mps: np.ndarray | None = None
                  ) -> list[dict[str, float]]:
    """Per stop (module docstring) its ``t_s`` (first ZUPT), ``drive_s``, ``first_roll_deg``,
    ``first_pitch_deg``, ``level_roll_deg``, ``level_pitch_deg``, ``stop_s`` and
    ``v_stop_mps`` (the filter's forward speed before the first ZUPT: its innovation); from
    the filter's tilt (and forward speed) after each IMU sample (``t_s`` ascending, from
    alignment on) and the updater's stationarity then."""
    t = np.asarray(t_s, dtype=float)
    still = np.asarray(stationary, dtype=bool)
    tilt = np.degrees(np.column_stack([roll_rad, pitch_rad]))
    starts = np.flatnonzero(still[1:] & ~still[:-1]) + 1
    ends = np.flatnonzero(~still[1:] & still[:-1]) + 1  # first moving sample after a stop
    out = []
    # The drive begins at the first moving sample: after the alignment's rest, after a stop.
    drive_from = float(t[ends[0]]) if still[0] and len(ends) else float(t[0])
    for i in starts:
        later = ends[ends > i]
        j = int(later[0]) if len(later) else len(t)
        drive_s = float(t[i] - drive_from)
        drive_from = float(t[min(j, len(t) - 1)])
        if drive_s < MIN_DRIVE_S:
            continue
        first = tilt[i] - tilt[i - 1]
        k = i + int(np.searchsorted(t[i:j], t[i] + LEVEL_S))
        settled = t[j - 1] - t[i] >= LEVEL_S + RESTART_MARGIN_S
        level = tilt[k] - tilt[i - 1] if settled else np.full(2, math.nan)
        out.append({'t_s': float(t[i]), 'drive_s': drive_s, 'stop_s': float(t[j - 1] - t[i]),
                    'first_roll_deg': float(first[0]), 'first_pitch_deg': float(first[1]),
                    'level_roll_deg': float(level[0]), 'level_pitch_deg': float(level[1]),
                    'v_stop_mps': math.nan if v_fwd_mps is None else float(v_fwd_mps[i - 1])})
    return out


class StopTiltRecorder:
    """A :func:`~slip_estimator.streams.feed` callback: the filter's roll, pitch and the
    updater's stationarity after every IMU sample once the estimator is aligned."""

    def __init__(self, est: Any) -> None:
        self.est = est
        self.rows: list[tuple[float, float, float, bool, float]] = []

    def __call__(self, sample: Any) -> None:
        est = self.est
        if not est.aligned:
            return
        st = est.filter.state
        C = st.C_b_n
        self.rows.append((sample.stamp_ns * 1e-9, math.atan2(C[2, 1], C[2, 2]),
                          -math.asin(max(-1.0, min(1.0, C[2, 0]))), est.updater.is_stationary,
                          float(C[:, 0] @ st.v_eb_n)))

    def closures(self) -> list[dict[str, float]]:
        """:func:`stop_closures` of what was recorded."""
        if len(self.rows) < 2:
            return []
        t, roll, pitch, still, v_fwd = (np.array(c) for c in zip(*self.rows))
        return stop_closures(t, roll, pitch, still, v_fwd)


def run_closures(params: Any, data: Any) -> list[dict[str, float]]:
    """The shipped estimator with ``params`` over a ``streams.SensorData``; its stops."""
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.streams import feed, records

    est = SlipEstimator(params)
    rec = StopTiltRecorder(est)
    feed(est, records(data), rec, keep_estimates=False)
    return rec.closures()


Run = tuple[list[dict[str, float]], float]
"""One drive's stops and its 1.5-s reading error (m/s; NaN where it has none)."""


def _real_task(args: tuple[str, str, dict[str, Any]]) -> Run:
    from slip_estimator.core.params import Params
    from slip_estimator.effects import gnss_speed
    from slip_estimator.pathfinder import read_pathfinder_mat
    from slip_estimator.streams import from_pathfinder
    from slip_estimator.validation.sim_vs_real import RTK_LOGS, reading_error_mps

    label, mat, params = args
    p = Params.from_dict(params)
    log = read_pathfinder_mat(mat)
    data = from_pathfinder(log, p)
    reading = math.nan
    if label.removeprefix('real ') in RTK_LOGS:
        reading = reading_error_mps(p, data, gnss_speed(log, data.imu_ns * 1e-9))
    return run_closures(p, data), reading


def _sim_task(args: tuple[str, int]) -> Run:
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.sim.drives import (measured_ground, no_slip, stop_and_go_scenario,
                                           straight_scenario)
    from slip_estimator.sim.robots import ROBOTS
    from slip_estimator.streams import from_simulation
    from slip_estimator.validation.sim_vs_real import reading_error_mps

    label, seed = args
    drive = SIM_SOURCES[label][0]
    if drive == 'consumer':
        profile = ROBOTS['skid_steer_30hz_no_slip'](seed)
        r = simulate(profile.scenario)
        p = sim_params(r, profile.wheel_input, profile.joint_columns)
        return run_closures(p, from_simulation(r, p)), math.nan
    straight = drive.startswith('straight')
    shape = straight_scenario if straight else stop_and_go_scenario
    r = simulate(measured_ground(no_slip(shape(seed)),
                                 motion_bound=drive.endswith('_motion_bound')))
    p = sim_params(r)
    data = from_simulation(r, p)
    return (run_closures(p, data),
            reading_error_mps(p, data, r.speed_mps) if straight else math.nan)


def _task(args: tuple[Any, ...]) -> Run:
    return _real_task(args) if len(args) == 3 else _sim_task(args)


def submit_closures(pool: Executor, real: dict[str, tuple[str | Path, Any]]
                    ) -> Callable[[], tuple[dict[str, list[dict[str, float]]],
                                            dict[str, list[float]]]]:
    """Submit every source's drives to ``pool``; returns the call that waits for them and
    gives every stop by source label (``real <log>`` for a real log) and, by label, each
    drive's 1.5-s reading error where it has one (the RTK log, the simulated drives of its
    shape). ``real`` maps a log's name to its ``.mat`` path and the shipped params for it; the
    simulated sources are :data:`SIM_SOURCES` (their default params: the shipped model)."""
    tasks: list[tuple[Any, ...]] = [(label, seed) for label, (_, seeds, _) in
                                    SIM_SOURCES.items() for seed in seeds]
    tasks += [(f'real {name}', str(mat), p.to_dict()) for name, (mat, p) in real.items()]
    futures = [pool.submit(_task, a) for a in tasks]

    def gather() -> tuple[dict[str, list[dict[str, float]]], dict[str, list[float]]]:
        stops: dict[str, list[dict[str, float]]] = {}
        readings: dict[str, list[float]] = {}
        for a, f in zip(tasks, futures):
            run_stops, reading = f.result()
            stops.setdefault(a[0], []).extend(run_stops)
            if math.isfinite(reading):
                readings.setdefault(a[0], []).append(reading)
        return stops, readings
    return gather


def summarize(stops: Sequence[dict[str, float]]) -> dict[str, float]:
    """Over ``stops``: their number, the median drive, the median and 90th percentile of the
    forward speed the first ZUPT removed (m/s), and for ``first`` and ``level`` (roll,
    pitch, and the tilt |(roll, pitch)|) the median and 90th percentile of |delta|, deg, and
    the median of |delta| / sqrt(drive_s), deg/sqrt(s). NaN where no stop has the figure."""
    v_stop = np.abs([s['v_stop_mps'] for s in stops])
    out: dict[str, float] = {'n': float(len(stops)),
                             'drive_s': _pct([s['drive_s'] for s in stops], 50),
                             'v_stop_median_mps': _pct(v_stop, 50),
                             'v_stop_p90_mps': _pct(v_stop, 90)}
    for kind in ('first', 'level'):
        roll = np.array([s[f'{kind}_roll_deg'] for s in stops], dtype=float)
        pitch = np.array([s[f'{kind}_pitch_deg'] for s in stops], dtype=float)
        drive = np.array([s['drive_s'] for s in stops], dtype=float)
        for axis, d in (('roll', np.abs(roll)), ('pitch', np.abs(pitch)),
                        ('tilt', np.hypot(roll, pitch))):
            out[f'{kind}_{axis}_median_deg'] = _pct(d, 50)
            out[f'{kind}_{axis}_p90_deg'] = _pct(d, 90)
            out[f'{kind}_{axis}_rate_deg_rts'] = _pct(d / np.sqrt(drive), 50) if len(d) \
                else math.nan
        out[f'{kind}_n'] = float(np.isfinite(roll).sum())
    # The first ZUPT's pitch per m/s of the speed it removes: the velocity-tilt gain.
    gain = [abs(s['first_pitch_deg']) / abs(s['v_stop_mps']) for s in stops
            if abs(s['v_stop_mps']) > GAIN_MIN_SPEED_MPS]
    out['gain_median_deg_per_mps'] = _pct(gain, 50)
    return out


def _pct(x: Any, q: float) -> float:
    v = np.asarray(x, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, q)) if len(v) else math.nan
