"""What a finished slip measurement is held as: the chain of measured changes and its anchor.

A slip is measured from rest (anchored on the stop's zero velocity) or as a change from the
held slip before it. Each change adds the INS error over its measuring span (the step test's
learned 2.5-s spread) to the chain, so the held slip grows less certain from one change to
the next until a stop or a return to the ground measured after the last start:

* **baseline.** The first slip after a start from rest is the ground's; a later measurement
  within the chain's spread of it is that ground again (``slip_baseline = 'snap'``), which
  ends the chain (measured on the real logs: a chain of INS intervals is worse than the
  ZUPT-anchored start). Not on another slope: gravity along it changes the traction the
  wheels must give, so the same ground slips differently there (a pitch beyond
  ``SLOPE_RAD`` from the baseline's, plus ``_SLOPE_SIGMA`` of the attitude's tilt
  uncertainty: a consumer IMU's pitch wanders by 2 degrees on level ground);
* **false alarm.** A measurement within the change threshold of the previous hold is that
  hold (the INS confirms it);
* **run-ahead.** One that no slope explains (:mod:`.run_ahead`) is the INS:
  back to the baseline;
* **assumed.** After a start in motion nothing measured the ground: a slip the INS could not
  place is assumed (zero, the wheels' speed) and carries ``ASSUMED_SLIP_STD``; an INS too
  coarse to place a slip within the low class takes zero as its baseline until a stop.

Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.params import Params

_COARSE_INS_FRACTION = 0.15
"""An INS whose speed over a measurement span scatters by more than this fraction of the rim
speed cannot place a slip within the low class (0.2 wide)."""
ASSUMED_SLIP_STD = 0.1
"""1-sigma of a slip nothing measured (a start in motion, before a stop): half the low class."""
SLOPE_RAD = math.radians(4.0)
"""Another slope: gravity along it (sin 4 deg = 0.07 of the weight) is of the order of soft
ground's rolling resistance (0.05-0.1), so the wheels' traction demand and slip differ there.
Real terrain undulates by less (test17run: up to about 3 deg; at 2 deg one of its injected
patterns lost a return to its baseline, F1 0.98 -> 0.81)."""
_SLOPE_SIGMA = 2.0
"""A pitch change beyond ``SLOPE_RAD`` plus this many tilt sigmas is another slope."""


def coarse_ins(spread_var: float, w: float) -> bool:
    """True when the INS speed over a measuring span (``spread_var``, m^2/s^2) scatters by
    more than ``_COARSE_INS_FRACTION`` of the rim speed ``w``."""
    return math.sqrt(spread_var) > _COARSE_INS_FRACTION * abs(w)


class SlipChain:
    """The held slip's provenance: the ground's baseline, the chain's variance since the last
    anchor, and whether the hold rests on an assumption (see the module docstring)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.baseline: float | None = None
        self.baseline_pitch_rad: float | None = None  # the pitch it was measured at
        self.reset()

    def reset(self) -> None:
        """Forget the chain (a stop or a re-initialised velocity); the baseline is kept."""
        self.chain_var = 0.0
        self.assumed = False  # the held slip rests on an assumption, not a measurement

    def settle(self, measured: float, previous: float | None, w: float, spread_var: float,
               wheel_change_mps: float, from_rest: bool, unmeasured: bool,
               implausible_run_ahead: bool, pitch_rad: float = 0.0,
               pitch_std_rad: float = 0.0, body_span_s: float | None = None,
               spread_scale_s: float = 1.0, coarse_start: bool = False) -> float:
        """The slip to hold after a measurement of ``measured`` at rim speed ``w`` and pitch
        ``pitch_rad`` (1-sigma ``pitch_std_rad``).

        previous : the hold before the change (None after a start).
        spread_var : the INS's learned speed-change variance over a measuring span, m^2/s^2.
        wheel_change_mps : the wheel-side change threshold at ``w``.
        from_rest : the measurement started from a ZUPT-anchored stop (a new baseline).
        unmeasured : the INS was re-initialised from the rim (zero slip assumed).
        implausible_run_ahead : a run-ahead no slope explains was measured.
        body_span_s : for a body-side change, the time its free INS integrated over, s.
        spread_scale_s : the span ``spread_var`` refers to, s.
        coarse_start : a start from rest whose measured speed the filter knows too coarse to
            place the slip within the low class (:func:`coarse_ins` of its own variance).
        """
        p = self.params
        if unmeasured:
            self.assumed = True
        baseline = self.baseline
        if baseline is None and coarse_ins(spread_var, w):
            # A start in motion with an INS too coarse to place a slip within the low class:
            # no stop measured the ground yet, zero slip (the wheels' speed) is the assumed
            # baseline, and a change measured from there is kept only beyond the chain's
            # spread (a consumer IMU read s = 0.6 for 200 s, truth 0.1).
            baseline = 0.0
        # Within this speed of the previous hold or of the baseline a measurement is that
        # value: the wheel-side threshold, or less where the INS over a measurement's span is
        # better than that (a good IMU resolves smaller slip differences).
        h = min(wheel_change_mps, p.slip_continuity_sigma * math.sqrt(spread_var))
        if implausible_run_ahead:
            # Back to the ground's baseline (none yet after a start in motion: the wheels').
            measured = baseline if baseline is not None else 0.0
            self.assumed = self.assumed or baseline is None
        if from_rest:
            # An INS the filter knows too coarse to place the ground's slip within the low
            # class (a vibrating 30-Hz consumer IMU read s = -0.34 after a stop, truth 0)
            # takes the wheels' speed as the baseline, assumed, as after a start in motion.
            coarse = coarse_start
            if coarse:
                measured = 0.0
            self.baseline, self.assumed, self.chain_var = measured, coarse, 0.0
            self.baseline_pitch_rad = pitch_rad
            return measured
        # Each change measured from the held model before it adds its INS error to the
        # model's: the chain's spread since the last anchor (a start from rest, or a return to
        # the baseline) is how far from the baseline a measurement may still be that ground.
        self.chain_var += spread_var
        if previous is not None and abs(measured - previous) * abs(w) < h:
            return previous  # a false alarm: the INS confirms the held slip
        if previous is not None and body_span_s is not None and \
                abs(measured - previous) * abs(w) < p.slip_continuity_sigma * math.sqrt(
                    spread_var * max(body_span_s, spread_scale_s) / spread_scale_s):
            # A body-side change is the free INS's word alone: one within what this INS
            # drifts over the span it integrated is not resolved, and the hold stays (a
            # vibrating 30-Hz consumer IMU read a body stopping at 1.1 m/s where its free
            # speed had not moved: the aid's own acceleration jumped by 0.4 m/s^2).
            return previous
        base_pitch = self.baseline_pitch_rad
        other_slope = base_pitch is not None and \
            abs(pitch_rad - base_pitch) > SLOPE_RAD + _SLOPE_SIGMA * pitch_std_rad
        if (baseline is not None and p.slip_baseline == 'snap' and not other_slope
                and abs(measured - baseline) * abs(w)
                < max(h, p.slip_continuity_sigma * math.sqrt(self.chain_var))):
            # Back on ordinary ground: the slip measured after the last start, anchored on the
            # zero velocity at rest, is more accurate than a chain of INS intervals.
            self.chain_var = 0.0
            return baseline
        return measured

    def held_speed_var_mps2(self, w: float, spread_var: float) -> float:
        """Body-speed variance of the held slip at rim speed ``w``, m^2/s^2: the INS spread of
        a measurement plus the chain since the last anchor; ``ASSUMED_SLIP_STD`` of ``w`` if
        nothing measured it (a start in motion), or the chain of changes measured from there
        if wider (on the 30-Hz consumer robot four such changes ratcheted the hold from 0 to
        0.46, truth 0.11, while the published sigma stayed at 0.10)."""
        if self.assumed:
            return max((ASSUMED_SLIP_STD * w) ** 2, self.chain_var)
        return spread_var + self.chain_var
