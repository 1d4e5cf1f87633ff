"""Body-side change detection while a slip is held: a step of the free residual
``v_free - g(s_hold) w`` in the multi-scale step test (:mod:`.step_test`), anchored on velocity
continuity from the aided samples before its onset (:meth:`~.aided_record.AidedRecord.before`),
and quiet for ``QUIET_AFTER_GAP_S`` after an IMU gap or a run-ahead's return. Speeds in m/s.

A body-side change is anchored at its alarm on velocity continuity (the held model's speed at
the onset plus the INS speed change since) by an update of the aid's variance, which moves the
velocity as far as the filter's own velocity variance lets it: 78 % of the way (median) on the
real test17run IMU, 10-24 % on the simulated ones (a full reset measured worse on the real log,
docs/limits.md). Until the alarm the aid pulled the INS towards the old slip, and the filter
took the pull for tilt and accelerometer bias: the alarm takes those corrections back
(``AidDecision.take_back_since_ns``), or the free INS measures the change short (patch entries
read 30-40 % low). Not after a start in motion: there the aid is still levelling the INS (a
30-Hz consumer IMU lost 1-2.5 deg). Nor on an INS whose free speed scatters beyond
``COARSE_CONTINUITY_FRACTION`` of the rim speed: there the aided speed carries the continuity,
as on the wheel side (the free speed of the 30-Hz consumer robot ran 2-6 m/s from the body over
the anchor's span). Only the standard library is used.
"""
from __future__ import annotations

from slip_estimator.core.params import Params
from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.aided_record import AidedRecord, Anchor
from slip_estimator.core.slip_model.chain import COARSE_CONTINUITY_FRACTION, coarse_ins
from slip_estimator.core.slip_model.records import Change, ModelSample
from slip_estimator.core.slip_model.step_test import SCALES_S, StepTest
from slip_estimator.core.slip_model.thresholds import (body_change_sigmas, spread_var_mps2,
                                                       wheel_change_mps)

_NS = 1_000_000_000
QUIET_AFTER_GAP_S = 4.0
"""After an IMU gap (or a run-ahead's return) the filter settles its attitude and biases: no
body-side step test."""


class BodySide:
    """The step test's alarms as changes, and the quiet window after an IMU gap or a
    run-ahead's return (see the module docstring)."""

    def __init__(self, params: Params) -> None:
        self.params = params
        self.clear()

    def clear(self) -> None:
        """No gap to re-anchor after, no quiet window (a stop, a re-initialised velocity)."""
        self._reanchor, self._quiet_until_ns = False, 0

    def interrupt(self) -> None:
        """The INS went through a gap: what it integrated across it is not the body's."""
        self._reanchor = True

    def gap_closed(self, t_ns: int) -> bool:
        """True at the first tracked sample after an IMU gap (the velocity is re-anchored on
        the held slip there), which opens the quiet window."""
        if not self._reanchor:
            return False
        self._reanchor = False
        self._quiet_until_ns = t_ns + int(QUIET_AFTER_GAP_S * _NS)
        return True

    def returned(self, t_ns: int) -> None:
        """A held run-ahead is over and the velocity was anchored on the ground's slip, a
        speed the INS did not measure: quiet as after a gap while the filter settles its tilt
        to it (measured_no_slip seed 2: a step read 3.2 s after such a return, +0.4 on a
        ground that never slips)."""
        self._quiet_until_ns = t_ns + int(QUIET_AFTER_GAP_S * _NS)

    def quiet(self, t_ns: int) -> bool:
        """Within the quiet window after a gap: no body-side change, and the aid repairs."""
        return t_ns < self._quiet_until_ns

    def check(self, s: ModelSample, g_hold: float, turning: bool, step_test: StepTest,
              aided: AidedRecord, baseline: float | None) -> Change | None:
        """Feed ``step_test`` the free residual of sample ``s`` at the held speed ratio
        ``g_hold``; the change at its alarm, anchored on the ``aided`` samples before the
        onset, else None. ``baseline``: the ground's slip (None before a stop measured it,
        or while it is only assumed and no start resolved the ground: then the aid's
        corrections are kept)."""
        p = self.params
        t_ns, w, v, v_free = s.t_ns, s.w_mps, s.v_mps, s.v_free_mps
        z = g_hold * w
        k = body_change_sigmas(p, turning)
        onset_ns = step_test.add(t_ns, v_free - z, s.aid_accel_mps2,
                                 wheel_change_mps(p, w), k, s.reading_var_mps2)
        if onset_ns is None or self.quiet(t_ns):
            return None
        # Continuity from before the longest scale: a transition slower than the scale
        # that fired began earlier, while the aid still held the old slip.
        onset_ns = min(onset_ns, t_ns - int(SCALES_S[-1] * _NS))
        before = aided.before(onset_ns)
        if before is None:
            return None
        # Once a stop measured the ground, the aid's tilt and bias corrections since
        # the onset are the old slip's and are taken back; after a start in motion
        # they are still levelling the INS (a 30-Hz consumer IMU lost 1-2.5 deg), as
        # on an INS too coarse for its free speed to carry the continuity.
        spread_var = spread_var_mps2(step_test.spread_var, s.reading_var_mps2)
        coarse = coarse_ins(spread_var[-1], w, COARSE_CONTINUITY_FRACTION)
        take_back = before.last_ns if baseline is not None and not coarse else None
        if coarse:
            # As on the wheel side: the aided speed carries the continuity (the free
            # speed of a 30-Hz consumer IMU moved 2-6 m/s more than the body over
            # 2.75 s and its anchor reversed the body).
            return Change('body', Anchor(before.z_mps, before.v_mps, True, t_ns=before.t_ns),
                          AidDecision(before.z_mps + v - before.v_mps,
                                      p.wheel_aid_std_mps ** 2, anchor=True))
        # Re-anchor now on continuity (the aid had been pulling the INS back onto the
        # old slip): the held speed before the onset plus the free speed change since,
        # without the aid corrections made since the onset. The mean free speed is the
        # one at the window's mean time, with the aid's acceleration there (paired with
        # the window's end, the continuity was off by that acceleration times 0.25 s:
        # 0.04 m/s at 0.17 m/s^2).
        return Change('body', Anchor(before.z_mps, before.v_free_mps, True, t_ns=before.t_ns),
                      AidDecision(before.z_mps + v_free - before.v_free_mps
                                  + before.aid_accel_mps2 * (t_ns - before.t_ns) * 1e-9,
                                  p.wheel_aid_std_mps ** 2, anchor=True,
                                  take_back_since_ns=take_back))
