"""What the real IMU can resolve of a body-side slip change: the floor no slip model passes.

A body-side change (the wheels hold their rate, the body slows in sand) shows only in the IMU:
the free INS has to carry the body speed across the transition. Two measurements on the RTK
log say how well it can, independent of any slip model:

* :func:`tilt_closure`: the tilt the gyro integrates across the drive against the change of
  the gravity direction the accelerometer measures between the rest before and the rest after
  (at rest there is no vibration and a 1-s mean levels to a few thousandths of a degree). Each
  0.1 deg of tilt error is 0.017 m/s^2 of forward acceleration error;
* :func:`body_side_bound`: an oracle that knows the instant of every change and the true speed
  before it, and reads the change with the shipped filter's free INS (its attitude, velocity
  and biases at the onset, the raw IMU after it) across a span long enough to contain the
  transition. The class recall it reaches at the injected body-side levels is an upper bound
  for any real-time reading of those changes from this IMU.

Both take the shipped parameters; only the core and numpy are used. The oracle's parts
(:func:`reading_errors`, :func:`class_recall_bound`) also give each simulated drive its
ceiling (``slip-estimator accuracy --bound``, :func:`slip_estimator.accuracy.reading_bound`).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from slip_estimator.core.params import Params

BOUND_SPANS_S = (1.0, 1.5, 2.0)
"""Reading spans of :func:`body_side_bound`: a 1-s transition between two 0.5-s means needs
1.5 s; 1.0 s is shorter than any real reading (a bound on the bound)."""
_DRIVING_MPS = 0.4
"""RTK speed above which an onset counts as driving (the log cruises at ~0.7 m/s)."""


def grid_indices(t_s: np.ndarray, grid_s: float) -> np.ndarray:
    """The sample indices nearest after every ``grid_s`` of the sample times ``t_s`` (s)."""
    return np.unique(np.searchsorted(t_s, np.arange(t_s[0], t_s[-1], grid_s)))


def tilt_closure(log: Any, params: Params, rest_s: float = 3.0) -> dict[str, float]:
    """Gyro-integrated tilt across the drive against accelerometer levelling at both rests.

    The gyro bias (with the planet's rate) is the mean rate of the ``rest_s`` before the
    motion; the attitude starts from that rest's levelled tilt and is integrated sample by
    sample (exact rotation per sample) to the rest after the motion, where it is compared with
    that rest's levelled tilt. A straight drive keeps the planet rate's projection: on a drive
    with turns its change (up to 15 deg/h) is part of the figure. Returns pitch and roll of
    both (deg), their differences, the drive's duration (s) and the accelerometer's own
    agreement between the two halves of the rest after (deg, the floor of the comparison).
    """
    from slip_estimator.pathfinder import motion_interval
    from slip_estimator.streams import from_pathfinder

    return tilt_closure_between(from_pathfinder(log, params), *motion_interval(log), rest_s)


def tilt_closure_between(data: Any, t_start_s: float, t_end_s: float, rest_s: float = 3.0
                         ) -> dict[str, float]:
    """:func:`tilt_closure` on any ``streams.SensorData`` (a real log or a simulated drive)
    whose motion runs from ``t_start_s`` to ``t_end_s`` (s, on the data's ``imu_ns`` clock)."""
    from slip_estimator.core.alignment import level
    from slip_estimator.core.frames import dcm_to_rpy, rpy_to_dcm
    from slip_estimator.core.mechanization import rodrigues

    t = data.imu_ns * 1e-9
    t_start, t_end = t_start_s, t_end_s
    before = (t > t_start - 0.5 - rest_s) & (t < t_start - 0.5)
    after = (t > t_end + 1.0) & (t < t_end + 1.0 + rest_s)
    if before.sum() < 10 or after.sum() < 10:
        return {}
    bias = data.omega_ib_b[before].mean(axis=0)
    C = rpy_to_dcm(*level(data.f_ib_b[before].mean(axis=0)), 0.0)
    i_from = int(np.flatnonzero(before)[-1])
    i_to = int(np.flatnonzero(after)[len(np.flatnonzero(after)) // 2])
    for i in range(i_from + 1, i_to + 1):
        C = C @ np.array(rodrigues(*((data.omega_ib_b[i] - bias) * (t[i] - t[i - 1])))
                         ).reshape(3, 3)
    gyro_roll, gyro_pitch, _ = dcm_to_rpy(C)
    k = np.flatnonzero(after)
    roll, pitch = level(data.f_ib_b[k].mean(axis=0))
    (roll1, pitch1), (roll2, pitch2) = (level(data.f_ib_b[k[:len(k) // 2]].mean(axis=0)),
                                        level(data.f_ib_b[k[len(k) // 2:]].mean(axis=0)))
    deg = math.degrees
    return {'drive_s': float(t[i_to] - t[i_from]),
            'pitch_gyro_deg': deg(gyro_pitch), 'roll_gyro_deg': deg(gyro_roll),
            'pitch_level_deg': deg(pitch), 'roll_level_deg': deg(roll),
            'pitch_diff_deg': deg(gyro_pitch - pitch), 'roll_diff_deg': deg(gyro_roll - roll),
            'level_floor_deg': deg(max(abs(pitch1 - pitch2), abs(roll1 - roll2)))}


def oracle_recall(speed_errors_mps: np.ndarray, slip: float, rim_mps: float) -> float:
    """Fraction of readings that keep the class of a true ``slip`` at rim speed ``rim_mps``
    when the body speed read after the change is off by each of ``speed_errors_mps``
    (``s_read = s - e / rim``, eq. 1)."""
    from slip_estimator.core.slip import slip_class_array

    e = np.asarray(speed_errors_mps, dtype=float)
    read = slip - e / rim_mps
    moving = np.ones(read.shape, dtype=bool)
    true_class = slip_class_array(np.array([slip]), np.array([True]))[0]
    return float(np.mean(slip_class_array(read, moving) == true_class))


def _forward_speed_mps(state: Any) -> float:
    """Horizontal speed along the body's heading, m/s."""
    x = np.array(state.C_b_n[:, 0], dtype=float)
    x[2] = 0.0
    return float(state.v_eb_n @ (x / np.linalg.norm(x)))


def reading_errors(params: Params, data: Any, v_true_mps: np.ndarray, onsets: Sequence[int],
                   spans_s: Sequence[float]) -> list[np.ndarray]:
    """The oracle's reading error: from each IMU sample index of ``onsets``, the shipped
    filter's state (``params``, run over ``data``, a ``streams.SensorData``) is propagated
    through the raw IMU alone; its forward speed change over each span of ``spans_s`` less
    the true one (``v_true_mps`` per IMU sample), m/s, per span."""
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.core.mechanization import mechanize
    from slip_estimator.effects import run_core

    t = data.imu_ns * 1e-9
    wanted = set(int(i) for i in onsets)
    states: dict[int, Any] = {}  # IMU sample index -> the filter's state after it
    index = iter(range(len(t)))

    class Recorded(SlipEstimator):
        def add_imu(self, sample: Any) -> list:
            out = super().add_imu(sample)
            i = next(index)
            if self.aligned and i in wanted:
                states[i] = self.state.copy()
            return out

    est, _, _ = run_core(params, data, estimator=Recorded)
    planet = est.filter.planet
    spans = sorted(spans_s)
    errors: list[list[float]] = [[] for _ in spans]
    for i0, state in sorted(states.items()):
        if t[i0] + spans[-1] > t[-1] - 0.5:
            continue
        st, v0, i = state.copy(), _forward_speed_mps(state), i0
        for k, span in enumerate(spans):
            while t[i] < t[i0] + span:
                mechanize(st, data.f_ib_b[i + 1], data.omega_ib_b[i + 1], t[i + 1] - t[i],
                          planet)
                i += 1
            errors[k].append((_forward_speed_mps(st) - v0) - (v_true_mps[i] - v_true_mps[i0]))
    return [np.array(e) for e in errors]


def class_recall_bound(errors_mps: np.ndarray, slip: np.ndarray, slip_class: np.ndarray,
                       rim_mps: np.ndarray, max_samples: int = 2000) -> list[float]:
    """Per moving class (1 low .. 4 extreme) the oracle's recall over truth samples (``slip``,
    ``slip_class``, ``rim_mps`` each), every sample reading with each of ``errors_mps``
    (:func:`oracle_recall`); NaN for an absent class. At most ``max_samples`` samples, evenly
    spaced, are read."""
    k = np.flatnonzero((slip_class >= 1) & np.isfinite(slip) & (np.abs(rim_mps) > 0.05))
    k = k[::max(1, len(k) // max_samples)]
    per: dict[int, list[float]] = {c: [] for c in range(1, 5)}
    for j in k:
        per[int(slip_class[j])].append(oracle_recall(errors_mps, slip[j], abs(rim_mps[j])))
    return [float(np.mean(per[c])) if per[c] else math.nan for c in range(1, 5)]


def body_side_bound(log: Any, params: Params, body_factors: Sequence[float],
                    spans_s: Sequence[float] = BOUND_SPANS_S, grid_s: float = 0.1
                    ) -> dict[str, Any]:
    """The oracle of the module docstring on the plain log, from every ``grid_s`` while
    driving. ``body_factors``: the injected body-speed factors; each is turned into its truth
    slip with the ground's own slip (median RTK speed over rim speed while driving).

    Returns ``spans_s``, per span the RMS of the speed-change error (``rms_mps``, m/s), the
    truth slips (``levels``), the median rim speed (``rim_mps``) and per span and level the
    oracle's class recall (``recall``), and the number of onsets.
    """
    from slip_estimator.effects import gnss_speed
    from slip_estimator.streams import from_pathfinder

    data = from_pathfinder(log, params)
    t = data.imu_ns * 1e-9
    v_rtk = gnss_speed(log, t)
    spans = sorted(spans_s)
    onsets = [i for i in grid_indices(t, grid_s) if v_rtk[i] > _DRIVING_MPS]
    errors = reading_errors(params, data, v_rtk, onsets, spans)
    rim = np.interp(t, data.wheel_ns * 1e-9, data.rim_mps.mean(axis=1))
    driving = (v_rtk > _DRIVING_MPS) & (rim > 0.5)
    rim_mps = float(np.median(rim[driving]))
    ground = 1.0 - float(np.median(v_rtk[driving] / rim[driving]))
    levels = sorted({round(1.0 - f * (1.0 - ground), 2) for f in body_factors})
    return {'spans_s': spans, 'levels': levels, 'rim_mps': rim_mps, 'n': len(errors[0]),
            'rms_mps': [float(np.sqrt(np.mean(np.square(e)))) for e in errors],
            'recall': [[oracle_recall(e, s, rim_mps) for s in levels] for e in errors]}
