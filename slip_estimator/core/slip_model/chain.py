"""What a finished slip measurement is held as: the chain of measured changes and its anchor.

A slip is measured from rest (anchored on the stop's zero velocity) or as a change from the
held slip before it. Each change adds the INS error over its measuring span (the step test's
learned 2.5-s spread) to the chain, so the held slip grows less certain from one change to
the next until a stop or a return to the ground measured after the last start:

* **baseline.** The first slip after a start from rest is the ground's; a later measurement
  within the chain's spread of it is that ground again (``slip_baseline = 'snap'``), which ends
  the chain (measured on the real logs: a chain of INS intervals is worse than the
  ZUPT-anchored start). A change the rim made (``rim_spun``) from a measured ground is judged
  by the chain before it: the INS resolved it at its shortest scale. Not on another slope:
  gravity along it changes the traction the wheels must give, so the same ground slips
  differently there (a pitch beyond ``SLOPE_RAD`` from the baseline's, plus ``_SLOPE_SIGMA`` of
  the attitude's tilt uncertainty: a consumer IMU's pitch wanders by 2 degrees on level
  ground);
* **false alarm.** A measurement within the change threshold of the previous hold is that
  hold (the INS confirms it);
* **run-ahead.** One that no slope explains (:mod:`.run_ahead`) is the INS:
  back to the baseline; where it was read on the body side (a steady rim: the INS's word
  alone) and not beyond ``run_ahead.MAX_SLIP`` (a body does not roll at twice the rim speed)
  the holds from there are ``doubted`` (the body may have run ahead: :data:`REJECTED_DOUBT`)
  until a stop or a return to the baseline (which the rejection is itself where it ends a
  chain off the baseline on the baseline's slope);
* **return of a run-ahead.** A run-ahead read nose down (:mod:`.run_ahead`), held or read
  short and confirmed as the hold before it, leaves a ground (``SlipReading.left_ground``,
  while the ground ahead is still nose-down); a body-side rise read from there past that
  ground, within the chain's spread of it, is the body falling back onto it: the ground, which
  ends the chain. The aided INS lags the pull, so the onset reads short (rough seed 0 at
  138 s: -0.04, truth -0.21) and its return, read from that hold, lands past the ground by
  the shortfall (0.24 on ground of 0.12, truth 0.00: 141 false medium samples). A partial
  return (short of the ground) is held as read; the grade's easing ends it
  (:meth:`~.run_ahead.RunAheadCheck.returned`);
* **ratchet.** Body-side changes in one direction, each alarm firing as soon as the step
  test could after the last hold, are one free-INS excursion unless together they beat the
  drift of their whole span: back to the hold before them (``RUN_GAP_S``);
* **ground.** A start from rest places the ground's slip to the filter's speed sigma at its
  end; only within ``ASSUMED_SLIP_STD`` of the rim speed is that better than assuming zero
  slip, and only such a baseline is the resolved ``ground`` (the odometry guard carries it).
  Not where the rest's zero-velocity updates left the INS speed off zero
  (:meth:`~.stop_clock.StopClock.rest_offset_mps`: an acceleration error they had not removed,
  which the start's free INS integrates) and the reading departs from the baseline beyond the
  INS spread on the side that offset pushes it: the baseline is held;
* **assumed.** After a start in motion nothing measured the ground: a slip the INS could not
  place is assumed (zero, the wheels' speed) and carries ``ASSUMED_SLIP_STD``; an INS too
  coarse to place a slip within the low class takes zero as its baseline until a stop.

Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.params import Params
from slip_estimator.core.slip_model import run_ahead
from slip_estimator.core.slip_model.records import Resolution, SlipReading

_COARSE_INS_FRACTION = 0.15
"""An INS whose speed over a measurement span scatters by more than this fraction of the rim
speed cannot place a slip within the low class (0.2 wide)."""
COARSE_CONTINUITY_FRACTION = 0.3
"""An INS whose speed over a measuring span scatters by more than this fraction of the rim
speed cannot carry a body-side change's continuity on its free speed: at the alarms of the
30-Hz consumer robot its spread was 0.38-0.63 of the rim speed and its free speed moved 2-6 m/s
more than the body over 2.75 s; on the real test17run with injected changes 0.11-0.27."""
ASSUMED_SLIP_STD = 0.1
"""1-sigma of a slip nothing measured (a start in motion, before a stop): half the low class."""
SLOPE_RAD = math.radians(4.0)
"""Another slope: gravity along it (sin 4 deg = 0.07 of the weight) is of the order of soft
ground's rolling resistance (0.05-0.1), so the wheels' traction demand and slip differ there.
Real terrain undulates by less (test17run: up to about 3 deg; at 2 deg one of its injected
patterns lost a return to its baseline, F1 0.98 -> 0.81)."""
_SLOPE_SIGMA = 2.0
"""A pitch change beyond ``SLOPE_RAD`` plus this many tilt sigmas is another slope."""
RESOLVED_SIGMAS = 3.5
"""A speed difference beyond this many sigmas of the INS's measured spread is one the INS
resolves (the step test's default ``slip_change_sigma``; kept apart from that parameter, which
a configuration may raise to switch the body-side step test off)."""
RUN_GAP_S = 0.5
"""A body-side change whose continuity anchor lies within this time (the step test's smoothing)
of the end of the previous body-side measurement, in the same direction, continues that
change's run (the ratchet): its alarm fired as soon as the step test had filled its longest
scale after the hold, so the free residual was still moving when the hold was taken. Measured
gaps: 0.1 s in all four ratchets on ground that never slips (and one on rough ground, truth
unchanged), 1.4-2.8 s between true consecutive changes on rough ground (4 seeds)."""


REJECTED_DOUBT = 0.5
"""Probability that a run-ahead the slope check rejected was the body's: the check is a coin
flip where the terrain pitches as much as a slope (rough ground: 8 of its 15 rejections over
seeds 0-7 were run-aheads the body made; the mean pitch over their windows -12.5 to +11.9 deg,
-8.8 to +10.7 for the INS's). Where it was, the hold snapped to the baseline is off by the
run-ahead and every change read from it after (the return to the ground read as a medium),
until a stop or a return to the baseline. Those holds are kept as read (snapping the return
to the ground offset later changes: rough seeds 1 and 7) but published as the mixture with
the baseline (:mod:`~slip_estimator.core.slip_confidence`). Measured (rough seeds 0-7,
balanced / false alarms): 0.568 / 10.4 -> 0.572 / 6.9 %; the doubt kept across the
rejection's own return to the baseline 0.555 / 6.0 % (seed 1 0.46 -> 0.32: a true high patch
after a rightly rejected INS run-ahead published low; test17run mixed 0.627 -> 0.594); only
where the rejection is on another slope than the baseline's 0.572 / 7.5 %; only for the next
change if it mirrors the rejected one 0.568 / 8.4 %.

Only a body-side rejection: a run-ahead read on the wheel side is the rim stepping down under
a body that kept its speed, the wheels ceasing to spin that the hold before had read short; the
baseline is then the ground again, not a guess. Doubting it too published the real test17run's
injected x2.0 spin-up after such a rejection low (high recall 0.93 -> 0.48); every rough-ground
rejection is body-side (its rims hold their rate)."""


def coarse_ins(spread_var: float, w: float, fraction: float = _COARSE_INS_FRACTION) -> bool:
    """True when the INS speed over a measuring span (``spread_var``, m^2/s^2) scatters by
    more than ``fraction`` (``_COARSE_INS_FRACTION`` unless given) of the rim speed ``w``."""
    return math.sqrt(spread_var) > fraction * abs(w)


class SlipChain:
    """The held slip's provenance: the ground's baseline, the chain's variance since the last
    anchor, and whether the hold rests on an assumption (see the module docstring)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.baseline: float | None = None
        self.baseline_pitch_rad: float | None = None  # the pitch it was measured at
        self.ground: float | None = None
        """the last baseline its start placed within ``ASSUMED_SLIP_STD`` (1-sigma): the
        ground's slip as far as this drive has resolved it (kept across stops)"""
        self.wheel_changed = False
        """a wheel-side change was held since the baseline's start (kept across stops): the
        wheels, not the ground, moved the slip, and the baseline may have been theirs"""
        self.reset()

    def reset(self) -> None:
        """Forget the chain (a stop or a re-initialised velocity); the baseline is kept."""
        self.chain_var = 0.0
        self.ins_chain_var = 0.0
        """what the odometry guard counts of ``chain_var`` (:func:`~.hold_variance.
        guard_var_mps2`): the changes the INS alone read that moved the hold to a new level;
        none for a reading that confirmed the hold (a false alarm, the INS's drift) or one
        whose rim stepped beyond what the INS misses while the body did not follow (the wheels
        spinning up or gripping again, ``rim_spun`` of :meth:`settle`: the INS resolved it)"""
        self.assumed = False  # the held slip rests on an assumption, not a measurement
        self._run: tuple[float, float, float] | None = None  # (slip before, t0 s, sign)
        self._body_end_s: float | None = None  # the end of the last body-side measurement
        self.doubted = False  # a run-ahead was rejected since the last anchor (REJECTED_DOUBT)

    @property
    def unplaced(self) -> bool:
        """The baseline is only assumed (a coarse start) and no start has resolved the
        ground yet: the aid is still levelling the filter's tilt, and a body-side alarm takes
        none of its corrections back (skid_steer_30hz seed 10: a take-back from the assumed 0
        moved the pitch 0.37 -> 1.92 deg). A measured baseline keeps the take-back even
        unresolved (seed 1: without it an alarm read 0.76 on ground of 0.04, +4 m)."""
        return self.assumed and self.ground is None

    def settle(self, reading: SlipReading, resolution: Resolution) -> float:
        """The slip to hold after ``reading``, judged against what the INS and the wheels
        resolve at its rim speed (``resolution``)."""
        measured = reading.slip  # a rejected run-ahead or a coarse start replace it below
        # The three every rule's arithmetic reads; the other facts by their records' names.
        previous, w, spread_var = reading.previous, reading.w_mps, resolution.spread_var_mps2
        p = self.params
        if reading.unmeasured:
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
        h = min(resolution.wheel_change_mps, p.slip_continuity_sigma * math.sqrt(spread_var))
        if reading.implausible_run_ahead:
            # Back to the ground's baseline (none yet after a start in motion: the wheels');
            # after a body-side run-ahead what is held from there rests on that decision
            # (REJECTED_DOUBT). Not after a wheel-side one (the rim stepped, the body kept its
            # speed: the wheels stopped spinning), nor one beyond MAX_SLIP: no ground lets the
            # body roll at twice the rim speed (a 50-g spike's 2 m/s held the class low 10 s).
            self.doubted = reading.body_window_s is not None and measured >= -run_ahead.MAX_SLIP
            measured = baseline if baseline is not None else 0.0
            self.assumed = self.assumed or baseline is None
        if reading.from_rest and self.baseline is not None and not self.wheel_changed and \
                (self.baseline - measured) * reading.rest_offset_mps * w > 0.0 and \
                abs(measured - self.baseline) * abs(w) > math.sqrt(spread_var):
            # The stop's first zero-velocity update put the held slip's speed error into tilt
            # and the rest was too short for the updates to take it out again: the start's
            # free INS runs off with the rest's offset (rough seed 4 at 253 s: the rest's speed
            # stayed at -0.014 m/s under its updates, the start read 0.29 on ground of 0.07,
            # with a filter speed sigma of 0.018 m/s). The slip lies beyond the reading on the
            # side the offset hides; where the ground the last start measured lies there and
            # the reading departs from it by more than the INS spreads over a measuring span,
            # that ground is the better reading (on the other side, or within the spread,
            # the reading itself: rough seeds 2 and 6, 0.02-0.03 from their truth).
            self.chain_var, self.doubted = 0.0, False
            return self.baseline
        if reading.from_rest:
            # An INS the filter knows too coarse to place the ground's slip within the low
            # class (a vibrating 30-Hz consumer IMU read s = -0.34 after a stop, truth 0)
            # takes the wheels' speed as the baseline, assumed, as after a start in motion.
            coarse = coarse_ins(reading.start_speed_var_mps2, w)
            if coarse:
                measured = 0.0
            self.baseline, self.assumed, self.chain_var = measured, coarse, 0.0
            self.doubted = self.wheel_changed = False
            self.ins_chain_var = 0.0
            self.baseline_pitch_rad = reading.pitch_rad
            if math.sqrt(reading.start_speed_var_mps2) <= ASSUMED_SLIP_STD * abs(w):
                # Better placed than the assumed zero slip: the ground, resolved.
                self.ground = measured
            return measured
        # Each change measured from the held model before it adds its INS error to the
        # model's: the chain's spread since the last anchor (a start from rest, or a return to
        # the baseline) is how far from the baseline a measurement may still be that ground.
        self.chain_var += spread_var
        run, self._run = self._run, None
        if reading.body_window_s is not None:
            end_s, self._body_end_s = self._body_end_s, reading.body_window_s[1]
            if end_s is None or reading.body_window_s[0] - end_s > RUN_GAP_S:
                run = None
        else:
            run, self._body_end_s = None, None
        if previous is not None and abs(measured - previous) * abs(w) < h:
            self._run = run
            return previous  # a false alarm: the INS confirms the held slip
        if reading.body_window_s is None:
            self.wheel_changed = True
        if previous is not None and reading.body_span_s is not None and \
                abs(measured - previous) * abs(w) < p.slip_continuity_sigma * math.sqrt(
                    spread_var * max(reading.body_span_s, resolution.spread_span_s)
                    / resolution.spread_span_s):
            # A body-side change is the free INS's word alone: one within what this INS
            # drifts over the span it integrated is not resolved, and the hold stays (a
            # vibrating 30-Hz consumer IMU read a body stopping at 1.1 m/s where its free
            # speed had not moved: the aid's own acceleration jumped by 0.4 m/s^2).
            self._run = run
            return previous
        left = reading.left_ground
        if left is not None and reading.body_window_s is not None and previous is not None and \
                measured > max(previous, left) and (measured - left) * abs(w) < max(
                    h, p.slip_continuity_sigma * math.sqrt(self.chain_var)):
            # The return of a run-ahead read nose down, past the ground it left: read on top
            # of an onset read short (module docstring), the ground.
            self.returned()
            return left
        if reading.body_window_s is not None and previous is not None:
            sign = math.copysign(1.0, measured - previous)
            if run is None or run[2] != sign:
                run = (previous, reading.body_window_s[0], sign)
            elif abs(measured - run[0]) * abs(w) < p.slip_continuity_sigma * math.sqrt(
                    spread_var) * max(1.0, (reading.body_window_s[1] - run[1])
                                      / resolution.spread_span_s):
                # The ratchet: body-side changes in one direction, each beginning where the
                # last ended, are one free-INS excursion unless together they beat what the
                # INS drifts over their whole span; a drift that keeps its direction beyond
                # a scale is a bias (tilt, accelerometer bias), growing with the span, not
                # its square root (the Pathfinder's measured IMU with rocking read a ground
                # that never slips 0.06 -> 0.47 -> 0.85 -> 1.0 within 6 s). Back to the
                # hold before the run.
                return run[0]
            self._run = run
        base_pitch = self.baseline_pitch_rad
        other_slope = base_pitch is not None and \
            abs(reading.pitch_rad - base_pitch) > SLOPE_RAD + _SLOPE_SIGMA * reading.pitch_std_rad
        # A rim-spun change from a measured ground adds no measuring span's drift to what
        # the snap judges (test17run wheels x1.4 read 0.316, truth 0.31, snapped to 0.045);
        # from an assumed one the chain's spread alone keeps a coarse INS's readings.
        snap_var = self.chain_var - spread_var if reading.rim_spun and self.baseline is not None \
            else self.chain_var
        if (baseline is not None and p.slip_baseline == 'snap' and not other_slope
                and abs(measured - baseline) * abs(w)
                < max(h, p.slip_continuity_sigma * math.sqrt(max(snap_var, 0.0)))):
            # Back on ordinary ground: the slip measured after the last start, anchored on the
            # zero velocity at rest, is more accurate than a chain of INS intervals (and a
            # rejected run-ahead that ends a chain here is a return to the ground's slip).
            self.chain_var, self.ins_chain_var, self._run, self.doubted = 0.0, 0.0, None, False
            return baseline
        if not reading.rim_spun:
            self.ins_chain_var += spread_var
        return measured

    def returned(self) -> None:
        """A held run-ahead is over (:meth:`~.run_ahead.RunAheadCheck.returned`): the body is
        back on the ground's slip, which ends the chain as a return to the baseline does."""
        self.chain_var, self.ins_chain_var, self._run = 0.0, 0.0, None
