"""The wheel aid: what one wheel sample's rim speed may tell the filter.

``wheel_aid = 'hold'``: the slip model (:mod:`slip_estimator.core.slip_model.model`) decides per
wheel sample whether the rim speed aids the forward velocity as ``r w g(s_hold)``, re-anchors
it after a slip change, or leaves the INS free while a new slip is measured. While the
estimator recovers (after an in-motion start, an IMU gap or a divergence) the rim speed
re-anchors the velocity with zero slip assumed. ``'off'``: never (the paper's method). The
decisions are :class:`~slip_estimator.core.slip_model.aid_decision.AidDecision`
values for the filter's :class:`~slip_estimator.core.measurements.ForwardSpeed` model.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.history import HistoryPoint
from slip_estimator.core.odometry_guard import GuardDecision, decide, ins_speed_error_var
from slip_estimator.core.params import Params
from slip_estimator.core.slip_confidence import Confidence, ReadingRecord
from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.chain import ASSUMED_SLIP_STD, REJECTED_DOUBT
from slip_estimator.core.slip_model.hold_variance import assumed_hold, guard_var_mps2
from slip_estimator.core.slip_model.model import Mode, SlipModel
from slip_estimator.core.slip_model.rim_memory import rim_steady
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.types import SlipEstimate, WheelSample

_RECOVERY_SLIP_STD = 0.1  # zero slip assumed while recovering: 10 % of the rim speed, 1-sigma


class WheelAid:
    """Wheel-aid decisions (see the module docstring); :attr:`slip_model` is the slip model."""

    def __init__(self, params: Params) -> None:
        own = params.slip_model
        self._mode = own.wheel_aid
        self._moving_speed_mps = own.moving_speed_threshold_mps
        self._aid_std_mps = own.wheel_aid_std_mps
        self._latency_s = params.wheel_latency_s
        self._last: tuple[int, float] | None = None  # (stamp ns, rim speed m/s) of the last sample
        self._rim_steady = False  # the last sample's rim speed moved little from the one before
        self._resolving_sigmas = own.slip_change_sigma
        self.slip_model = SlipModel(params)
        self.readings = ReadingRecord()

    def stopping(self, wheel: WheelSample) -> bool:
        """The wheels stopped less than ``STOP_S`` ago, or stop by the sample's stamp (in any
        aid mode; call once per wheel sample).

        1. The body stops with the wheels: a slide on wheels held still ends within a tenth of
           a second on level ground (friction decelerates it at 2 m/s^2 or more), and after
           ``STOP_S`` the slip model takes the body to be at rest. A forward speed the INS
           still shows until then is its own error (a held slip's, a measurement's), not a
           slide: the slip is published as not moving. A slide that lasts, or a failed
           encoder, reads as slip from then on (:meth:`SlipModel.stopping`).
        2. The rim speed describes ``wheel_latency_s`` before the stamp (a count difference:
           the middle of its interval); so does the slip ratio, which changes slowly, but
           whether the wheels move changes at once. A slowing rim whose trend from the last
           sample, carried over the latency, falls below the moving threshold has stopped by
           the stamp: the slip published there is "not moving"."""
        held = self.slip_model.stopping(wheel.stamp_ns, wheel.rim_speed_mps,
                                        awaits_aid=self._mode == 'hold')
        last, self._last = self._last, (wheel.stamp_ns, wheel.rim_speed_mps)
        self._rim_steady = rim_steady(None if last is None else last[1], wheel.rim_speed_mps)
        return held or self._stops_by_stamp(wheel, last)

    def _stops_by_stamp(self, wheel: WheelSample, last: tuple[int, float] | None) -> bool:
        w = wheel.rim_speed_mps
        if last is None or wheel.stamp_ns <= last[0] or abs(w) >= abs(last[1]):
            return False
        slope_mps_per_s = (w - last[1]) / ((wheel.stamp_ns - last[0]) * 1e-9)
        return abs(w + slope_mps_per_s * self._latency_s) < self._moving_speed_mps

    def reanchor(self, rim_speed_mps: float, turning: bool) -> AidDecision | None:
        """While recovering: the rim speed itself (zero slip assumed; not in a turn, whose
        skid the rim speed does not describe). A repair: the free speed keeps its effect."""
        if self._mode == 'off' or turning:
            return None
        var_mps2 = self._aid_std_mps ** 2 + (_RECOVERY_SLIP_STD * rim_speed_mps) ** 2
        return AidDecision(rim_speed_mps, var_mps2, repair=True)

    def rim_timing_var_mps2(self, wheel: WheelSample) -> float:
        """Variance of the rim speed from its timing against the INS, m^2/s^2: the change since
        the last sample, squared (call before :meth:`stopping`). A count difference describes
        its interval, not an instant, and its latency is declared, not measured: a rim speed
        that changes is placed to within one sample interval (on the real s5t1 log the body led
        the rim by about one 10-Hz sample at every start and stop; 74 of its 104 samples read
        medium or worse were there)."""
        if self._last is None or wheel.stamp_ns <= self._last[0]:
            return 0.0
        return (wheel.rim_speed_mps - self._last[1]) ** 2

    @property
    def held_slip(self) -> float | None:
        """The slip the slip model holds (a change it accepted, or the ground's); None while it
        measures, at rest, or without the hold mode."""
        return self.slip_model.slip_hold if self._mode == 'hold' else None

    def held_speed_var_mps2(self, rim_speed_mps: float) -> float:
        """The held slip's own body-speed variance (``SlipModel.held_speed_var_mps2``); 0
        without the hold mode."""
        if self._mode != 'hold':
            return 0.0
        return self.slip_model.held_speed_var_mps2(rim_speed_mps)

    def confidence(self, rim_speed_mps: float, turning: bool) -> Confidence:
        """What the published slip adds to the filter's reading (:mod:`~slip_estimator.core.
        slip_confidence`; call once per evaluated wheel sample; nothing without the hold
        mode: no step test, no readings)."""
        if self._mode != 'hold':
            return Confidence()
        held, model = self.held_slip, self.slip_model
        self.readings.observe(held, model.baseline, model.mode is Mode.REST)
        doubt = REJECTED_DOUBT if held is not None and model.chain.doubted else 0.0
        return self.readings.confidence(held, model.baseline,
                                        model.body_change_mps(rim_speed_mps, turning), doubt)

    def odometry_decision(self, est: SlipEstimate) -> GuardDecision:
        """Whether the published odometry falls back to wheels + gyro at this sample
        (:func:`~slip_estimator.core.odometry_guard.decide` on the slip model's INS spread and
        the held level's chain variance (:func:`~.hold_variance.guard_var_mps2`: a hold chained on
        changes a consumer IMU alone measured is no better placed than that chain); a
        hold measured from rest with no change chained to it is anchored, and only on such a
        hold does the fallback carry a slip: the ground's as a start resolved it
        (``SlipChain.ground``: placed within ``ASSUMED_SLIP_STD``, better than assuming zero
        slip), if within half the low class (``ASSUMED_SLIP_STD``). A chained one on an INS
        that cannot resolve slip is no better than the raw rim speed, and a wrong one far
        worse (a consumer IMU's no-slip drive ended 4.8 m off carrying its anchored holds,
        2.8 m at the raw rim speed; another, 3.76 m against 3.42 at the rim speed, carrying
        s = 0.062 read at a start whose speed sigma was 0.145 of the rim speed);
        test17run's ground slips by ~0.05, and carrying it takes the plain forward-speed RMSE
        0.0444 -> 0.0403 m/s)). Only at a steady rim speed (:func:`~.rim_memory.rim_steady`,
        from :meth:`stopping`)."""
        model = self.slip_model
        chain = model.chain
        anchored = not chain.assumed and chain.chain_var == 0.0
        ground = chain.ground if self.held_slip is not None else None
        ins_var = ins_speed_error_var(model.spread_var, SCALES_S)
        w = est.wheel_speed_mps
        return decide(est, guard_var_mps2(chain, ins_var, self.held_slip, w), anchored,
                      self._resolving_sigmas, ground
                      if anchored and abs(ground or 0.0) <= ASSUMED_SLIP_STD else None,
                      self._rim_steady, assumed_hold(chain, self.held_slip, ins_var, w))

    def decide(self, wheel: WheelSample, at: HistoryPoint, est: SlipEstimate,
               C_b_n: np.ndarray, turning: bool, tilt_std_rad: float = 0.0,
               reading_var_mps2: list[float] | None = None,
               speed_var_mps2: float = 0.0) -> AidDecision | None:
        """The slip model's decision for one evaluated wheel sample (``est`` its slip, ``at``
        the history at its instant, ``C_b_n`` the attitude now, ``tilt_std_rad`` its tilt
        1-sigma; ``reading_var_mps2`` the filter's free-INS prediction per step-test scale and
        ``speed_var_mps2`` its forward-speed variance, :meth:`SlipModel.step`)."""
        if self._mode != 'hold':
            return None
        w = wheel.rim_speed_mps
        moving = est.slip_class > 0 and abs(w) >= self._moving_speed_mps
        pitch_rad = -math.asin(max(-1.0, min(1.0, float(C_b_n[2, 0]))))
        return self.slip_model.step(wheel.stamp_ns, w, at.v_fwd_mps, at.v_free_mps, moving,
                                    turning, pitch_rad, at.aid_accel_mps2, tilt_std_rad,
                                    reading_var_mps2, speed_var_mps2)
