"""The odometry guard (core/odometry_guard.py): when the published track falls back to wheels +
gyro, and what it then publishes, in closed form; on a consumer-IMU drive, the fallback named
in the health report."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_estimator.core.odometry_guard import (GuardDecision, OdometryGuard, decide,
                                                ins_speed_error_var)
from slip_estimator.core.types import OdometryEstimate, SlipEstimate
from slip_estimator.core.wheel_odometry import SPEED_STD_FRACTION

NS = 1_000_000_000


def _slip(rim_mps: float, body_mps: float, slip_class: int = 1) -> SlipEstimate:
    s = 1.0 - body_mps / rim_mps if slip_class >= 0 else math.nan
    return SlipEstimate(0, s, 0.1, slip_class, body_mps, 0.1, rim_mps)


def _odometry(t_s: float, p_ob_o, yaw_rad: float) -> OdometryEstimate:
    q = np.array([math.cos(0.5 * yaw_rad), 0.0, 0.0, math.sin(0.5 * yaw_rad)])
    return OdometryEstimate(round(t_s * NS), np.array(p_ob_o, dtype=float), q,
                            np.array([0.3, 0.01, 0.0]), np.zeros(3), np.eye(6) * 1e-2,
                            np.eye(6) * 1e-3)


def test_ins_speed_error_is_the_longest_span_or_a_shorter_one_carried_to_it():
    """Random-walk scaling: 0.01 m^2/s^2 over 1 s is 0.025 over 2.5 s, above 0.02 learned
    there; below it (0.004 -> 0.01) the 2.5-s spread stands."""
    assert ins_speed_error_var([0.01, 0.02], (1.0, 2.5)) == pytest.approx(0.025)
    assert ins_speed_error_var([0.004, 0.02], (1.0, 2.5)) == pytest.approx(0.02)


def test_falls_back_only_where_a_slip_cannot_be_placed_in_the_low_class():
    """At 1 m/s the coarse-INS bound is 0.15 m/s (chain.coarse_ins): 0.16 falls back, 0.14
    does not; nor a stop, an unknown slip, or a slip measured from rest beyond 3.5 sigmas."""
    coarse, fine = 0.16 ** 2, 0.14 ** 2
    assert decide(_slip(1.0, 0.0, 4), coarse, False, 3.5).fallback
    assert not decide(_slip(1.0, 0.0, 4), fine, False, 3.5).fallback
    assert not decide(_slip(0.0 + 1e-9, 0.0, 0), coarse, False, 3.5).fallback  # at rest
    assert not decide(_slip(1.0, math.nan, -1), coarse, False, 3.5).fallback  # unknown
    # From rest: a stuck body (1.0 m/s from the rim > 3.5 * 0.16) is resolved; 0.2 m/s is not.
    assert not decide(_slip(1.0, 0.0, 4), coarse, True, 3.5).fallback
    assert decide(_slip(1.0, 0.8, 2), coarse, True, 3.5).fallback
    d = decide(_slip(1.0, 0.0, 4), coarse, False, 3.5)
    assert d == GuardDecision(True, True, 1.0, pytest.approx(0.16))


def test_the_fallback_carries_the_ground_slip_it_is_given():
    """With the ground's slip measured from rest (0.05, or a run-ahead of -0.05) the fallback
    advances at the rim speed through it: 0.95 and 1/0.95 m/s at 1 m/s; without, the rim."""
    coarse = 0.16 ** 2
    assert decide(_slip(1.0, 0.9), coarse, False, 3.5, 0.05).rim_speed_mps == \
        pytest.approx(0.95)
    assert decide(_slip(1.0, 0.9), coarse, False, 3.5, -0.05).rim_speed_mps == \
        pytest.approx(1.0 / 0.95)
    assert decide(_slip(1.0, 0.9), coarse, False, 3.5).rim_speed_mps == 1.0


def test_never_fallen_back_publishes_the_fused_solution_itself():
    guard = OdometryGuard()
    guard.wheel(decide(_slip(1.0, 0.98), 0.01 ** 2, False, 3.5))
    odo = _odometry(1.0, (3.0, 4.0, 0.5), 0.3)
    assert guard.publish(odo) is odo
    assert guard.figures() == ({'odometry_fallback': False, 'odometry_fallback_share': 0.0,
                                'odometry_ins_speed_error_mps': pytest.approx(0.01),
                                'odometry_fallback_reason': 'none'}, None)


def test_fallback_advances_at_the_rim_speed_along_the_heading_then_resumes_without_a_jump():
    """A fused track drifting east at 0.3 m/s while heading north (ENU yaw 90 deg), wheels at
    1 m/s: 2 s of fallback publish (0, 2, 0) with the forward speed 1 m/s and (0.1 * 1 m)^2
    per second on x and y; back on the fused track, its 1-m step east lands at (1, 2, 0)."""
    guard = OdometryGuard()
    guard.wheel(decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5))
    north = 0.5 * math.pi
    for t in (0.0, 1.0):
        guard.publish(_odometry(t, (0.3 * t, 0.0, 0.0), north))
    out = guard.publish(_odometry(2.0, (0.6, 0.0, 0.0), north))
    np.testing.assert_allclose(out.p_ob_o, (0.0, 2.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(out.v_ob_b, (1.0, 0.0, 0.0))
    assert out.twist_covariance[0, 0] == pytest.approx(SPEED_STD_FRACTION ** 2)
    assert out.pose_covariance[0, 0] == pytest.approx(1e-2 + 2 * SPEED_STD_FRACTION ** 2)
    values, note = guard.figures()
    assert values['odometry_fallback'] and values['odometry_fallback_share'] == 1.0
    assert note is not None and 'wheels + gyro fallback' in note
    guard.wheel(decide(_slip(1.0, 0.98), 0.01 ** 2, False, 3.5))
    out = guard.publish(_odometry(3.0, (1.6, 0.0, 0.0), 0.0))
    np.testing.assert_allclose(out.p_ob_o, (1.0, 2.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(out.v_ob_b, (0.3, 0.01, 0.0))  # the fused twist again
    assert guard.figures()[1] is None
    assert guard.figures()[0]['odometry_fallback_share'] == 0.5


def test_a_change_anchor_moves_the_published_track_only_where_the_ins_places_the_change():
    """At 1 m/s the bound is ASSUMED_SLIP_STD x rim = 0.1 m/s. INS error 0.12 m/s, fused (not
    coarse): the anchor's 1.5-m sideways move is not published, the fused steps after it are
    (1 m north lands 1 m north of the last published point); 0.05 m/s: it is published. In
    fallback the fused step is not taken at all, so the move is not subtracted twice."""
    north = 0.5 * math.pi
    for ins_error_mps, published_east_m in ((0.12, 0.0), (0.05, 1.5)):
        guard = OdometryGuard()
        guard.wheel(decide(_slip(1.0, 0.98), ins_error_mps ** 2, False, 3.5))
        guard.publish(_odometry(0.0, (0.0, 0.0, 0.0), north))
        guard.change_anchored(np.array((1.5, 0.0, 0.0)))
        out = guard.publish(_odometry(0.1, (1.5, 0.0, 0.0), north))
        np.testing.assert_allclose(out.p_ob_o, (published_east_m, 0.0, 0.0), atol=1e-12)
        out = guard.publish(_odometry(1.1, (1.5, 1.0, 0.0), north))
        np.testing.assert_allclose(out.p_ob_o, (published_east_m, 1.0, 0.0), atol=1e-12)
    guard = OdometryGuard()
    guard.wheel(decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5))  # fallback, rim 1 m/s
    guard.publish(_odometry(0.0, (0.0, 0.0, 0.0), north))
    guard.change_anchored(np.array((1.5, 0.0, 0.0)))
    out = guard.publish(_odometry(1.0, (1.5, 0.0, 0.0), north))
    np.testing.assert_allclose(out.p_ob_o, (0.0, 1.0, 0.0), atol=1e-12)


def test_a_changing_rim_advances_the_fallback_but_the_twist_is_the_fused_speed():
    """Braking from 1 m/s: the rim speed's count difference (0.8 m/s) still advances the
    track (1 s north: (0, 0.8, 0)), but it lags the body, so the fused twist (0.3 m/s) and
    its covariance are published; at a steady rim the rim speed is again the twist."""
    guard = OdometryGuard()
    guard.wheel(decide(_slip(0.8, 0.0, 4), 0.5 ** 2, False, 3.5, rim_steady=False))
    north = 0.5 * math.pi
    guard.publish(_odometry(0.0, (0.0, 0.0, 0.0), north))
    out = guard.publish(_odometry(1.0, (0.3, 0.0, 0.0), north))
    np.testing.assert_allclose(out.p_ob_o, (0.0, 0.8, 0.0), atol=1e-12)
    np.testing.assert_allclose(out.v_ob_b, (0.3, 0.01, 0.0))
    assert out.twist_covariance[0, 0] == pytest.approx(1e-3)
    assert guard.fallback and guard.figures()[0]['odometry_fallback_share'] == 1.0
    guard.wheel(decide(_slip(0.8, 0.0, 4), 0.5 ** 2, False, 3.5, rim_steady=True))
    out = guard.publish(_odometry(2.0, (0.6, 0.0, 0.0), north))
    np.testing.assert_allclose(out.p_ob_o, (0.0, 1.6, 0.0), atol=1e-12)
    np.testing.assert_allclose(out.v_ob_b, (0.8, 0.0, 0.0))


def test_a_fallback_of_a_measuring_span_holds_through_still_wheels():
    """In fallback at 1 m/s for 3 s (beyond the 2.5-s measuring span), then the wheels stop
    (class 'none'): the fused position jumps 0.2 m at rest (the stop's zero-velocity
    correction) and the published one stays at 3 m, named as held through a stop; a moving
    verdict on a fine INS ends the fallback, and the fused increments follow again. A
    fallback of 1 s (a rim slowing into the stop) does not hold, nor does a still verdict
    without a fallback before it. ``wheel`` says True only where a fallback of a span ends."""
    def still(t_s: float) -> GuardDecision:
        return decide(SlipEstimate(round(t_s * NS), 0.0, 0.1, 0, 0.0, 0.1, 0.0), 0.5 ** 2,
                      False, 3.5)
    guard = OdometryGuard()
    assert not guard.wheel(decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5))  # at t = 0
    guard.publish(_odometry(0.0, (0.0, 0.0, 0.0), 0.0))
    guard.publish(_odometry(3.0, (1.5, 0.0, 0.0), 0.0))
    assert still(3.0).still and not still(3.0).fallback
    assert not guard.wheel(still(3.0))
    out = guard.publish(_odometry(4.0, (1.7, 0.0, 0.0), 0.0))
    np.testing.assert_allclose(out.p_ob_o, (3.0, 0.0, 0.0), atol=1e-12)
    assert guard.fallback and 'held through a stop' in guard.figures()[1]
    fine = SlipEstimate(5 * NS, 0.02, 0.1, 1, 0.98, 0.1, 1.0)
    assert guard.wheel(decide(fine, 0.01 ** 2, False, 3.5))  # ended after 5 s: True
    out = guard.publish(_odometry(5.0, (2.7, 0.0, 0.0), 0.0))
    np.testing.assert_allclose(out.p_ob_o, (4.0, 0.0, 0.0), atol=1e-12)
    short = OdometryGuard()
    short.wheel(decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5))
    assert not short.wheel(still(1.0))  # ended, but short of a span: False
    assert not short.fallback
    fresh = OdometryGuard()
    fresh.wheel(still(3.0))
    odo = _odometry(1.0, (3.0, 4.0, 0.5), 0.3)
    assert not fresh.fallback and fresh.publish(odo) is odo


def test_fallback_through_a_quarter_circle_ends_at_radius_radius():
    """1 m/s at pi/20 rad/s for 10 s from the origin heading east (fused position frozen):
    a quarter circle of radius 20/pi m ends at (R, R), to the step's first-order error."""
    guard = OdometryGuard()
    guard.wheel(decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5))
    rate, dt = math.pi / 20.0, 1e-3
    out = None
    for k in range(10_001):
        out = guard.publish(_odometry(k * dt, (0.0, 0.0, 0.0), rate * k * dt))
    r = 20.0 / math.pi
    np.testing.assert_allclose(out.p_ob_o[:2], (r, r), atol=2e-3)


def test_a_consumer_imu_false_alarm_falls_back_and_is_named_in_the_health_report():
    """The 30-Hz vibrating consumer IMU over ground without slip (seed 1, 120 s): a false
    body-side alarm holds the INS near 0 m/s from about 68 s while the wheels read 1 m/s.
    The published forward speed is the wheels' there (the fused one reads about 0) and
    /diagnostics names the fallback."""
    from slip_estimator.effects import run_core
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.sim.robots import no_slip_robot
    from slip_estimator.streams import from_simulation

    scenario = no_slip_robot(1).scenario.replace(duration_s=120.0)
    r = simulate(scenario)
    p = sim_params(r)
    est, _, odo = run_core(p, from_simulation(r, p), odometry_every=3)
    late = odo[:, 0] > odo[0, 0] + 80 * NS
    assert np.mean(odo[late, 1]) > 0.6  # the published forward speed is the wheels'
    health = est.health()
    assert health.values['odometry_fallback'] is True
    assert 'odometry: wheels + gyro fallback' in health.message
    assert health.level < 2


def test_a_hold_on_an_assumed_slip_falls_back_and_is_named():
    """A start in motion assumes zero slip (the rim speed); a change the INS read from there
    (spread 0.05 m/s over a measuring span) to a hold of 0.3 at 0.4 m/s puts the body 0.12
    m/s from the rim, within 3.5 sigmas (0.175): the guard counts the assumption's 0.1 of the
    rim speed too, sqrt(0.05^2 + 0.04^2) = 0.064 m/s against the coarse-INS bound of 0.06
    (0.15 x 0.4): a fallback, named 'assumed_hold'. Without the assumption (the INS alone,
    0.05 m/s) it would not fall back. The same hold measured from a stop (nothing assumed)
    counts the INS's spread and the change's, 0.0707 m/s, and is not named so; a hold back at
    the assumed slip, and one beyond 3.5 sigmas (0.5: 0.2 m/s), judge the INS alone."""
    from slip_estimator.core.params import Params
    from slip_estimator.core.slip_model.chain import SlipChain
    from slip_estimator.core.slip_model.hold_variance import assumed_hold, guard_var_mps2
    from slip_estimator.core.slip_model.records import Resolution, SlipReading
    ins, w = 0.05 ** 2, 0.4

    def chained(start_from_rest: bool) -> tuple[SlipChain, float]:
        chain = SlipChain(Params())
        if start_from_rest:  # measured at a stop
            chain.settle(SlipReading(0.0, None, w, from_rest=True), Resolution(1e-4, 1.0, 0.05))
        else:  # zero slip, assumed
            chain.settle(SlipReading(0.0, None, w, unmeasured=True), Resolution(0.0, 1.0, 0.05))
        return chain, chain.settle(SlipReading(0.3, 0.0, w), Resolution(ins, 1.0, 0.05))

    chain, held = chained(False)
    assert chain.assumed and held == 0.3 and chain.ins_chain_var == pytest.approx(ins)
    assert assumed_hold(chain, held, ins, w)
    var = guard_var_mps2(chain, ins, held, w)
    assert var == pytest.approx(ins + (0.1 * w) ** 2)
    d = decide(_slip(w, (1.0 - held) * w, 3), var, False, 3.5, assumed_hold=True)
    assert d.fallback and d.reason == 'assumed_hold'
    assert not decide(_slip(w, (1.0 - held) * w, 3), ins, False, 3.5).fallback
    guard = OdometryGuard()
    guard.wheel(d)
    values, note = guard.figures()
    assert values['odometry_fallback_reason'] == 'assumed_hold'
    assert note is not None and 'a slip no stop measured' in note
    assert not assumed_hold(chain, 0.0, ins, w)  # back at the assumed slip
    assert guard_var_mps2(chain, ins, 0.0, w) == pytest.approx(ins)
    assert not assumed_hold(chain, 0.5, ins, w)  # 0.2 m/s: resolved
    assert guard_var_mps2(chain, ins, 0.5, w) == pytest.approx(ins)
    rest, held = chained(True)
    assert not rest.assumed and held == 0.3 and not assumed_hold(rest, held, ins, w)
    assert guard_var_mps2(rest, ins, held, w) == pytest.approx(2 * ins)
    d = decide(_slip(w, (1.0 - held) * w, 3), 2 * ins, False, 3.5)
    assert d.fallback and d.reason == 'coarse_ins'


def test_the_fallback_reason_names_a_hold_through_a_stop():
    """A fallback that lasted a measuring span holds through still wheels: named
    'held_through_stop' there, 'coarse_ins' before; 'none' without a fallback."""
    guard = OdometryGuard()
    coarse = decide(_slip(1.0, 0.0, 4), 0.5 ** 2, False, 3.5)
    guard.wheel(coarse)
    assert guard.figures()[0]['odometry_fallback_reason'] == 'coarse_ins'
    guard.wheel(decide(SlipEstimate(10 * NS, 0.0, 0.1, 0, 0.0, 0.1, 0.0), 0.5 ** 2, False,
                       3.5))
    assert guard.figures()[0]['odometry_fallback_reason'] == 'held_through_stop'
    assert decide(_slip(1.0, 0.98), 0.01 ** 2, False, 3.5).reason == 'none'
