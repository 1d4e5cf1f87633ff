"""The slip a finished measurement (:mod:`.measurement`) settles on: what it measured, held as
the chain decides (baseline, false alarm, run-ahead, the rest offset: :class:`~.chain.SlipChain`),
with what the measurement itself knows of it: a body-side reading still drifting at its
timeout or putting the body against its wheels (:func:`body_reversed`), the span its free
INS integrated, and whether a wheel-side change was the wheels'
(:func:`rim_spun`): the :class:`~.records.SlipReading` it hands the chain. Speeds in m/s,
variances in m^2/s^2. Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.params import Params
from slip_estimator.core.slip import speed_ratio
from slip_estimator.core.slip_model.aided_record import Anchor
from slip_estimator.core.slip_model.chain import RESOLVED_SIGMAS, SlipChain
from slip_estimator.core.slip_model.measurement import SlipMeasurement
from slip_estimator.core.slip_model.records import ModelSample, Resolution, SlipReading
from slip_estimator.core.slip_model.run_ahead import RunAheadCheck
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.slip_model.thresholds import predicted_coarse, wheel_change_mps


def settle(s: ModelSample, measurement: SlipMeasurement, chain: SlipChain,
           run_ahead: RunAheadCheck, previous: float | None, from_rest: bool,
           rest_offset_mps: float, spread_var_mps2: list[float], noise_var_mps2: float,
           p: Params) -> float:
    """The slip ``measurement``, finished at sample ``s``, settles on (see the module
    docstring). ``previous``: the hold before a change (None after a start);
    ``from_rest``: it started from a ZUPT-anchored stop, whose zero-velocity updates left
    ``rest_offset_mps`` (:meth:`~.stop_clock.StopClock.rest_offset_mps`); ``run_ahead``: the
    pitch, and the run-ahead held (told what is held now); ``spread_var_mps2``:
    the free residual's spread per step-test scale; ``noise_var_mps2``: the wheel/INS
    consistency noise."""
    w = s.w_mps
    unmeasured = measurement.anchor is None and not from_rest
    # A body-side reading still moving at the timeout is INS drift (SlipMeasurement.
    # drifting). Where the filter's own error model says its INS cannot place a slip
    # within the low class (coarse_ins), a reading is held to what that INS resolves: a
    # body-side change to the free INS's predicted drift over its span (shortest scale),
    # a start from rest to the speed's variance at the end of its measurement.
    drifting = measurement.drifting()
    body_span_s = measurement.body_span_s() if predicted_coarse(s.reading_var_mps2, w) else None
    anchor = measurement.anchor
    body_window_s = (anchor.t_ns * 1e-9, s.t_ns * 1e-9) \
        if anchor is not None and anchor.body else None
    body_speed_mps = measurement.body_speed_mps()  # (slip() ends the measurement)
    measured = measurement.slip(previous, p.slip_continuity_sigma, noise_var_mps2,
                                spread_var_mps2[-1], SCALES_S[-1])
    if drifting and previous is not None:
        return previous  # INS drift, not a change: the hold stays
    if previous is not None and body_reversed(body_speed_mps, w, spread_var_mps2[0]):
        return previous  # the INS, not the body: the hold stays
    reading = SlipReading(
        measured, previous, w, from_rest=from_rest, unmeasured=unmeasured,
        implausible_run_ahead=not from_rest and run_ahead.implausible(measured),
        pitch_rad=run_ahead.pitch_rad, pitch_std_rad=s.pitch_std_rad, body_span_s=body_span_s,
        start_speed_var_mps2=s.speed_var_mps2, body_window_s=body_window_s,
        rim_spun=anchor is not None and not anchor.body and rim_spun(anchor, measured, w,
                                                                     previous, spread_var_mps2),
        left_ground=None if from_rest else run_ahead.left,
        rest_offset_mps=rest_offset_mps if from_rest else 0.0)
    resolution = Resolution(spread_var_mps2[-1], SCALES_S[-1], wheel_change_mps(p, w))
    held = chain.settle(reading, resolution)
    run_ahead.held(held, None if from_rest else previous, chain.baseline, measured)
    return held


def body_reversed(body_speed_mps: float | None, w: float, spread_var_1s_mps2: float) -> bool:
    """A body-side measurement's mean speed ``body_speed_mps`` (None: not body-side) puts the
    body against wheels driving at rim speed ``w`` by more than the INS resolves over its
    shortest scale (``RESOLVED_SIGMAS`` of the 1-s spread ``spread_var_1s_mps2``). Wheels held
    at their rate do not drive a body backwards on ground a rover drives: that reading is the
    free INS, whose clamped slip of 1 would otherwise hold "extreme" (and from a hold of 1
    confirm it). On the 30-Hz consumer robot (``skid_steer_30hz`` seed 10 at 320-325 s) the
    alarm's take-back left a tilt 1.5-3.3 deg nose-up of the truth (0.4-1.0 deg), which the
    free INS turned into 0.26-0.56 m/s^2 of deceleration: it read the body at -0.3 to -0.4
    m/s, truth 0.65-1.02, over 1-s spreads of 0.049-0.054 m/s, and s = 1 was held 25 s (the
    odometry guard took it as resolved from the rim: 27.5 m final error, wheels + gyro 17.8).
    A stuck body (s = 1) reads within the spread of zero and is kept."""
    if body_speed_mps is None:
        return False
    return body_speed_mps * math.copysign(1.0, w) < -RESOLVED_SIGMAS * math.sqrt(
        spread_var_1s_mps2)


def rim_spun(anchor: Anchor, measured: float, w: float, previous: float | None,
             spread_var_mps2: list[float]) -> bool:
    """A wheel-side change from ``anchor`` read as ``measured`` at rim speed ``w`` (the hold
    before it ``previous``) is the wheels': the rim stepped by more than the INS misses over
    its shortest scale (``RESOLVED_SIGMAS`` of the 1-s spread ``spread_var_mps2[0]``) and the
    body's speed change differs from that step by as much (the wheels spun up or gripped
    again; the INS resolved it). A rim held steady while the slip moved is not: there the INS
    alone read the change."""
    g_before = speed_ratio(previous) if previous is not None else 0.0
    if g_before <= 0.0:
        return False
    resolved_mps = RESOLVED_SIGMAS * math.sqrt(spread_var_mps2[0])
    rim_step = w - anchor.z_mps / g_before
    body_step = speed_ratio(measured) * w - anchor.z_mps
    return abs(rim_step) > resolved_mps and abs(rim_step - body_step) > resolved_mps
