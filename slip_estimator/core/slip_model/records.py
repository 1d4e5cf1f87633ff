"""The records the slip model hands its parts: one wheel sample's inputs (:class:`ModelSample`),
a detected change (:class:`Change`), and a finished measurement as the chain judges it
(:class:`SlipReading`, against what the INS and the wheels resolve: :class:`Resolution`).
Speeds are forward speeds of the base point along the body's x axis, m/s; variances of them
m^2/s^2. Only the standard library is used."""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.aided_record import Anchor


@dataclass(frozen=True, slots=True)
class ModelSample:
    """One wheel sample as the slip model reads it (:meth:`~.model.SlipModel.step`)."""

    t_ns: int
    """the wheel sample's stamp, ns"""
    w_mps: float
    """rim speed ``r omega``"""
    v_mps: float
    """the filter's forward speed at ``t_ns``"""
    v_free_mps: float
    """the free forward speed: the filter's, less everything the wheel aid did to it"""
    aid_accel_mps2: float
    """the along-track acceleration the aid's corrections cause at ``t_ns``, m/s^2: the free
    speed's change from a past sample plus that sample's aid acceleration times the elapsed
    time is the speed change the INS saw without the aid corrections made in between"""
    pitch_std_rad: float
    """the filter's tilt 1-sigma"""
    reading_var_mps2: tuple[float, ...]
    """the filter's prediction of its free INS's speed-change variance per step-test scale,
    m^2/s^2 (empty: none)"""
    speed_var_mps2: float
    """the filter's forward-speed variance, m^2/s^2"""


class Change(NamedTuple):
    """A slip change one side detected: the slip model starts measuring from ``anchor``."""

    side: str
    """'wheel' or 'body'"""
    anchor: Anchor | None
    """what the measurement continues from (None: no aided sample before it)"""
    decision: AidDecision | None
    """what the filter is told at once (a re-anchor, a take-back), or None"""


@dataclass(frozen=True, slots=True)
class SlipReading:
    """A finished slip measurement as the chain judges it (:meth:`~.chain.SlipChain.settle`),
    built where it ends (:func:`~.settling.settle`)."""

    slip: float
    """the slip measured"""
    previous: float | None
    """the hold before the change (None after a start)"""
    w_mps: float
    """rim speed ``r omega`` at its end"""
    from_rest: bool = False
    """the measurement started from a ZUPT-anchored stop (a new baseline)"""
    unmeasured: bool = False
    """the INS was re-initialised from the rim (zero slip assumed)"""
    implausible_run_ahead: bool = False
    """a run-ahead no slope explains was measured (:mod:`.run_ahead`)"""
    pitch_rad: float = 0.0
    """the pitch it was measured at"""
    pitch_std_rad: float = 0.0
    """the filter's tilt 1-sigma"""
    body_span_s: float | None = None
    """for a body-side change, the time its free INS integrated over, s"""
    start_speed_var_mps2: float = 0.0
    """for a start from rest, the filter's forward-speed variance at the end of its
    measurement: too coarse to place the slip within the low class
    (:func:`~.chain.coarse_ins`), zero is the baseline; within ``ASSUMED_SLIP_STD`` of the rim
    speed, the baseline is also the resolved ``ground``"""
    body_window_s: tuple[float, float] | None = None
    """for any body-side change, (its continuity anchor, its end), s"""
    rim_spun: bool = False
    """the rim stepped beyond what the INS misses and the body did not follow
    (:func:`~.settling.rim_spun`): a new level held adds nothing to ``ins_chain_var``"""
    left_ground: float | None = None
    """the ground's slip a run-ahead read nose down left, while the ground ahead is still
    nose-down (:attr:`~.run_ahead.RunAheadCheck.left`): a rise is its return"""
    rest_offset_mps: float = 0.0
    """for a start from rest, the forward speed the rest's zero-velocity updates left
    (:meth:`~.stop_clock.StopClock.rest_offset_mps`, 0 where none): the start's free INS
    integrates that acceleration, and its speed errs to the offset's side by an amount nothing
    measured; the baseline before it, where it lies on the side the error hides, is held"""


@dataclass(frozen=True, slots=True)
class Resolution:
    """What a speed difference at the reading's rim speed must beat to be a change: the INS's
    learned spread over a measuring span and the wheel-side threshold."""

    spread_var_mps2: float
    """the INS's learned speed-change variance over a measuring span"""
    spread_span_s: float
    """the span ``spread_var_mps2`` refers to, s"""
    wheel_change_mps: float
    """the wheel-side change threshold at the rim speed"""
