"""The filter's recent forward speed, for wheel samples that describe an earlier instant, and
the wheel samples waiting for the INS to reach their stamps (:class:`WheelQueue`).

A wheel sample is evaluated against the body velocity ``wheel_latency_s`` before its stamp,
which the INS passed a few samples ago. :class:`ForwardSpeedHistory` keeps, at the IMU rate
over the last ``horizon_s``, the forward speed of the wheel-contact point, the yaw rate, and
the slip model's *free* forward speed (the filter's, less what the wheel aid did to it).

Corrections: a filter correction moves the current forward speed; the recorded past moves with
it (as one running shift, not by rewriting the entries), so an old wheel sample is compared
with the corrected, not the superseded, estimate. The free speed is what the INS said then and
is not shifted; a wheel-aid correction is accumulated (its velocity jump, and the along-track
acceleration its tilt and accelerometer-bias change cause from then on) and taken out of it.

Taking the aid back: the aid is right only while the held slip is. When the body slows in
sand at an unchanged wheel rate the aid pulls the INS towards the old speed until the step
test fires, 1-2.5 s later, and the filter explains that pull as tilt and accelerometer bias
(0.1-0.4 deg on the simulated drives, 0.4-1 deg on the real test17run log). Left in place,
that acceleration error (0.02-0.1 m/s^2) makes the free INS measure the change short (patch
entries read 30-40 % low). The history keeps the aid's recent error-state corrections
(:meth:`ForwardSpeedHistory.aid_taught_since`) so that the estimator can take back the tilt
and bias parts made since a change began.

Verifying a take-back: on an IMU whose tilt wanders (the simulated Pathfinder's vibration),
what the aid taught over the seconds before a false body-side alarm was its levelling of the
INS's own excursion; taken back, the INS runs away at the rate removed (0.26-0.54 m/s in the
next second after 0.30-0.46 m/s^2 removed on ground that never slips, the rim steady) and a
false slip is held. A true change mostly leaves the INS level after the take-back, but where
the body keeps slowing through the check (a slip ramp the alarm fired in the middle of) the
INS follows it at a rate like the one removed: only a take-back well beyond what this IMU
resolves over the check (:class:`RunawayScale`, measured: its free residual's 1-s spread,
its tilt 1-sigma, the aid's innovation scatter) is checked. The history keeps the last
take-back for :meth:`ForwardSpeedHistory.take_back_refuted`, which returns the correction
that restores it (its tilt and bias, and the speed lost meanwhile).
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.state import ATT, BA, N_ERR, VEL, NavState
from slip_estimator.core.types import WheelSample

_NS = 1_000_000_000
TAKE_BACK_CHECK_S = SCALES_S[0]
"""How long after a take-back the INS is watched (see
:meth:`ForwardSpeedHistory.take_back_refuted`): the step test's shortest scale, over which
its spread is measured (:class:`RunawayScale`)."""
RUNAWAY_SIGMA = 4.0
"""A take-back is checked when the along-track acceleration it removed exceeds this many times
the acceleration the INS resolves over the check (:class:`RunawayScale`). On the simulated
Pathfinder IMU (1-s spread 0.045-0.068 m/s, g times the tilt 1-sigma 0.050-0.062 m/s^2) that
is 0.20-0.27 m/s^2 (the constant it replaces: 0.2), where the false take-backs on ground that
never slips removed 4.1-9.5 times the scale; on the consumer 30-Hz IMU (g tilt 0.066-0.089)
0.26-0.36. Below 3.7 a tactical IMU's right take-back at a patch the body kept slowing
through (0.074 m/s^2 removed, g tilt 0.020) would be restored."""
_RUNAWAY_RATIO = (0.7, 1.3)
"""The INS's speed change over the check, relative to the acceleration removed times the
check's span, that marks it as running away at that rate (the false take-backs: 0.82-1.17)."""


class RunawayScale(NamedTuple):
    """What a take-back's check is measured against, from this IMU and these wheels at the
    take-back (:func:`runaway_scale`)."""

    accel_mps2: float
    """along-track acceleration the free INS resolves over ``TAKE_BACK_CHECK_S``, m/s^2"""
    rim_mps: float
    """rim-speed change that still counts as steady over the check, m/s"""


def runaway_scale(spread_var_mps2: float, tilt_std_rad: float, g_mps2: float,
                  aid_noise_var_mps2: float) -> RunawayScale:
    """The check's scale from measured quantities: the acceleration is the coarser of the free
    residual's measured spread over the check span (``spread_var_mps2``, the step test's at
    its shortest scale) per that span and the filter's tilt resolution (``tilt_std_rad``, its
    1-sigma, grown by the vibration the IMU shows) times ``g_mps2`` (a take-back within either could be the aid's routine levelling of a
    real tilt or a body that keeps slowing); the rim tolerance is the wheel aid's measured
    innovation scatter (``aid_noise_var_mps2``: encoder quantisation, pitching; where the rim
    moves beyond it, the INS may have followed the body)."""
    return RunawayScale(max(math.sqrt(spread_var_mps2) / TAKE_BACK_CHECK_S,
                            tilt_std_rad * g_mps2), math.sqrt(aid_noise_var_mps2))


@dataclass
class _TakeBack:
    """A take-back waiting for its check: when, its tilt and bias error state, the along-track
    acceleration it removed, the forward speed then, the scale it is checked against, and the
    rim speed at the first wheel sample after it."""

    t_ns: int
    dx: np.ndarray
    da_fwd_mps2: float
    v_fwd_mps: float
    scale: RunawayScale
    rim_mps: float | None = None


class HistoryPoint(NamedTuple):
    """The history at one instant (linearly interpolated)."""

    v_fwd_mps: float
    """forward speed of the wheel-contact point (corrections included), m/s"""
    yaw_rate_b_rps: float
    """gyro z less its bias (FRD), rad/s"""
    v_free_mps: float
    """the slip model's free forward speed (wheel-aid corrections excluded), m/s"""
    aid_accel_mps2: float
    """along-track acceleration the wheel aid's corrections cause, m/s^2"""


class Correction(NamedTuple):
    """What one closed-loop correction did to the forward motion."""

    dv_fwd_mps: float
    """change of the forward speed ``C_b_n[:, 0] . v_eb_n``, m/s"""
    da_fwd_mps2: float
    """change of ``g C_b_n[2, 0] - b_a[0]`` (along-track gravity less bias), m/s^2"""
    dx: np.ndarray | None = None
    """the error state fed back (``core.state`` layout)"""


class ForwardSpeedHistory:
    """Forward speed, yaw rate and free speed over the last ``horizon_s`` (see module doc)."""

    def __init__(self, l_bw_b: tuple[float, float, float], horizon_s: float = 2.0,
                 aid_horizon_s: float = 4.0) -> None:
        self._l_bw_b = l_bw_b
        self._horizon_ns = int(horizon_s * _NS)
        self._aid_horizon_ns = int(aid_horizon_s * _NS)
        self._rows: deque = deque()
        self._shift_mps = 0.0  # sum of the forward-speed corrections so far
        self._aid_v_mps, self._aid_a_mps2 = 0.0, 0.0
        self._taught: deque = deque()  # (stamp ns, dx) of the wheel aid's corrections
        self._taken_back: _TakeBack | None = None  # the last take-back, until checked

    def __len__(self) -> int:
        return len(self._rows)

    def clear(self) -> None:
        """Forget the recorded past and the aid's accumulated effect (after a recovery)."""
        self._rows.clear()
        self._taught.clear()
        self._taken_back = None
        self._aid_v_mps, self._aid_a_mps2 = 0.0, 0.0

    def newest(self) -> tuple[int, HistoryPoint]:
        """Stamp and values of the newest entry, as recorded (corrections since excluded)."""
        t, v, y, f, a = self._rows[-1]
        return t, HistoryPoint(v + self._shift_mps, y, f, a)

    def apply(self, correction: Correction, aid: bool, taught: bool = False) -> None:
        """Move the recorded forward speeds by a correction; a wheel-aid one (``aid``) is also
        kept out of the free speed from now on; an ordinary aid update (``taught``, not an
        anchor or a take-back) is remembered for :meth:`aid_taught_since`."""
        change = correction.dv_fwd_mps
        self._shift_mps += change
        if aid:
            self._aid_v_mps += change
            self._aid_a_mps2 += correction.da_fwd_mps2
        if taught and correction.dx is not None and self._rows:
            stamp_ns = self._rows[-1][0]
            remembered = self._taught
            remembered.append((stamp_ns, correction.dx))
            while remembered[0][0] < stamp_ns - self._aid_horizon_ns:
                remembered.popleft()

    def aid_taught_since(self, since_ns: int) -> np.ndarray:
        """The tilt and accelerometer-bias parts of the wheel aid's corrections made at or
        after ``since_ns`` (INS time, within the last ``aid_horizon_s``), summed into one error
        state (velocity, position and gyro bias zero); they are forgotten."""
        dx = np.zeros(N_ERR)
        taught = self._taught
        while taught and taught[-1][0] >= since_ns:
            d = taught.pop()[1]
            dx[ATT] += d[ATT]
            dx[BA] += d[BA]
        return dx

    def taken_back(self, scale: RunawayScale, *corrections: Correction) -> None:
        """Remember a take-back (its corrections: the take-back and the anchor after it; their
        tilt and bias parts) for :meth:`take_back_refuted`, checked against ``scale``."""
        dx = np.zeros(N_ERR)
        for c in corrections:
            dx[ATT] += c.dx[ATT]
            dx[BA] += c.dx[BA]
        t_ns, now = self.newest()
        self._taken_back = _TakeBack(t_ns, dx, sum(c.da_fwd_mps2 for c in corrections),
                                     now.v_fwd_mps, scale)

    def take_back_refuted(self, rim_mps: float, forward_n: np.ndarray) -> np.ndarray | None:
        """``TAKE_BACK_CHECK_S`` after a take-back (``rim_mps``: the rim speed now; ``forward_n``:
        the body's forward axis in navigation axes): the error state that restores it (the
        tilt and bias taken back, and the forward speed the INS lost since) if the INS ran
        away at the rate removed while the rim stayed steady (module doc), else None."""
        tb = self._taken_back
        if tb is None:
            return None
        if tb.rim_mps is None:
            tb.rim_mps = rim_mps
        t_ns, now = self.newest()
        if t_ns - tb.t_ns < int(TAKE_BACK_CHECK_S * _NS):
            return None
        self._taken_back = None
        removed_mps = tb.da_fwd_mps2 * TAKE_BACK_CHECK_S
        dv_mps = now.v_fwd_mps - tb.v_fwd_mps
        lo, hi = _RUNAWAY_RATIO
        if abs(tb.da_fwd_mps2) < RUNAWAY_SIGMA * tb.scale.accel_mps2 \
                or abs(rim_mps - tb.rim_mps) >= tb.scale.rim_mps \
                or not lo * abs(removed_mps) <= dv_mps * math.copysign(1.0, removed_mps) \
                <= hi * abs(removed_mps):
            return None
        dx = -tb.dx
        dx[VEL] = dv_mps * forward_n
        return dx

    def record(self, stamp_ns: int, state: NavState, w_b: list[float], dt_s: float) -> None:
        """Append the state at ``stamp_ns`` (gyro rate ``w_b``, IMU step ``dt_s``)."""
        # Forward component of NonHolonomic.point_velocity_b, in scalars (runs at IMU rate;
        # the planet-rate part of the lever-arm term, < 3e-5 m/s, is left out).
        _, bg_y, bg_z = state.b_g.tolist()
        wy, wz = w_b[1] - bg_y, w_b[2] - bg_z
        _, ly, lz = self._l_bw_b
        C, (vN, vE, vD), _ = state.floats()
        c1, c2, c3 = C[0], C[3], C[6]
        v_fwd = (c1 * vN + c2 * vE + c3 * vD) + wy * lz - wz * ly
        # The free speed: the filter's, less what the wheel aid did to it, with that
        # acceleration, so that a speed change over an interval can be taken without the aid
        # corrections made in it (the aid cannot hide a slip step by tilting the INS).
        self._aid_v_mps += self._aid_a_mps2 * dt_s
        rows = self._rows
        rows.append((stamp_ns, v_fwd - self._shift_mps, wz, v_fwd - self._aid_v_mps,
                     self._aid_a_mps2))
        horizon = stamp_ns - self._horizon_ns
        while rows[0][0] < horizon:  # never empties: the newest entry is not older
            rows.popleft()

    def _row_before(self, stamp_ns: int) -> int:
        """Index of the last row at or before ``stamp_ns`` (within the recorded span; bisection
        on the stamps), the first row's when only one is at or before it."""
        h = self._rows
        lo, hi = 0, len(h) - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if h[mid][0] <= stamp_ns:
                lo = mid
            else:
                hi = mid
        return lo

    def at(self, stamp_ns: int) -> HistoryPoint | None:
        """The history at ``stamp_ns`` by linear interpolation; None outside the horizon."""
        h = self._rows
        if not h or stamp_ns < h[0][0] or stamp_ns > h[-1][0]:
            return None
        lo = self._row_before(stamp_ns)
        hi = min(lo + 1, len(h) - 1)
        t0, v0, y0, f0, a0 = h[lo]
        t1, v1, y1, f1, a1 = h[hi]
        a = 0.0 if t1 == t0 else (stamp_ns - t0) / (t1 - t0)
        return HistoryPoint(v0 + a * (v1 - v0) + self._shift_mps, y0 + a * (y1 - y0),
                            f0 + a * (f1 - f0), a0 + a * (a1 - a0))

    def mean_yaw_rate_b_rps(self, start_ns: int, end_ns: int) -> float | None:
        """The mean over ``[start_ns, end_ns]`` (clipped to the recorded span) of the gyro z
        rate less its bias (FRD, linearly interpolated between samples), rad/s: what a wheel
        sample's count difference over that interval turned at. A single sample would not do:
        a vibration line the IMU rate folds onto a multiple of the wheel rate (a 70-Hz
        resonance at 30 Hz is 10 Hz) holds one phase at every wheel instant and reads as a
        gyro bias; over a whole wheel interval it averages out. None outside the horizon;
        the interpolated value when the interval is empty."""
        h = self._rows
        if not h or end_ns < h[0][0] or start_ns > h[-1][0]:
            return None
        start_ns, end_ns = max(start_ns, h[0][0]), min(end_ns, h[-1][0])
        if end_ns <= start_ns:
            return self.at(start_ns).yaw_rate_b_rps
        lo = self._row_before(start_ns)
        area = 0.0  # trapezoids of the linear interpolant, from start_ns to end_ns
        t_prev, y_prev = start_ns, self.at(start_ns).yaw_rate_b_rps
        # By index: a deque indexes near its ends in a step, islice walked all the older rows.
        for i in range(lo + 1, len(h)):
            t, _, y, _, _ = h[i]
            if t >= end_ns:
                break
            area += 0.5 * (y + y_prev) * (t - t_prev)
            t_prev, y_prev = t, y
        area += 0.5 * (self.at(end_ns).yaw_rate_b_rps + y_prev) * (end_ns - t_prev)
        return area / (end_ns - start_ns)


class WheelQueue:
    """Wheel samples waiting for the INS to reach their stamps, oldest first.

    At most ``size`` wait: when the wheel stamps run far ahead of the IMU (clock offset, IMU
    dropout) the newest are kept.
    """

    def __init__(self, size: int = 50) -> None:
        self._size = size
        self._waiting: deque[WheelSample] = deque()

    def __len__(self) -> int:
        return len(self._waiting)

    def push(self, sample: WheelSample) -> bool:
        """Queue a sample; True when the oldest had to be dropped for it."""
        self._waiting.append(sample)
        if len(self._waiting) <= self._size:
            return False
        self._waiting.popleft()
        return True

    def any_reached(self, stamp_ns: int) -> bool:
        """True when a sample stamped at or before ``stamp_ns`` waits."""
        waiting = self._waiting
        return bool(waiting) and waiting[0].stamp_ns <= stamp_ns

    def reached(self, stamp_ns: int) -> Iterator[WheelSample]:
        """Take out, oldest first, the samples stamped at or before ``stamp_ns``."""
        waiting = self._waiting
        while waiting and waiting[0].stamp_ns <= stamp_ns:
            yield waiting.popleft()

    def drain(self) -> Iterator[WheelSample]:
        """Take out every sample, oldest first."""
        while self._waiting:
            yield self._waiting.popleft()

    def newest_rim_speed_mps(self) -> float:
        """The rim speed of the newest waiting sample (0 when none waits), m/s."""
        return self._waiting[-1].rim_speed_mps if self._waiting else 0.0
