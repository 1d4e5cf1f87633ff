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
and bias parts made since a change began; the last take-back is checked after it
(:mod:`slip_estimator.core.take_back`).
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from slip_estimator.core.state import ATT, BA, N_ERR, NavState
from slip_estimator.core.take_back import RunawayScale, TakeBackCheck
from slip_estimator.core.types import WheelSample

_NS = 1_000_000_000
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
        self._take_back = TakeBackCheck()  # the last take-back, until checked

    def __len__(self) -> int:
        return len(self._rows)

    def clear(self) -> None:
        """Forget the recorded past and the aid's accumulated effect (after a recovery)."""
        self._rows.clear()
        self._taught.clear()
        self._take_back.clear()
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
        """Remember a take-back (its corrections: the take-back and the anchor after it) for
        :meth:`take_back_refuted`, checked against ``scale`` (:meth:`TakeBackCheck.taken_back`)."""
        t_ns, now = self.newest()
        self._take_back.taken_back(t_ns, now.v_fwd_mps, scale, corrections)

    def take_back_refuted(self, rim_mps: float, forward_n: np.ndarray) -> np.ndarray | None:
        """The error state that restores the last take-back, or None
        (:meth:`TakeBackCheck.refuted`; ``rim_mps``: the rim speed now, ``forward_n``: the
        body's forward axis in navigation axes)."""
        if not self._take_back.pending:
            return None
        t_ns, now = self.newest()
        return self._take_back.refuted(t_ns, now.v_fwd_mps, rim_mps, forward_n)

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
