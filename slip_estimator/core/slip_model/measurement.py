"""Measuring a slip while the INS runs free: from rest, after a body-side alarm, or after a
wheel-side change.

Physics. While the body speeds up or slows down (entering or leaving sand) the slip is not
settled, and the encoder speed, a count difference, lags the body: a measurement takes steady
samples only, for ``slip_measure_s``, and goes on while the filter's speed still moves between
the halves of its window (by more than twice the wheel/INS consistency noise, 2 cm/s at
least), up to ``_TIMEOUT_FACTOR`` times that time. What it measured depends on what it started
from (its :class:`~slip_estimator.core.slip_model.aided_record.Anchor`):

* **nothing** (a start from rest, ZUPT-anchored, or a recovery): the median INS slip;
* **a body-side alarm**: the velocity was re-anchored on continuity at the alarm and the INS
  has run free since, so its mean speed is the body's; the rest of the transition after the
  alarm (which comes mid-transition) is measured through;
* **a wheel-side change**: velocity continuity from the held model before the rim began to
  move plus the INS speed change since (the free INS with the aid's acceleration then; the
  aided one where the INS is coarse). A change within ``slip_continuity_sigma`` of the INS
  spread over that span is none (the body kept its speed), unless the rim's own change at the
  old slip is closer: a commanded rate the body followed.

What the measured slip is then held as is :mod:`slip_estimator.core.slip_model.chain`'s decision.
Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.slip_model.aided_record import Anchor
from slip_estimator.core.slip import slip_ratio, speed_ratio

_NS = 1_000_000_000
_TIMEOUT_FACTOR = 5.0
"""After this many ``slip_measure_s`` a measurement settles even if the body still moves."""
_SETTLED_MPS = 0.02
"""The body has settled when its speed moved by less than this (or twice the consistency
noise, if larger) between the halves of the measuring window."""


class SlipMeasurement:
    """One measurement of the module docstring (``measure_s``: ``slip_measure_s``)."""

    def __init__(self, measure_s: float) -> None:
        self._measure_ns = int(measure_s * _NS)
        self._timeout_ns = int(_TIMEOUT_FACTOR * measure_s * _NS)
        self.anchor: Anchor | None = None
        self._vals: list[tuple[float, float, float, float, int]] = []
        self.restart()

    def start(self, anchor: Anchor | None) -> None:
        """A new measurement from ``anchor`` (None: from rest or a recovery)."""
        self.anchor, self._vals = anchor, []
        self.restart()

    def restart(self) -> None:
        """Measure afresh from the next steady sample (a turn, an unsteady rim, an IMU gap)."""
        self._since_ns: int | None = None
        self.unsettled = False  # the last measurement ended at the timeout, still moving

    def add(self, t_ns: int, w: float, v: float, v_free: float, noise_var: float) -> bool:
        """One steady, straight sample (rim speed ``w``, the filter's forward speed ``v``, the
        free one ``v_free``; ``noise_var`` the wheel/INS consistency noise, m^2/s^2); True once
        the body has settled."""
        if self._since_ns is None:
            self._since_ns, self._vals = t_ns, []
        vals = self._vals
        vals.append((slip_ratio(v, w), v, w, v_free, t_ns))
        # After a body-side alarm the rest of the transition must be measured through (the
        # alarm comes mid-transition): once trimmed, the rest spans the measuring time again.
        body = self.anchor is not None and self.anchor.body
        if t_ns - (vals[0][4] if body else self._since_ns) < self._measure_ns:
            return False
        half = len(vals) // 2
        dv = (sum(x[1] for x in vals[half:]) / (len(vals) - half)
              - sum(x[1] for x in vals[:half]) / max(half, 1))
        if abs(dv) > max(_SETTLED_MPS, 2.0 * math.sqrt(noise_var)):
            if t_ns - self._since_ns < self._timeout_ns:
                del vals[:half]  # still speeding up or slowing down: measure on
                return False
            self.unsettled = True
        return True

    def drifting(self) -> bool:
        """A body-side measurement that timed out with the speed still moving at a steady rim:
        a slip is piecewise constant and settles within seconds, a tilt error accelerates
        the free INS for as long as it runs (a consumer IMU read s = 0.13 -> 1.0 so, while the
        truth held 0)."""
        return self.unsettled and self.anchor is not None and self.anchor.body

    def body_span_s(self) -> float | None:
        """Time from a body-side change's continuity anchor to the end of its measurement, s
        (what the free INS integrated over); None for any other measurement."""
        a = self.anchor
        if a is None or not a.body or not self._vals:
            return None
        return (self._vals[-1][4] - a.t_ns) * 1e-9

    def body_speed_mps(self) -> float | None:
        """The mean forward speed of a body-side measurement, m/s (the free INS since its
        alarm); None for any other measurement."""
        a = self.anchor
        if a is None or not a.body or not self._vals:
            return None
        return sum(x[1] for x in self._vals) / len(self._vals)

    def slip(self, previous: float | None, continuity_sigma: float, noise_var: float,
             spread_var: float, spread_scale_s: float) -> float:
        """The slip measured (before the chain's decision). ``previous``: the hold before a
        wheel-side change; ``noise_var``: the consistency noise; ``spread_var``: the INS
        speed-change variance over ``spread_scale_s`` (m^2/s^2), scaled to the span."""
        vals, a, n = self._vals, self.anchor, len(self._vals)
        self.anchor = None
        if a is None:
            return sorted(x[0] for x in vals)[n // 2]
        w_mean = sum(x[2] for x in vals) / n
        if a.body:
            return slip_ratio(sum(x[1] for x in vals) / n, w_mean)
        span_s = (sum(x[4] for x in vals) / n - a.t_ns) * 1e-9
        free = a.aid_accel_mps2 is not None
        dv = sum(x[3 if free else 1] for x in vals) / n - a.v_mps \
            + (a.aid_accel_mps2 * span_s if free else 0.0)
        followed = speed_ratio(previous) * w_mean - a.z_mps  # the rim's change at the old slip
        sigma = math.sqrt(max(noise_var, spread_var * span_s / spread_scale_s))
        if abs(dv) < continuity_sigma * sigma and abs(dv) < abs(dv - followed):
            dv = 0.0  # the body kept its speed
        return slip_ratio(a.z_mps + dv, w_mean)
