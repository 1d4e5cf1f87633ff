"""What the slip model tells the filter to do with one wheel sample's forward speed
(:class:`AidDecision`, made by :mod:`slip_estimator.core.slip_model.model`, applied by
:mod:`slip_estimator.core.wheel_update`). Only the standard library is used."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class AidDecision:
    """What the filter should do with this wheel sample's forward speed.

    z_mps : forward speed of the base point to update towards, m/s.
    var_mps2 : its variance, m^2/s^2.
    anchor : True for a re-anchor (a known jump of the INS error: not gated), False for the
        ordinary aid (gated like every pseudo-measurement).
    held_slip : the slip just settled on (for the residual monitor), or None.
    repair : True when the update repairs INS damage (after an IMU gap) rather than holding a
        slip: the free speed then keeps its effect (the step test must see the repaired INS).
    take_back_since_ns : a change began at this wheel time: the tilt and accelerometer-bias
        corrections the aid made since were made under the old slip and are taken back first
        (:mod:`slip_estimator.core.history`); None: keep them.
    update : False for a take-back alone (a wheel-side change: the measurement that follows
        starts from the INS as it is); ``z_mps`` and ``var_mps2`` are then unused.
    """

    z_mps: float
    var_mps2: float
    anchor: bool = False
    held_slip: float | None = None
    repair: bool = False
    take_back_since_ns: int | None = None
    update: bool = True
