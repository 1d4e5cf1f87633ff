"""Wheel-side change detection while a slip is held: the rim speed moved and the body did not
follow (or the reverse), so the held model's speed ``z = g(s_hold) w`` departs from the
filter's forward speed ``v`` beyond :func:`~.thresholds.wheel_change_mps` for
``WHEEL_CHANGE_S``. The change's measurement continues from the aided samples before the rim
began to move (:meth:`~.aided_record.AidedRecord.before` its onset,
:meth:`~.rim_memory.RimMemory.onset_ns`). Speeds in m/s. Only the standard library is used.
"""
from __future__ import annotations

import math

from slip_estimator.core.params import Params
from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.aided_record import AidedRecord, Anchor
from slip_estimator.core.slip_model.chain import coarse_ins
from slip_estimator.core.slip_model.records import Change, ModelSample
from slip_estimator.core.slip_model.rim_memory import RimMemory
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.slip_model.thresholds import predicted_coarse, wheel_change_mps

_NS = 1_000_000_000
WHEEL_CHANGE_S = 0.15
"""A wheel-side discrepancy that lasts this long is a change, not a noisy sample or an encoder
glitch: the third consecutive sample at 10 Hz, the ninth at 50 Hz (a count of samples would
take a 0.06-s glitch for a change at 50 Hz)."""
WHEEL_TAKE_BACK_S = SCALES_S[0]
"""What the aid taught in this last stretch before a wheel-side change is taken back: a rim
speed that moves (wheels spinning up, or a new commanded rate while the body slows in sand)
was aided towards the old slip until the discrepancy lasted ``WHEEL_CHANGE_S``; on the
50-Hz robot that taught 0.09 m/s^2 in 0.5 s and the body's half of the change was lost."""


class WheelSide:
    """The wheel-side discrepancy under way (see the module docstring)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.clear()

    def clear(self) -> None:
        """No discrepancy under way (a stop, a change)."""
        self._since_ns: int | None = None  # a wheel-side discrepancy since then

    def check(self, s: ModelSample, g_hold: float, rim: RimMemory, aided: AidedRecord,
              noise_var_mps2: float, spread_var_mps2: list[float],
              baseline: float | None) -> tuple[bool, Change | None]:
        """Whether sample ``s`` shows a wheel-side discrepancy at the held speed ratio
        ``g_hold``, and the change once it has lasted ``WHEEL_CHANGE_S`` (else None).
        ``noise_var_mps2``: the wheel/INS consistency noise; ``spread_var_mps2``: the free
        residual's spread per step-test scale; ``baseline``: the ground's slip (None before
        a stop measured it: then the aid's corrections are kept)."""
        p = self.params
        t_ns, w = s.t_ns, s.w_mps
        z = g_hold * w
        # The rim must have moved by at least half the discrepancy it is to explain (encoder
        # noise moves it too; a body-side change leaves it where it was).
        gap = abs(z - s.v_mps)
        # On an INS the filter knows too coarse (coarse_ins), by more than the wheel/INS
        # consistency noise explains too (a consumer IMU's aided speed scatters by 0.13 m/s:
        # a rim changing speed showed 31 "changes" per drive on ground that never slipped,
        # each leaving the INS free for a second).
        threshold = wheel_change_mps(p, w)
        if predicted_coarse(s.reading_var_mps2, w):
            threshold = max(threshold, p.slip_change_sigma * math.sqrt(noise_var_mps2))
        if not (gap > threshold and rim.moved_mps(w) * g_hold > 0.5 * gap):
            self._since_ns = None
            return False, None
        if self._since_ns is None:
            self._since_ns = t_ns
        if t_ns - self._since_ns < int(WHEEL_CHANGE_S * _NS):
            return True, None
        # Continuity from before the rim began to move: on a ramp of the rim the aid
        # pulled the INS along with the old slip until the discrepancy showed.
        onset_ns = rim.onset_ns(w)
        m = aided.before(onset_ns)
        coarse = coarse_ins(spread_var_mps2[-1], w)  # (a consumer IMU: aided speed)
        anchor = None if m is None else Anchor(
            m.z_mps, m.v_mps if coarse else m.v_free_mps, False,
            None if coarse else m.aid_accel_mps2, m.t_ns)
        take_back = None
        if baseline is not None:  # as for the body side (:mod:`.body_side`)
            take_back = AidDecision(z, 0.0, update=False,
                                    take_back_since_ns=t_ns - int(WHEEL_TAKE_BACK_S * _NS))
        return True, Change('wheel', anchor, take_back)
