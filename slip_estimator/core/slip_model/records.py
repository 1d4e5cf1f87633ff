"""The records the slip model hands its parts: one wheel sample's inputs (:class:`ModelSample`)
and a detected change (:class:`Change`). Speeds are forward speeds of the base point along the
body's x axis, m/s. Only the standard library is used."""
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
