"""Odometry that does no harm: the published track falls back to wheels + gyro where the IMU
cannot resolve slip.

The fused forward speed differs from the rim speed only by the slip the INS reads. A slip
reading is worth more than the wheels only where the INS's speed error is small against the
slip classes. Where that error exceeds the fraction of the rim speed within which a slip can
be placed in the low class (:func:`~slip_estimator.core.slip_model.chain.coarse_ins`, the slip
model's own "coarse INS" test), a medium or extreme reading is as likely the INS's error as the
ground's slip, and following it costs the slip times the distance: on a vibrating 30-Hz
consumer IMU a false body-side alarm held the INS at 0 m/s for 180 s while the wheels read
1 m/s. There the published position advances as wheels + gyro: the rim speed along the fused
attitude's x axis (the fused heading and slope), from where the published track was; elsewhere
by the fused position's increments. The track is continuous either way (no jump at a switch).
A fallback that lasted a measuring span holds through a stop (the wheels' zero speed): the
stop's zero-velocity aid corrects the fused position for the INS's speed error while the track
followed the wheels. For the same reason, where such a fallback ends the fused position forgets
its cross-track error's correlation with the INS's other errors: the fused track then moves
sideways only for errors built after it. The published track came along the fused heading at
the rim speed, so it shares the aided INS's along-track error (the rim speed the aid gave it:
forgetting that correlation too cost `skid_steer_30hz` seed 0 0.45 -> 1.11 m, kept 0.55), but
not the INS's sideways position error, which the later speed updates would otherwise correct
in the published track (seed 2: 1.2 m sideways within 0.4 s, 2 s after a fallback ended).

The INS's speed error is the IMU's own measured error over a measuring span: the slip model's
learned spread of the free residual's change (:attr:`SlipModel.spread_var`) at its longest
scale, or its 1-s spread carried to that scale as a random walk, if larger (it is learned
sooner); with the held level's chain variance added (the changes the INS alone read since
the last anchor, :func:`~slip_estimator.core.slip_model.hold_variance.guard_var_mps2`): a
hold chained on several changes is placed no better than their summed spread, unless it puts
the body beyond ``RESOLVED_SIGMAS`` of the INS's spread from the rim speed. A change where the
rim stepped and the body did not follow (the wheels spun up or gripped again) is the wheels',
not the INS's, and adds nothing: a rim spinning up at a steady IMU is not published as the
fallback unless the INS alone is coarse. One exception keeps a coarse INS: a slip measured
from rest (on a stop's zero velocity, no change chained to it since) that puts the body's
speed beyond ``slip_change_sigma`` of that error from the rim speed: wheels spinning on a body
that stayed stuck, which the free INS sees from a ZUPT far better than over a running
measuring span. A hold chained after a start in motion (no stop measured the ground: the
chain's baseline is assumed) and moved off the assumed slip by changes the INS alone read adds
the assumption's variance (``ASSUMED_SLIP_STD`` of the rim speed) to those changes'
(:func:`~slip_estimator.core.slip_model.hold_variance.assumed_hold`), and such a fallback is
named ``assumed_hold`` in /diagnostics: on ``skid_steer_30hz`` seed 3 the fused track followed
two of them (0.33 kept after its sand patch ended, -0.14 read at a patch's end, on ground of
0.07) and ended 14.11 m off against the wheels + gyro's 9.75 (9.39 with the rule).

A slip change's anchor (the ungated forward-speed update at a change's onset) moves the fused
position through its correlation with the speed it resets: on the 30-Hz consumer robot by
0.3-2.2 m, mostly sideways, in one sample, for speed corrections of 0.01-0.3 m/s
(``skid_steer_30hz`` seed 16 at 121.9 s: 2.2 m sideways within 0.1 s, away from the truth;
about as many such moves went towards the truth as away). Where the INS's speed error at
the last verdict exceeds ``ASSUMED_SLIP_STD`` of the rim speed (it places a slip no better than
an assumed one) the published track does not take that move (:meth:`OdometryGuard.
change_anchored`): seeds 0-19 worse than wheels + gyro 7 -> 5, their shortfall 5.1 -> 3.5 m,
seed 16 12.76 -> 9.57 m; one right move lost (seed 3 at 201 s, after 60 s of a wrong hold
followed: 9.39 -> 10.79 m). Settled slips' anchors keep theirs (they remove the free run's
drift: taking every anchor's out gave seeds 4 / 9 / 19 19.78 / 6.89 / 15.86 m against
19.06 / 6.57 / 15.10, and ungated the tactical drive 0.10 -> 0.15 m).

Not resolved here (measured): the first tens of seconds after an in-motion start on a
consumer IMU, before the spread is learned (its prior is the wheel aid's noise): the INS's
reading is followed there. The fallback follows the rim speed, so it follows a wheel-side
slip it cannot resolve; it is taken only where a slip cannot be placed at all.

Only the standard library and numpy are used.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from slip_estimator.core.slip import speed_ratio
from slip_estimator.core.slip_model.chain import ASSUMED_SLIP_STD, coarse_ins
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.types import OdometryEstimate, SlipEstimate
from slip_estimator.core.wheel_odometry import SPEED_STD_FRACTION


def ins_speed_error_var(spread_var_mps2: list[float], scales_s: tuple[float, ...]) -> float:
    """Variance of the INS's forward-speed error over a measuring span, m^2/s^2: the learned
    spread at the longest scale, or a shorter scale's carried to it as a random walk
    (variance proportional to time), whichever is larger."""
    longest = scales_s[-1]
    return max(v * longest / s for v, s in zip(spread_var_mps2, scales_s))


def x_axis_odom(q_wxyz: np.ndarray) -> tuple[float, float, float]:
    """The base_link x axis in odom of the orientation ``q_wxyz`` (first DCM column)."""
    w, x, y, z = q_wxyz.tolist()
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))


@dataclass(frozen=True)
class GuardDecision:
    """The guard's verdict at one wheel sample."""

    moving: bool
    """the wheels move and the slip is known (the share of fallback counts these)"""
    fallback: bool
    """True: the published track advances as wheels + gyro"""
    rim_speed_mps: float
    """the speed the fallback advances at: the rim speed, through the ground's slip where one
    was measured from rest, m/s"""
    ins_error_mps: float
    """the INS's forward-speed error the verdict rests on (:func:`ins_speed_error_var`)"""
    rim_steady: bool = True
    """the rim speed moved little since the last wheel sample (not speeding up or braking)"""
    still: bool = False
    """the wheels are stopped or stopping (slip class 'none'): a fallback under way holds
    (:meth:`OdometryGuard.wheel`)"""
    stamp_ns: int = 0
    """the wheel sample's time, ns"""
    assumed_hold: bool = False
    """the INS error counts an assumed slip's: the held slip departs from a slip nothing
    measured by changes the INS alone read
    (:func:`~slip_estimator.core.slip_model.hold_variance.assumed_hold`)"""

    @property
    def reason(self) -> str:
        """Why the published track advances as wheels + gyro ('none' where it does not):
        'held_through_stop', 'assumed_hold' or 'coarse_ins'."""
        if not self.fallback:
            return 'none'
        if self.still:
            return 'held_through_stop'
        return 'assumed_hold' if self.assumed_hold else 'coarse_ins'


def decide(est: SlipEstimate, ins_error_var_mps2: float, anchored: bool,
           resolving_sigmas: float, held_slip: float | None = None,
           rim_steady: bool = True, assumed_hold: bool = False) -> GuardDecision:
    """Fall back where the wheels move (a known slip class above 'none') and the INS's speed
    error (variance ``ins_error_var_mps2``) is too coarse to place a slip in the low class;
    not while the slip is unknown (the rim speed then re-anchors the INS itself), and not
    where the slip was measured from rest (``anchored``: on a stop's zero velocity, where the
    free INS is far better than its error over a measuring span) and the INS reads the body's
    speed beyond ``resolving_sigmas`` of that error from the rim speed: wheels spinning on a
    body that stayed stuck. The fallback carries ``held_slip``, the ground's slip measured
    from rest (None: the raw rim speed): on the real test17run the raw rim speed read the body
    0.045 m/s RMS off against the fused 0.039, as its ground slips by about 0.05.
    ``rim_steady``: the rim speed moved little since the last sample (see
    :meth:`OdometryGuard.publish`); ``assumed_hold``: ``ins_error_var_mps2`` counts an assumed
    slip's variance (:func:`~slip_estimator.core.slip_model.hold_variance.assumed_hold`),
    named as the fallback's reason."""
    w = est.wheel_speed_mps
    speed = w if held_slip is None else w * speed_ratio(held_slip)
    err = math.sqrt(max(ins_error_var_mps2, 0.0))
    moving = est.slip_class > 0 and math.isfinite(est.slip_ratio)
    resolved = anchored and abs(est.body_speed_mps - w) > resolving_sigmas * err
    return GuardDecision(moving, moving and coarse_ins(ins_error_var_mps2, w) and not resolved,
                         speed, err, rim_steady, est.slip_class == 0, est.stamp_ns,
                         assumed_hold)


class OdometryGuard:
    """The published track (see the module docstring): :meth:`wheel` takes each evaluated
    wheel sample's verdict, :meth:`publish` turns the fused odometry into the published one."""

    def __init__(self) -> None:
        self.decision: GuardDecision | None = None
        self._offset_m = np.zeros(3)  # published minus fused position
        self._var_m2 = 0.0  # variance the fallback added to the position
        self._last: tuple[int, np.ndarray] | None = None  # (stamp, fused position) published
        self.samples = {'moving': 0, 'fallback': 0}
        self._since_ns: int | None = None  # when the fallback under way began
        self._moved_m = np.zeros(3)  # a change anchor's position move, not yet published

    def change_anchored(self, moved_o_m: np.ndarray) -> None:
        """A slip change's anchor (the ungated speed update at a change's onset) moved the fused
        position by ``moved_o_m`` (odom axes, m). Where the INS's speed error at the last
        verdict exceeds ``ASSUMED_SLIP_STD`` of the rim speed (it places a slip no better than
        an assumed one) the published track does not take that move: it is the position's
        correlation with the speed the anchor resets, whose error such an INS cannot tell
        from the slip change it reads (see the module docstring)."""
        d = self.decision
        if d is not None and d.ins_error_mps > ASSUMED_SLIP_STD * abs(d.rim_speed_mps):
            self._moved_m = self._moved_m + moved_o_m

    def wheel(self, decision: GuardDecision) -> bool:
        """The verdict at the latest evaluated wheel sample (holds until the next). A fallback
        under way holds through still wheels: the stop's zero-velocity aid corrects the fused
        position for the INS's speed error over the fallback, which the published track never
        had (a consumer no-slip drive's track jumped 0.17 m at rest, 0.09 m away from wheels +
        gyro's end; real s5t1 final error 3.43 -> 3.06 m). Only a fallback that lasted the
        measuring span its INS error refers to (``SCALES_S[-1]``): one shorter is the rim
        decelerating into the stop (under 15 % of a slowing rim speed the error is always
        coarse), not the INS, and there the zero-velocity aid corrects a good INS (a tactical
        drive's fallbacks began at 0.07-0.2 m/s for 0.2-0.7 s; holding them ended it 0.97 m
        off, 0.11 m without).

        Returns True where a fallback that lasted that span ends here: the fused position's
        cross-track error is then the INS's over the fallback, which the published track (on
        the wheels) never had, and its correlation with the INS's other errors is to be
        forgotten (:meth:`ErrorStateFilter.decorrelate_cross_track`; see the module
        docstring)."""
        lasted = self.fallback and self._since_ns is not None and \
            decision.stamp_ns - self._since_ns >= SCALES_S[-1] * 1e9
        if decision.still and lasted:
            decision = replace(decision, fallback=True)
        elif decision.fallback and not self.fallback:
            self._since_ns = decision.stamp_ns
        ended = lasted and not decision.fallback
        self.decision = decision
        if decision.moving:
            self.samples['moving'] += 1
            self.samples['fallback'] += decision.fallback
        return ended

    @property
    def fallback(self) -> bool:
        """True while the published track advances as wheels + gyro."""
        return self.decision is not None and self.decision.fallback

    def publish(self, odo: OdometryEstimate) -> OdometryEstimate:
        """The published odometry at ``odo.stamp_ns`` from the fused ``odo``: its position
        advanced since the last call by the fused increment, or in fallback by the rim speed
        along the fused x axis (then the linear twist is that speed, forward, where the rim
        speed is steady).

        The rim speed is a count difference: the distance of its interval, stamped at its end
        and arriving late. Summed, it is the distance travelled, so the position advances by
        it through starts and stops; but while it changes (speeding up, braking) it lags the
        body's speed by a sample interval or more, and the fused speed, good over the tenths
        of a second it takes (the slip model aids no such sample), is the twist published.
        On the real test17run the rim speed read starts and stops up to 0.2 m/s behind RTK
        where the fused speed was within 0.1: forward-speed RMSE 0.0403 -> 0.0347 m/s."""
        last, self._last = self._last, (odo.stamp_ns, odo.p_ob_o)
        d = self.decision
        moved, self._moved_m = self._moved_m, np.zeros(3)
        if d is None or not d.fallback:
            self._offset_m = self._offset_m - moved  # (in fallback no fused step is taken)
            if self._var_m2 == 0.0 and not self._offset_m.any():
                return odo  # never fell back: the fused solution itself
            return self._shifted(odo)
        if last is not None and odo.stamp_ns > last[0]:
            dt = (odo.stamp_ns - last[0]) * 1e-9
            step_m = d.rim_speed_mps * dt
            fused_step = odo.p_ob_o - last[1]
            self._offset_m = self._offset_m + np.array(x_axis_odom(odo.q_ob_wxyz)) * step_m \
                - fused_step
            self._var_m2 += (SPEED_STD_FRACTION * step_m) ** 2
        out = self._shifted(odo)
        if not d.rim_steady:
            return out
        twist_cov = out.twist_covariance.copy()
        twist_cov[0, :] = twist_cov[:, 0] = 0.0
        twist_cov[0, 0] = (SPEED_STD_FRACTION * d.rim_speed_mps) ** 2  # the wheels' slip
        return replace(out, v_ob_b=np.array((d.rim_speed_mps, 0.0, 0.0)),
                       twist_covariance=twist_cov)

    def _shifted(self, odo: OdometryEstimate) -> OdometryEstimate:
        pose_cov = odo.pose_covariance.copy()
        pose_cov[0, 0] += self._var_m2
        pose_cov[1, 1] += self._var_m2
        return replace(odo, p_ob_o=odo.p_ob_o + self._offset_m, pose_covariance=pose_cov)

    def figures(self) -> tuple[dict, str | None]:
        """Values for /diagnostics and, while the fallback is taken, a note naming it."""
        d = self.decision
        n = self.samples['moving']
        values = {'odometry_fallback': self.fallback,
                  'odometry_fallback_share': self.samples['fallback'] / n if n else 0.0,
                  'odometry_ins_speed_error_mps': d.ins_error_mps if d else math.nan,
                  'odometry_fallback_reason': d.reason if d else 'none'}
        note = None
        if d is not None and d.reason == 'assumed_hold':
            note = ('odometry: wheels + gyro fallback (the held slip departs from a slip no stop '
                    'measured by changes the INS alone read: placed within %.2f m/s over %.2f '
                    'm/s of rim speed, slip not resolvable, position advanced at the rim speed '
                    'along the fused heading)' % (d.ins_error_mps, abs(d.rim_speed_mps)))
        elif d is not None and d.fallback and d.still:
            note = ('odometry: wheels + gyro fallback held through a stop (the wheels are '
                    'still; the fused position is corrected at rest for a speed the track '
                    'did not follow)')
        elif d is not None and d.fallback:
            note = ('odometry: wheels + gyro fallback (INS speed error %.2f m/s over %.2f m/s '
                    'of rim speed: slip not resolvable, position advanced at the rim speed '
                    'along the fused heading)' % (d.ins_error_mps, abs(d.rim_speed_mps)))
        return values, note
