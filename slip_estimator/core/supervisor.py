"""The estimator's supervisor: health checks, recovery, resets, wheel timeout, health report.

It decides and reports; it never changes the filter itself. Each check returns a decision
(:class:`FilterVerdict`, :class:`GapAction`, slip unknown or not) that the facade carries out,
and the supervisor keeps only its own bookkeeping: the counters (the node's record of what
happened), the recent events that the health message names, the recovery window and the
wheel stream's arrivals.
"""
from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from slip_estimator.core import kalman
from slip_estimator.core.diagnosis import ResidualMonitor, slip_model_figures
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.params import Params
from slip_estimator.core.state import VEL, NavState
from slip_estimator.core.timing import WheelTimingMonitor
from slip_estimator.core.types import Health, WheelSample, imu_values_usable, wheel_speeds

if TYPE_CHECKING:
    from slip_estimator.core.slip_model.model import SlipModel

_NS = 1_000_000_000
_EVENTS_HELD = 20
_EVENT_AGE_NS = 10 * _NS  # events younger than this are named in the health message


class GapAction(enum.Enum):
    """What an IMU step of a given length calls for."""

    NONE = 0
    INTERRUPT = 1
    """a gap: the slip model's step test must not span it, the INS integrates across"""
    RECOVER = 2
    """a long gap: not integrated across; velocity re-initialised"""


@dataclass(frozen=True)
class FilterVerdict:
    """The filter-health decision after an update epoch."""

    reset: bool = False
    """non-finite state or covariance: full reset, re-align"""
    repaired_P: np.ndarray | None = None
    """P with its eigenvalues floored (it lost positive definiteness)"""
    recover_reason: str | None = None
    """divergence: re-initialise the velocity (with the biases clipped, when given)"""
    b_a: np.ndarray | None = None
    b_g: np.ndarray | None = None


def check_filter(p: Params, st: NavState, P: np.ndarray) -> FilterVerdict:
    """Covariance must stay finite, symmetric and positive definite; the state must stay
    within physical bounds. Repair what can be repaired, otherwise re-initialise."""
    # A finite sum has finite terms; only a non-finite sum (NaN/Inf, or an overflow of
    # finite terms) needs the element-wise check.
    if not (math.isfinite(float(P.sum()) + sum(st.v_eb_n.tolist())
                          + sum(st.C_b_n.ravel().tolist()) + sum(st.llh.tolist()))
            or (np.isfinite(P).all() and np.isfinite(st.v_eb_n).all()
                and np.isfinite(st.C_b_n).all() and np.isfinite(st.llh).all())):
        return FilterVerdict(reset=True)
    repaired = None
    if P.diagonal().min() <= 0.0:
        w, V = np.linalg.eigh(kalman.symmetrize(P))
        repaired = kalman.symmetrize((V * np.maximum(w, 1e-18)) @ V.T)
    speed = math.sqrt(st.v_eb_n.dot(st.v_eb_n))  # np.linalg.norm of a vector
    bias_out = (np.abs(st.b_a).max() > 10.0 * p.initial_accel_bias_std
                or np.abs(st.b_g).max() > 10.0 * p.initial_gyro_bias_std)
    if speed > 2.0 * p.max_wheel_speed_mps or bias_out:
        reason = 'divergence (speed %.1f m/s%s)' % (
            speed, ', biases out of bounds' if bias_out else '')
        if bias_out:
            return FilterVerdict(False, repaired, reason,
                                 np.clip(st.b_a, -p.initial_accel_bias_std,
                                         p.initial_accel_bias_std),
                                 np.clip(st.b_g, -p.initial_gyro_bias_std,
                                         p.initial_gyro_bias_std))
        return FilterVerdict(False, repaired, reason)
    return FilterVerdict(False, repaired)


class Supervisor:
    """Recovery window, IMU gaps and saturation, wheel timeout, events and the health report.

    :meth:`reset` (with the filter) forgets the recovery window and the wheel stream; the
    events survive it (they are the record of what happened).
    """

    def __init__(self, params: Params) -> None:
        self.params = params
        self._recovery_ns = int(params.recovery_s * _NS)
        self._wheel_timeout_ns = int(params.wheel_timeout_s * _NS)
        # Clipping thresholds (None: a range of 0 is not declared, nothing to check).
        self._accel_clip_mps2 = (0.999 * params.accel_range_mps2
                                 if params.accel_range_mps2 > 0.0 else None)
        self._gyro_clip_rps = (0.999 * params.gyro_range_rps
                               if params.gyro_range_rps > 0.0 else None)
        self.counters: dict[str, int] = dict.fromkeys((
            'imu_samples', 'imu_rejected', 'imu_gaps', 'imu_saturated', 'wheel_samples',
            'wheel_rejected', 'wheel_late', 'wheel_future', 'zupt', 'zaru', 'nhc', 'wheel',
            'wheel_yaw', 'gated', 'resets', 'recoveries', 'divergence_resets',
            'covariance_repairs', 'slip_estimates', 'slip_unknown'), 0)
        self.events: deque = deque(maxlen=_EVENTS_HELD)
        self.reset()

    def reset(self) -> None:
        self.recovering_until_ns: int | None = None
        self._last_wheel_ns: int | None = None  # stamp of the last wheel sample
        self.wheel_arrival_ns: int | None = None  # when it arrived, in IMU time
        self._last_stale_ns: int | None = None

    def event(self, stamp_ns: int | None, text: str) -> None:
        self.events.append((stamp_ns, text))

    # ------------------------------------------------------------------ IMU
    def accept_imu(self, stamp_ns: int, last_ns: int | None, f_b: list[float],
                   w_b: list[float]) -> bool:
        """A usable IMU sample (counted either way): finite, plausible, after ``last_ns``."""
        ok = imu_values_usable(f_b, w_b) and (last_ns is None or stamp_ns > last_ns)
        self.counters['imu_samples' if ok else 'imu_rejected'] += 1
        return ok

    def imu_step(self, stamp_ns: int, dt_s: float, f_b: list[float], w_b: list[float],
                 aligned: bool) -> GapAction:
        """Clipping (counted, named) and the action an IMU step of ``dt_s`` calls for."""
        accel_clip, gyro_clip = self._accel_clip_mps2, self._gyro_clip_rps
        if ((accel_clip is not None and max(map(abs, f_b)) >= accel_clip)
                or (gyro_clip is not None and max(map(abs, w_b)) >= gyro_clip)):
            self.counters['imu_saturated'] += 1
            self.event(stamp_ns, 'IMU at its measurement range (clipping)')
        p = self.params
        if dt_s <= p.max_imu_gap_s:
            return GapAction.NONE
        self.counters['imu_gaps'] += 1
        self.event(stamp_ns, f'IMU gap of {dt_s:.2f} s')
        if aligned and dt_s > p.recovery_gap_s:
            # Not integrated across: one sample says nothing about minutes of motion.
            return GapAction.RECOVER
        return GapAction.INTERRUPT

    def check_filter(self, stamp_ns: int, state: NavState, P: np.ndarray) -> FilterVerdict:
        """:func:`check_filter`, counted and named."""
        verdict = check_filter(self.params, state, P)
        if verdict.reset:
            self.counters['resets'] += 1
            self.event(stamp_ns, 'non-finite filter state: full reset, re-aligning')
            return verdict
        if verdict.repaired_P is not None:
            self.counters['covariance_repairs'] += 1
            self.event(stamp_ns, 'covariance lost positive definiteness: repaired')
        if verdict.recover_reason is not None:
            self.counters['divergence_resets'] += 1
        return verdict

    # ------------------------------------------------------------------ recovery
    def aligned_in_motion(self, stamp_ns: int) -> None:
        """An in-motion start: slip unknown for ``recovery_s`` (named)."""
        p = self.params
        self.start_recovery(stamp_ns)
        self.event(stamp_ns, f'aligned in motion (no stationary window in '
                   f'{p.motion_alignment_after_s:.1f} s): slip unknown for {p.recovery_s:.0f} s')

    def start_recovery(self, stamp_ns: int, reason: str | None = None) -> None:
        """Slip is unknown for ``recovery_s`` from ``stamp_ns``; a ``reason`` (IMU gap,
        divergence) counts as a recovery and is named."""
        if reason is not None:
            self.counters['recoveries'] += 1
            self.event(stamp_ns, f'{reason}: velocity re-initialised, slip unknown for '
                       f'{self.params.recovery_s:.0f} s')
        self.recovering_until_ns = stamp_ns + self._recovery_ns

    def recovering(self, stamp_ns: int) -> bool:
        """True while a wheel sample at ``stamp_ns`` falls in the recovery window."""
        if self.recovering_until_ns is None:
            return False
        if stamp_ns >= self.recovering_until_ns:
            self.recovering_until_ns = None
            return False
        return True

    # ------------------------------------------------------------------ wheels
    def accept_wheel(self, sample: WheelSample, imu_now_ns: int | None) -> bool:
        """A usable wheel sample (counted either way): finite rim speeds within
        ``max_wheel_speed_mps``, stamped after the previous one. Its arrival is noted in IMU
        time (``imu_now_ns``, the last IMU stamp; the wheel stamp itself when that is not
        later): wheel stamps that lag the IMU by a constant latency still arrive on time."""
        last_ns = self._last_wheel_ns
        ok = (all(math.isfinite(v) and abs(v) <= self.params.max_wheel_speed_mps
                  for v in wheel_speeds(sample))
              and (last_ns is None or sample.stamp_ns > last_ns))
        self.counters['wheel_samples' if ok else 'wheel_rejected'] += 1
        if ok:
            self._last_wheel_ns = sample.stamp_ns
            self.wheel_arrival_ns = (sample.stamp_ns if imu_now_ns is None
                                     else max(sample.stamp_ns, imu_now_ns))
            self._last_stale_ns = None
        return ok

    def wheels_stale(self, stamp_ns: int, aligned_ns: int | None) -> int | None:
        """Wheel dropout, or no wheel data at all, at IMU time ``stamp_ns``: once per timeout
        (named), the stamp of an "unknown" slip report, else None.

        A dropout is judged on the wheel stream's own arrivals (no wheel sample for
        ``wheel_timeout_s`` of IMU time), not on its stamps: wheels stamped behind the IMU
        by more than the timeout still flow. The report is stamped in the wheel clock (the
        last wheel stamp plus the time since it arrived), so slip times never go back."""
        arrival = self.wheel_arrival_ns
        last = self._last_stale_ns if self._last_stale_ns is not None else arrival
        if last is None:
            last = aligned_ns
        if last is None or stamp_ns - last <= self._wheel_timeout_ns:
            return None
        self._last_stale_ns = stamp_ns
        if self._last_wheel_ns is None:
            self.event(stamp_ns, 'no wheel data: slip unknown, INS with ZUPT/ZARU only')
            return stamp_ns
        self.event(stamp_ns, f'wheel data missing for {(stamp_ns - arrival) * 1e-9:.1f} s: '
                   'slip unknown')
        return self._last_wheel_ns + (stamp_ns - arrival)

    # ------------------------------------------------------------------ report
    def health(self, stamp_ns: int | None, flt: ErrorStateFilter,
               motion: tuple[bool, bool],
               monitor: ResidualMonitor, timing: WheelTimingMonitor, track_width_m: float,
               imu_problem: str | None, slip_model: SlipModel,
               odometry: tuple[dict, str | None] = ({}, None)) -> Health:
        """The health report from the parts' figures and suspicions (``motion``: stationary
        and turning at the last update), the events of the last 10 s, the recovery and the
        bias bounds; the slip model's resolution limit and the odometry's fallback
        (``odometry``: :meth:`OdometryGuard.figures`) are stated, not faults (no WARN)."""
        p = self.params
        values: dict = dict(self.counters)
        state = flt.state
        if state is None and imu_problem is not None:
            return Health(2, f'IMU not usable, not aligning (odometry from the wheels only, slip '
                          f'unknown): {imu_problem}', values)
        if state is None:
            recent = '; '.join(dict.fromkeys(text for _, text in self.events))
            return Health(1, 'aligning: waiting for a stationary window or '
                          f'{p.motion_alignment_after_s:.1f} s of IMU and wheel data'
                          + (f' (after: {recent})' if recent else ''), values)
        sig = np.sqrt(np.maximum(np.diag(flt.P), 0.0))
        values.update({
            'stationary': motion[0], 'turning': motion[1],
            'velocity_std_mps': float(np.linalg.norm(sig[VEL])),
            'heading_std_rad': float(sig[2]),
            'accel_bias_mps2': [float(x) for x in state.b_a],
            'gyro_bias_rps': [float(x) for x in state.b_g],
        })
        for k, v in flt.nis_mean.items():
            values[f'nis_mean_{k}'] = v
        values.update(monitor.values())
        notes = [f'suspected: {text}' for text in monitor.suspects()]
        values['wheel_lag_s'], values['wheel_lag_correlation'] = timing.lag_s, timing.correlation
        values['effective_track_width_m'] = track_width_m
        values['effective_track_ratio'] = track_width_m / p.track_width
        lag_note = timing.suspicion(p.wheel_latency_s)
        if lag_note is not None:
            notes.append(f'suspected: {lag_note}')
        level = 1 if notes else 0
        if np.any(np.abs(state.b_g) > 5.0 * p.initial_gyro_bias_std):
            level = 1
            notes.append('gyro bias estimate beyond 5 sigma of its prior')
        if np.any(np.abs(state.b_a) > 5.0 * p.initial_accel_bias_std):
            level = 1
            notes.append('accelerometer bias estimate beyond 5 sigma of its prior')
        recent = [text for t, text in self.events
                  if t is not None and stamp_ns - t <= _EVENT_AGE_NS]
        if recent:
            level = max(level, 1)
            notes = list(dict.fromkeys(recent)) + notes
        if self.recovering_until_ns is not None:
            level = max(level, 1)
        slip_values, limit = slip_model_figures(slip_model)
        values.update(slip_values)
        if limit is not None and not motion[0]:
            notes.append(limit)  # after the level: a limit of the IMU, not a fault
        values.update(odometry[0])
        if odometry[1] is not None:
            notes.append(odometry[1])
        head = 'recovering' if self.recovering_until_ns is not None else 'running'
        return Health(level, head + (': ' + '; '.join(notes) if notes else ''), values)
