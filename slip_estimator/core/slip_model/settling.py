"""The slip a finished measurement (:mod:`.measurement`) settles on: what it measured, held as
the chain decides (baseline, false alarm, run-ahead, the rest offset: :class:`~.chain.SlipChain`),
with what the measurement itself knows of it: a body-side reading still drifting at its
timeout, the span its free INS integrated, and whether a wheel-side change was the wheels'
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
    measured = measurement.slip(previous, p.slip_continuity_sigma, noise_var_mps2,
                                spread_var_mps2[-1], SCALES_S[-1])
    if drifting and previous is not None:
        return previous  # INS drift, not a change: the hold stays
    reading = SlipReading(
        measured, previous, w, from_rest=from_rest, unmeasured=unmeasured,
        implausible_run_ahead=not from_rest and run_ahead.implausible(measured),
        pitch_rad=run_ahead.pitch_rad, pitch_std_rad=s.pitch_std_rad, body_span_s=body_span_s,
        start_speed_var_mps2=s.speed_var_mps2, body_window_s=body_window_s,
        rim_spun=anchor is not None and not anchor.body and rim_spun(anchor, measured, w,
                                                                     previous, spread_var_mps2),
        rest_offset_mps=rest_offset_mps if from_rest else 0.0)
    resolution = Resolution(spread_var_mps2[-1], SCALES_S[-1], wheel_change_mps(p, w))
    held = chain.settle(reading, resolution)
    run_ahead.held(held, None if from_rest else previous, chain.baseline)
    return held


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
