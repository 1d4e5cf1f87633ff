"""The slip model: which part of a wheel/IMU speed discrepancy is slip, and which is INS error.

What it assumes and where it fails: the package docstring (:mod:`slip_estimator.core.slip_model`).
In short, slip is piecewise constant, its changes are steps of the *free residual*
``rho = v_ins - g(s) w`` (``w = r omega`` the rim speed, ``g(s) = v / w`` of the held slip),
and INS error is a random walk.

The detector looks at the free residual of the *uncorrected* INS (the filter's own velocity
corrections removed, so the wheel aid cannot hide a change from it) with a multi-scale step
test (:mod:`.step_test`): the change of its 0.5-s mean over 1 s and 2.5 s
against ``slip_change_sigma`` times the spread of that change, learned online, and never below
``slip_change_fraction`` of the rim speed. A slow common divergence stays under the threshold;
a step beyond it is a slip change whichever side it shows on.

Modes (:class:`Mode`):

* ``REST``: not moving. The ZUPT anchors the velocity; the next start is measured from it
  (the INS speed its last half-second left off zero, beyond the ZUPT's 1-sigma, tells the
  chain the start's free INS runs off: :meth:`~.stop_clock.StopClock.rest_offset_mps`);
* ``MEASURE``: after a start or a detected change the INS runs free (no wheel aid) until the
  body has settled (:mod:`.measurement`); the measured slip is then held as :mod:`.chain`
  decides (the ground's baseline, a false alarm, a run-ahead no slope explains:
  :mod:`.settling`). A body-side change is anchored at its alarm on velocity continuity and
  the aid's corrections since its onset are taken back (:mod:`.body_side`); a wheel-side one
  is measured from before the rim began to move (:mod:`.wheel_side`);
* ``TRACK``: the held slip turns the rim speed into a forward-speed aid ``g(s_hold) w`` that
  stops the INS drift without assuming zero slip, while both sides watch for the next
  change (no aid while the rim speed changes: encoder lag).

Its parts, in the order a wheel sample meets them; the model owns them, hands each the
sample's inputs (:class:`~.records.ModelSample`) and applies what they return:

* :class:`~.stop_clock.StopClock` -- when still wheels are a stop and bring the zero-speed aid;
* :class:`~.rim_memory.RimMemory` -- whether the rim speed is steady, how far and since when
  it moved;
* ``MEASURE``: :class:`~.measurement.SlipMeasurement` and :func:`~.settling.settle` -- one
  measurement and what it settles on (:class:`~.chain.SlipChain`,
  :class:`~.run_ahead.RunAheadCheck`);
* ``TRACK``: :class:`~.wheel_side.WheelSide` and :class:`~.body_side.BodySide` (which feeds
  the :class:`~.step_test.StepTest`) -- a change on either side, returned as a
  :class:`~.records.Change` (its anchor and what the filter is told at once);
* :class:`~.aided_record.AidedRecord` and :class:`~.aided_record.ConsistencyNoise` -- the
  aided samples a change continues from, and the wheel/INS consistency noise;
* :mod:`.thresholds` -- the change thresholds from the parameters and the learned spread.

Decisions (:class:`AidDecision`) go to the estimator; only the standard library is used.
"""
from __future__ import annotations

import enum

from slip_estimator.core.params import Params
from slip_estimator.core.slip import speed_ratio
from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.aided_record import ANCHOR_S, AidedRecord, ConsistencyNoise
from slip_estimator.core.slip_model.body_side import BodySide
from slip_estimator.core.slip_model.chain import SlipChain
from slip_estimator.core.slip_model.hold_variance import held_speed_var_mps2
from slip_estimator.core.slip_model.measurement import SlipMeasurement
from slip_estimator.core.slip_model.records import Change, ModelSample
from slip_estimator.core.slip_model.rim_memory import RimMemory
from slip_estimator.core.slip_model.run_ahead import RunAheadCheck
from slip_estimator.core.slip_model.settling import settle
from slip_estimator.core.slip_model.step_test import SCALES_S, StepTest
from slip_estimator.core.slip_model.stop_clock import StopClock
from slip_estimator.core.slip_model.thresholds import body_change_mps, spread_var_mps2
from slip_estimator.core.slip_model.wheel_side import WheelSide

CHANGE_LOOKBACK_S = SCALES_S[-1] + ANCHOR_S + 0.5
"""How far before a body-side alarm its onset and continuity anchor can lie, s."""


class Mode(enum.Enum):
    """What the model does with a wheel sample (see the module docstring)."""

    REST = 'rest'
    MEASURE = 'measure'
    TRACK = 'track'


class SlipModel:
    """Slip change detection on both sides and wheel-aid decisions (see the module docstring).

    ``step`` takes one wheel sample: rim speed ``w``, the filter's forward speed ``v``, the
    free forward speed ``v_free`` and the rest of a :class:`~.records.ModelSample`, and
    returns the aid to apply or None.
    """

    def __init__(self, params: Params) -> None:
        self.params = params
        # Prior spread of the step statistic: twice the aid noise per sqrt(s) (a random walk).
        self.step_test = StepTest((2.0 * params.wheel_aid_std_mps) ** 2)
        self._noise = ConsistencyNoise()
        self._aided = AidedRecord(CHANGE_LOOKBACK_S)
        self.changes = {'wheel': 0, 'body': 0}
        self.chain = SlipChain(params)
        self._run_ahead = RunAheadCheck()
        self._rim = RimMemory()
        self._measurement = SlipMeasurement(params.slip_measure_s)
        self._stop = StopClock(params.moving_speed_threshold_mps)
        self._wheel_side = WheelSide(params)
        self._body_side = BodySide(params)
        self.reset(from_rest=True)  # a new filter starts from rest (or is told otherwise)

    def _reset(self) -> None:
        """Forget the held slip, its measurement and what the parts remember of the drive."""
        self.mode = Mode.REST
        self.slip_hold: float | None = None
        self._previous: float | None = None
        self._measurement.start(None)
        self._wheel_side.clear()
        self._rim.clear()
        self._aided.clear()
        self.step_test.clear()
        self._run_ahead.reset()
        self.chain.reset()
        self._body_side.clear()
        self._carried_var_mps2 = 0.0  # the last hold's, while nothing re-measured the speed
        # The filter's free-INS prediction per scale at the last sample (spread_var's floor).
        self._reading_var_mps2: tuple[float, ...] = ()

    def reset(self, from_rest: bool) -> None:
        """Forget the held slip and the stop under way: a stop (``from_rest``: the next start
        is ZUPT-anchored) or a velocity re-initialised after a fault (not an anchor)."""
        self._reset()
        self._stop.clear()
        self._from_rest = from_rest
        self._rest_offset_mps = 0.0  # the speed the last rest's updates left (StopClock)

    def interrupt(self) -> None:
        """The INS went through a gap: its speed change across it says nothing about slip, so
        the step test and a running measurement start afresh (the held slip is kept)."""
        self.step_test.clear()
        self._aided.clear()
        self._measurement.restart()
        self._body_side.interrupt()  # re-anchor on the held slip, then quiet

    # ------------------------------------------------------------------ the step
    def step(self, t_ns: int, w: float, v: float, v_free: float, moving: bool,
             turning: bool, pitch_rad: float = 0.0, aid_accel_mps2: float = 0.0,
             pitch_std_rad: float = 0.0, reading_var_mps2: list[float] | None = None,
             speed_var_mps2: float = 0.0) -> AidDecision | None:
        """One wheel sample (see the class docstring), dispatched by mode: the decision of the
        part that handled it."""
        s = ModelSample(t_ns, w, v, v_free, aid_accel_mps2, pitch_std_rad,
                        tuple(reading_var_mps2 or ()), speed_var_mps2)
        self._reading_var_mps2 = s.reading_var_mps2
        self._run_ahead.add(t_ns, pitch_rad)
        still_ns = self._stop.still_ns(t_ns, w)
        if not moving:
            return self._stopped(s, still_ns)
        steady = self._rim.add(t_ns, w)
        if self.slip_hold is None:
            self.mode = Mode.MEASURE
            return self._measure(s, steady, turning)
        return self._track(s, steady, turning)

    def _stopped(self, s: ModelSample, still_ns: int | None) -> AidDecision | None:
        """Not moving: the held slip is forgotten and the next start is from rest; wheels
        still for ``still_ns`` bring the stop's zero-speed aid (:meth:`StopClock.zero_speed_aid`:
        None while above the moving threshold, ns)."""
        p = self.params
        carried = self.held_speed_var_mps2(self._rim.last_mps or 0.0)
        self._reset()  # the stop under way is kept
        self._from_rest = True
        if still_ns is None:  # the rim is above the moving threshold
            return None
        rest_offset_mps = self._stop.zero_speed_aid(s.t_ns, still_ns, s.v_mps,
                                                    p.zupt_velocity_std_mps)
        if rest_offset_mps is None:  # stopping
            self._carried_var_mps2 = carried  # until the zero-speed aid
            self._rest_offset_mps = 0.0
            return None
        self._rest_offset_mps = rest_offset_mps
        return AidDecision(0.0, (2.0 * p.wheel_aid_std_mps) ** 2)

    def _measure(self, s: ModelSample, steady: bool, turning: bool) -> AidDecision | None:
        """The INS runs free until the body has settled
        (:class:`~slip_estimator.core.slip_model.measurement.SlipMeasurement`); then the measured
        slip is held as the chain decides and the velocity is anchored on it."""
        p = self.params
        if turning or not steady:
            self._measurement.restart()
            return None
        if not self._measurement.add(s.t_ns, s.w_mps, s.v_mps, s.v_free_mps,
                                     self.aid_noise_var):
            return None
        # The measurement ends the start from rest (and the offset its rest left).
        from_rest, rest_offset_mps = self._from_rest, self._rest_offset_mps
        self._from_rest, self._rest_offset_mps = False, 0.0
        measured = settle(s, self._measurement, self.chain, self._run_ahead, self._previous,
                          from_rest, rest_offset_mps, self.spread_var, self.aid_noise_var, p)
        self.slip_hold, self.mode = measured, Mode.TRACK
        self.step_test.clear()
        # Anchor the velocity on the new hold now (not gated: where the measurement snapped,
        # the INS is known to have drifted, it is not an outlier).
        return AidDecision(speed_ratio(measured) * s.w_mps, p.wheel_aid_std_mps ** 2,
                           anchor=True, held_slip=measured)

    def _track(self, s: ModelSample, steady: bool, turning: bool) -> AidDecision | None:
        """Aid the held slip, unless a change shows on the wheel side (:mod:`.wheel_side`) or
        the body side (:mod:`.body_side`): then measure it (:meth:`_start_change`)."""
        p = self.params
        t_ns, w, v, v_free = s.t_ns, s.w_mps, s.v_mps, s.v_free_mps
        g = speed_ratio(self.slip_hold)
        z = g * w
        if self._body_side.gap_closed(t_ns):
            return AidDecision(z, p.wheel_aid_std_mps ** 2, anchor=True, repair=True)
        ground = self._run_ahead.returned()
        if ground is not None:
            # The grade that pulled the body ahead of its wheels has eased: back on the
            # ground's slip, anchored there (the aid held the run-ahead's speed meanwhile).
            self.chain.returned()
            self._body_side.returned(t_ns)
            self.slip_hold = ground
            self.step_test.clear()
            self._aided.clear()
            return AidDecision(speed_ratio(ground) * w, p.wheel_aid_std_mps ** 2, anchor=True,
                               held_slip=ground)
        # Wheel side: the rim speed moved and the body did not follow (or the reverse).
        discrepant, change = self._wheel_side.check(s, g, self._rim, self._aided,
                                                    self.aid_noise_var, self.spread_var,
                                                    self.baseline)
        if change is not None:
            return self._start_change(change)
        if discrepant:
            return None  # not yet a change: no aid, no step test
        # Body side: a step of the free residual (nothing taken back from an unplaced hold).
        change = self._body_side.check(s, g, turning, self.step_test, self._aided,
                                       None if self.chain.unplaced else self.baseline)
        if change is not None:
            return self._start_change(change)
        self._noise.add(t_ns, z - v)
        self._aided.add(t_ns, z, v, v_free, s.aid_accel_mps2)
        if not steady:
            # Speeding up or braking, the slip of a skid-steer rover is not the cruise slip
            # held, and the INS is good over the few tenths of a second it takes: no aid.
            # (A step building up is aided on: the detector reads the free speed, and a free
            # INS on the real rover drifts by more than the steps it would wait for.)
            return None
        # Turning, the wheels also skid sideways: the held slip is a looser constraint.
        return AidDecision(z, p.wheel_aid_std_mps ** 2 * (4.0 if turning else 1.0),
                           repair=self._body_side.quiet(t_ns))

    def _start_change(self, change: Change) -> AidDecision | None:
        """Measure ``change`` from its anchor (the hold before it is the chain's previous);
        the decision it tells the filter at once."""
        self._carried_var_mps2 = self.held_speed_var_mps2(self._rim.last_mps or 0.0)
        self._previous = self.slip_hold
        self._measurement.start(change.anchor)
        self.slip_hold, self.mode = None, Mode.MEASURE
        self._wheel_side.clear()
        self._aided.clear()
        self.step_test.clear()
        self._from_rest = False
        self.changes[change.side] += 1
        return change.decision

    # -------------------------------------------------- what the estimator reads
    def stopping(self, t_ns: int, w: float, awaits_aid: bool = True) -> bool:
        """The wheels are stopping, not stopped (:meth:`StopClock.stopping`)."""
        return self._stop.stopping(t_ns, w, awaits_aid)

    def held_speed_var_mps2(self, w: float) -> float:
        """Body-speed variance of the held slip at rim speed ``w`` beyond the filter's (its
        aided covariance knows nothing of the hold), m^2/s^2
        (:func:`~.hold_variance.held_speed_var_mps2`); carried through a change's measurement
        and into a stop until the zero-speed aid (the hold's error stays in the INS; at a stop
        it is not the body sliding on)."""
        if self.mode is not Mode.TRACK:
            return self._carried_var_mps2
        return held_speed_var_mps2(self.chain, w, self.spread_var[-1])

    @property
    def aid_noise_var(self) -> float:
        """Measured wheel/INS consistency noise (the aid's innovation variance), m^2/s^2
        (:class:`~slip_estimator.core.slip_model.aided_record.ConsistencyNoise`)."""
        return self._noise.var_mps2

    @property
    def baseline(self) -> float | None:
        """The ground's slip measured after the last start from rest (None before one)."""
        return self.chain.baseline

    @property
    def spread_var(self) -> list[float]:
        """Variance of the free residual's change at each step-test scale, m^2/s^2, floored
        by the last sample's ``reading_var_mps2`` (:func:`~.thresholds.spread_var_mps2`)."""
        return spread_var_mps2(self.step_test.spread_var, self._reading_var_mps2)

    @property
    def rim_speed_mps(self) -> float | None:
        """The rim speed of the last moving wheel sample, m/s (None at rest)."""
        return self._rim.last_mps

    def body_change_mps(self, w: float, turning: bool = False) -> float:
        """CUSUM threshold h of a body-side change at rim speed ``w``, m/s
        (:func:`~.thresholds.body_change_mps` on :attr:`spread_var`)."""
        return body_change_mps(self.params, self.spread_var, w, turning)
