"""Unit tests of the estimator's parts, each driven alone with closed-form expectations:
the error-state filter (predict, gated Joseph update, correction), the forward-speed history
(correction shift, free speed), the supervisor's decisions, the wheel aid's decisions, the
pure slip output, and the parameter schema's removed keys."""
import dataclasses
import math

import numpy as np
import pytest

from slip_estimator.core.detectors import ImuRate, ImuWindow
from slip_estimator.core.filter import ErrorStateFilter, vibration_psd
from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.core.history import Correction, ForwardSpeedHistory
from slip_estimator.core.kalman import chi2_threshold
from slip_estimator.core.measurements import ForwardSpeed
from slip_estimator.core.outputs import (RESOLVED_P, slip_before_alignment, slip_estimate,
                                         unknown_slip)
from slip_estimator.core.params import (
    GROUPS,
    REMOVED_PARAMETERS,
    RENAMED_PARAMETERS,
    ParameterError,
    Params,
    renamed_in,
)
from slip_estimator.core.planet import EARTH, gravity_n
from slip_estimator.core.slip_model.aided_record import ANCHOR_S, AidedRecord
from slip_estimator.core.slip_model.rim_memory import MEMORY_S, RimMemory, rim_steady
from slip_estimator.core.slip import p_beyond_medium_bound
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.slip_model.stop_clock import STOP_S, StopClock
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState
from slip_estimator.core.supervisor import GapAction, Supervisor, check_filter
from slip_estimator.core.take_back import (RUNAWAY_SIGMA, TAKE_BACK_CHECK_S, RunawayScale,
                                           runaway_scale)
from slip_estimator.core.types import WheelSample
from slip_estimator.core.slip_model.wheel_aid import WheelAid

LLH = np.array([math.radians(39.6), math.radians(-79.9), 310.0])
P0 = np.diag([1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-4, 1e-16, 1e-16, 1e-2,
              1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8])


def level_state(v_eb_n=(0.0, 0.0, 0.0), heading_rad=0.0) -> NavState:
    return NavState(rpy_to_dcm(0.0, 0.0, heading_rad), np.array(v_eb_n, dtype=float),
                    LLH.copy(), np.zeros(3), np.zeros(3))


def started_filter(params=None, **state) -> ErrorStateFilter:
    flt = ErrorStateFilter(params or Params(), EARTH)
    flt.start(level_state(**state), P0.copy(), 9.8)
    return flt


# ---------------------------------------------------------------------------- filter
def test_predict_at_rest_grows_velocity_variance_by_the_accelerometer_psd():
    """Level and at rest, an empty vibration window: over tau the velocity variance grows by
    S_ra tau (plus the tilt coupling g^2 P_att tau^2, taken out in closed form)."""
    p = Params()
    flt = started_filter(p)
    g_n = gravity_n(EARTH, LLH[0], LLH[2])
    f_b = (-g_n).tolist()
    w_ie_b = [EARTH.omega_ie_rps * math.cos(LLH[0]), 0.0, -EARTH.omega_ie_rps * math.sin(LLH[0])]
    dt, n = 0.004, p.covariance_decimation
    due = [flt.mechanize(f_b, w_ie_b, dt) for _ in range(n)]
    assert due == [False] * (n - 1) + [True]
    flt.predict_covariance(ImuWindow(10), dt)
    tau = n * dt
    g = float(np.linalg.norm(g_n))
    expected = (P0[3, 3] + p.accel_noise_density_mps2_rthz ** 2 * tau
                + g * g * P0[0, 0] * tau * tau)
    assert flt.P[3, 3] == pytest.approx(expected, rel=2e-3)
    assert flt.P[POS, POS][2, 2] > P0[8, 8]  # height grows with the vertical velocity
    assert np.allclose(flt.P, flt.P.T, atol=0)
    assert np.linalg.norm(flt.state.v_eb_n) < 1e-6  # the INS stays at rest


def test_vibration_inflates_the_psd_by_the_excess_spread_only():
    S = (1e-6, 1e-4, 1e-8, 1e-12)
    quiet = ImuWindow(4)
    assert vibration_psd(S, 0.5, quiet, 0.01) == S  # fewer than two samples
    window = ImuWindow(4)
    for k in range(4):
        sign = 1.0 if k % 2 else -1.0
        window.add([0.0, 0.0, sign * 1.0], [0.0, 0.0, sign * 0.1])
    S_rg, S_ra, S_bad, S_bgd = vibration_psd(S, 0.5, window, 0.01)
    # variance 1.0 (accel z) and 0.01 (gyro z), beyond the white part S / dt
    assert S_ra == pytest.approx(1e-4 + 0.25 * (1.0 - 1e-4 / 0.01) * 0.01)
    assert S_rg == pytest.approx(1e-6 + 0.25 * (0.01 - 1e-6 / 0.01) * 0.01)
    assert (S_bad, S_bgd) == S[2:]
    assert vibration_psd(S, 0.0, window, 0.01) == S


def test_a_stop_reopens_tilt_and_horizontal_accel_bias_to_the_stated_acceleration():
    """North/east tilt rise to (sigma / g)^2, body x/y accelerometer bias to sigma^2 (a larger
    variance is kept); heading, the vertical bias, every other state and every correlation are
    left as they were, P stays positive semi-definite, and a second call changes nothing."""
    flt = started_filter()
    rng = np.random.default_rng(3)
    A = rng.normal(0.0, 3e-4, (N_ERR, N_ERR))
    flt.P = P0 + A @ A.T  # correlated
    flt.P[BA.start, BA.start] = 0.1 ** 2  # already larger than sigma^2: kept
    before = flt.P.copy()
    flt.reopen_levels(0.049)
    expected = before.copy()
    for i in (ATT.start, ATT.start + 1):
        expected[i, i] = (0.049 / 9.8) ** 2
    expected[BA.start + 1, BA.start + 1] = 0.049 ** 2
    assert before[ATT.start, ATT.start] < (0.049 / 9.8) ** 2  # so the test can fail
    np.testing.assert_array_equal(flt.P, expected)
    assert np.linalg.eigvalsh(flt.P).min() > 0.0
    flt.reopen_levels(0.049)
    np.testing.assert_array_equal(flt.P, expected)


def test_update_of_one_velocity_component_is_the_scalar_kalman_update():
    """H picks v_N: gain P / (P + R), posterior P R / (P + R), the velocity moves by the
    gain times the innovation (dx is subtracted from the state)."""
    flt = started_filter(v_eb_n=(1.0, 0.0, 0.0))
    H = np.zeros((1, N_ERR))
    H[0, 3] = -1.0  # innovation = z - v_N ~ -dv_N
    R = np.array([[1e-4]])
    outcome = flt.update('wheel', np.array([0.01]), H, R)
    k = 1e-4 / (1e-4 + 1e-4)
    assert not outcome.gated and outcome.record.accepted
    assert outcome.record.nis == pytest.approx(0.01 ** 2 / 2e-4)
    assert flt.state.v_eb_n[0] == pytest.approx(1.0 + k * 0.01)
    assert flt.P[3, 3] == pytest.approx(1e-4 * 1e-4 / 2e-4)
    assert outcome.correction.dv_fwd_mps == pytest.approx(k * 0.01)  # heading north: x = N
    assert flt.last_records == [outcome.record]
    assert flt.nis_mean['wheel'] == outcome.record.nis


def test_update_beyond_the_gate_is_applied_with_R_inflated_onto_the_gate():
    flt = started_filter()
    H = np.zeros((1, N_ERR))
    H[0, 3] = -1.0
    R = np.array([[1e-4]])
    outcome = flt.update('wheel', np.array([1.0]), H, R)  # NIS 5000
    gate = chi2_threshold(1, Params().innovation_gate_probability)
    assert outcome.gated and not outcome.record.accepted
    r_eff = 1e-4 * outcome.record.nis / gate
    assert flt.state.v_eb_n[0] == pytest.approx(1e-4 / (1e-4 + r_eff) * 1.0)
    # a non-finite innovation is recorded and not applied
    before = flt.state.v_eb_n.copy()
    assert flt.update('wheel', np.array([math.nan]), H, R).correction is None
    assert np.array_equal(flt.state.v_eb_n, before)


def test_body_velocity_updates_leave_heading_and_gyro_z_bias_to_the_gyro_and_yaw_aid():
    """NHC, the forward-speed aid and its anchors (body-frame velocity) do not correct the
    heading or the gyro z bias even where P correlates them with the velocity (consider
    states: zero gain rows, Joseph form: P stays symmetric and their variances do not shrink);
    the wheel yaw-rate aid does correct the z bias; the kalman update itself is the ordinary
    one without ``consider``, and so is the paper's method (``wheel_aid: off``)."""
    from slip_estimator.core.filter import BODY_VELOCITY_CONSIDER
    from slip_estimator.core.kalman import update
    from slip_estimator.core.measurements import NonHolonomic, WheelYawRate

    rng = np.random.default_rng(7)
    A = rng.standard_normal((N_ERR, N_ERR)) * np.sqrt(np.diag(P0))[:, None]
    P = A @ A.T + np.diag(P0)  # every state correlated with every other

    def fresh():
        flt = started_filter(v_eb_n=(0.8, 0.1, 0.0))
        flt.P = P.copy()
        return flt

    nhc = NonHolonomic(EARTH, np.array([-0.1, 0.0, 0.2]))
    H = nhc.jacobian(fresh().state, (1,))
    dx_plain, P_plain, _ = update(P, np.array([0.05]), H, np.array([[1e-4]]))
    assert P_plain[2, 2] < P[2, 2] and abs(dx_plain[2]) > 1e-3  # what it would do
    for name in ('nhc', 'wheel', None):
        flt = fresh()
        C0, b0 = flt.state.C_b_n.copy(), flt.state.b_g.copy()
        H = nhc.jacobian(flt.state, (1,))
        if name is None:
            flt.anchor(np.array([0.05]), H, np.array([[1e-4]]))
        else:
            flt.update(name, np.array([0.05]), H, np.array([[1e-4]]))
        heading = math.atan2(flt.state.C_b_n[1, 0], flt.state.C_b_n[0, 0])
        # (roll and pitch corrections turn the heading at second order only)
        assert abs(heading - math.atan2(C0[1, 0], C0[0, 0])) < 1e-3 * abs(dx_plain[2])
        assert flt.state.b_g[2] == b0[2] and flt.state.b_g[0] != b0[0]
        assert np.allclose(flt.P, flt.P.T, atol=0)
        for i in BODY_VELOCITY_CONSIDER:
            assert flt.P[i, i] == pytest.approx(P[i, i], rel=1e-9)
    flt = fresh()
    m = WheelYawRate(EARTH)
    flt.update('wheel_yaw', m.innovation(flt.state, 0.01, 0.0), m.jacobian(flt.state),
               np.array([[1e-4]]))
    assert flt.state.b_g[2] != 0.0 and flt.P[14, 14] < P[14, 14]
    paper = started_filter(Params(wheel_aid='off'), v_eb_n=(0.8, 0.1, 0.0))  # corrects all
    paper.P = P.copy()
    paper.update('nhc', np.array([0.05]), H, np.array([[1e-4]]))
    assert paper.P[2, 2] < P[2, 2] and paper.state.b_g[2] != 0.0


def test_a_stop_does_not_turn_the_heading_through_the_bias_heading_correlation():
    """A 10-s stop after a drive: the drive left the heading 14 deg uncertain and 0.75
    correlated with the gyro z bias (the heading integrated the bias), the INS velocity a few
    cm/s off, and the gyro at rest (a consumer one: 0.02 rad/s per sample at 30 Hz) reads a
    static bias 2.5 sigma away from the one the drive held. The stop's ZUPT + ZARU, applied as
    the updater applies them (window means at 10 Hz, R from the scatter), learn the bias but
    may turn the heading by no more than the gyro's own white noise could over the stop
    (3 sigma of its angle random walk, 2 deg; without the consider states: 18 deg) while the
    rest's bias may differ from the drive's (``rest_bias_jump_var_rps2``: before a stop
    after driving measured it, and when the drive vibrated beyond the rest). The paper's
    method (``wheel_aid: off``) still takes the correlation."""
    from slip_estimator.core.measurements import (NonHolonomic, PseudoMeasurements,
                                                  ZeroAngularRate, ZeroVelocity)
    from slip_estimator.core.planet import earth_rate_n

    rate_hz, std_rps, stop_s, period_s = 30.0, 0.02, 10.0, 0.1
    n_g = std_rps / math.sqrt(rate_hz)  # rad/s/sqrt(Hz)
    sd_psi, sd_bg, corr = math.radians(14.0), 8e-4, 0.75
    P = P0.copy()
    P[2, 2], P[14, 14] = sd_psi ** 2, sd_bg ** 2
    P[2, 14] = P[14, 2] = corr * sd_psi * sd_bg
    P[3, 3] = P[4, 4] = 0.03 ** 2  # velocity error, correlated with the heading
    P[2, 4] = P[4, 2] = -0.5 * sd_psi * 0.03
    b_rest = 2.5 * sd_bg
    rng = np.random.default_rng(3)

    def stop(params, jump_var_rps2=math.inf):
        flt = started_filter(params, v_eb_n=(0.02, -0.03, 0.0))
        flt.P = P.copy()
        flt.rest_bias_jump_var_rps2 = jump_var_rps2
        pm = PseudoMeasurements(ZeroVelocity(), ZeroAngularRate(EARTH, 1e-5, n_g),
                                NonHolonomic(EARTH, np.zeros(3)))
        C0 = flt.state.C_b_n.copy()
        n = int(rate_hz * period_s)
        for _ in range(int(stop_s / period_s)):
            w_ie_b = flt.state.C_b_n.T @ earth_rate_n(EARTH, LLH[0])
            w_mean = w_ie_b + np.array([0.0, 0.0, b_rest]) + rng.normal(0.0, std_rps, 3) / \
                math.sqrt(n)
            for c in pm.select(flt.state, w_mean, n / rate_hz, True, False,
                               np.full(3, std_rps ** 2), 1.0 / rate_hz):
                flt.update(c.name, c.innovation, c.H, c.R)
        turn = math.atan2(flt.state.C_b_n[1, 0], flt.state.C_b_n[0, 0]) - \
            math.atan2(C0[1, 0], C0[0, 0])
        return abs(turn), flt.state.b_g[2]

    arw_bound = 3.0 * n_g * math.sqrt(stop_s)
    turn, b_z = stop(Params())
    assert turn < arw_bound
    # the bias is learned at rest as a scalar filter learns it from the rest mean
    # (prior 0 +- sd_bg, the mean of stop_s x rate_hz samples)
    r_mean = std_rps ** 2 / (stop_s * rate_hz)
    posterior_sd = math.sqrt(1.0 / (1.0 / sd_bg ** 2 + 1.0 / r_mean))
    assert abs(b_z - b_rest * sd_bg ** 2 / (sd_bg ** 2 + r_mean)) < 3.0 * posterior_sd
    assert b_z > 0.0
    turn_paper, _ = stop(Params(wheel_aid='off'))
    assert turn_paper > 5.0 * arw_bound  # what the correlation does
    # a rest bias that may differ from the drive's by 10 sigma keeps 1 % of the heading gain;
    # one that is the drive's (no vibration beyond the rest's) is the drive's evidence
    assert stop(Params(), (10.0 * sd_bg) ** 2)[0] < arw_bound
    assert stop(Params(), 0.0)[0] > 5.0 * arw_bound


def test_correction_reports_the_forward_speed_and_along_track_gravity_change():
    flt = started_filter(v_eb_n=(1.0, 0.0, 0.0))
    dx = np.zeros(N_ERR)
    dx[VEL] = [0.1, 0.0, 0.0]
    dx[1] = 0.01  # pitch error: gravity along x changes by g * 0.01
    dx[BA] = [0.002, 0.0, 0.0]
    c = flt.correct(dx)
    assert c.dv_fwd_mps == pytest.approx(-0.1, abs=2e-3)
    # along-track gravity g C_b_n[2, 0] less the bias; before: level and unbiased
    assert abs(flt.state.C_b_n[2, 0]) == pytest.approx(0.01, rel=1e-3)
    assert c.da_fwd_mps2 == pytest.approx(9.8 * float(flt.state.C_b_n[2, 0]) - 0.002)


def test_forward_speed_model_is_the_forward_row_of_the_constraint_and_carries_R():
    m = ForwardSpeed(EARTH, np.array([-0.2, 0.1, 0.3]))
    st = level_state(v_eb_n=(0.5, 0.2, 0.0), heading_rad=0.3)
    H = m.jacobian(st)
    assert H.shape == (1, N_ERR)
    assert np.allclose(H[0, VEL], -st.C_b_n[:, 0])
    assert np.array_equal(m.covariance(0.04), [[0.04]])
    assert m.innovation(1.2, 1.0) == pytest.approx([0.2])


def test_mean_rate_between_updates():
    flt = started_filter()
    f = (-gravity_n(EARTH, LLH[0], LLH[2])).tolist()
    for w in ([0.1, 0.0, 0.0], [0.3, 0.0, 0.2]):
        flt.mechanize(f, w, 0.004)
    w_mean, n = flt.take_mean_rate()
    assert n == 2 and np.allclose(w_mean, [0.2, 0.0, 0.1])
    assert flt.take_mean_rate()[1] == 0


# ---------------------------------------------------------------------------- history
def test_history_shifts_the_recorded_speed_by_each_correction_and_keeps_the_free_speed():
    h = ForwardSpeedHistory((0.0, 0.0, 0.0), horizon_s=1.0)
    for k in range(5):  # 1.0 m/s north, heading north
        h.record(k * 100_000_000, level_state(v_eb_n=(1.0, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.1)
    h.apply(Correction(0.2, 0.0), aid=False)
    at = h.at(150_000_000)
    assert at.v_fwd_mps == pytest.approx(1.2) and at.v_free_mps == pytest.approx(1.0)
    # a wheel-aid correction stays out of the free speed, also its acceleration later on
    h.apply(Correction(-0.1, 0.5), aid=True)
    h.record(500_000_000, level_state(v_eb_n=(1.1, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.1)
    _, newest = h.newest()
    assert newest.v_fwd_mps == pytest.approx(1.1)
    assert newest.v_free_mps == pytest.approx(1.1 - (-0.1 + 0.5 * 0.1))
    assert newest.aid_accel_mps2 == 0.5
    assert h.at(-1) is None and h.at(600_000_000) is None


def test_history_remembers_the_aids_tilt_and_bias_corrections_to_take_them_back():
    h = ForwardSpeedHistory((0.0, 0.0, 0.0), aid_horizon_s=1.0)
    dx = np.arange(1.0, N_ERR + 1.0)
    for k in range(20):  # an aid update every 0.1 s
        h.record(k * 100_000_000, level_state(v_eb_n=(1.0, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.1)
        h.apply(Correction(0.0, 0.0, (k + 1) * dx), aid=True, taught=True)
    h.apply(Correction(0.1, 0.0, 100.0 * dx), aid=True)  # an anchor: not the aid's teaching
    taught = h.aid_taught_since(1_500_000_000)  # the updates at 1.5-1.9 s: 16+...+20 = 90
    assert taught[ATT] == pytest.approx(90.0 * dx[ATT])
    assert taught[BA] == pytest.approx(90.0 * dx[BA])
    assert not taught[VEL].any() and not taught[POS].any() and not taught[BG].any()
    assert not h.aid_taught_since(1_500_000_000).any()  # taken back once
    # older than the horizon (1 s before the newest) is forgotten
    assert h.aid_taught_since(0)[ATT] == pytest.approx((10 + 11 + 12 + 13 + 14 + 15) * dx[ATT])
    h.apply(Correction(0.0, 0.0, dx), aid=True, taught=True)
    h.clear()
    assert not h.aid_taught_since(0).any()


def test_history_keeps_its_horizon_and_interpolates():
    h = ForwardSpeedHistory((0.0, 0.0, 0.0), horizon_s=0.25)
    for k in range(6):
        h.record(k * 100_000_000, level_state(v_eb_n=(0.1 * k, 0.0, 0.0)), [0.0, 0.0, 0.1],
                 0.1)
    assert len(h) == 3  # 0.3, 0.4, 0.5 s
    assert h.at(350_000_000).v_fwd_mps == pytest.approx(0.35)
    assert h.at(350_000_000).yaw_rate_b_rps == pytest.approx(0.1)
    h.clear()
    assert len(h) == 0 and h.at(500_000_000) is None


def test_history_mean_yaw_rate_over_a_wheel_interval_cancels_a_folded_vibration_line():
    """A 70-Hz resonance sampled at 30 Hz is a 10-Hz line: at 10-Hz wheel instants the gyro
    sample (or its interpolation) holds one phase of it, a false rate of up to its amplitude;
    its mean over any whole 0.1-s wheel interval is the rate itself."""
    h = ForwardSpeedHistory((0.0, 0.0, 0.0))
    rate_rps, line_rps = 0.02, 0.05
    for k in range(60):
        t_s = k / 30.0
        w_z = rate_rps + line_rps * math.sin(2.0 * math.pi * 70.0 * t_s + 0.7)
        h.record(round(t_s * 1e9), level_state(), [0.0, 0.0, w_z], 1.0 / 30.0)
    ms = 1_000_000
    wheel_ns = [1000 * ms + k * 100 * ms for k in range(9)]
    single = [h.at(t - 50 * ms).yaw_rate_b_rps for t in wheel_ns]
    assert np.ptp(single) < 1e-6 and abs(single[0] - rate_rps) > 0.3 * line_rps
    for offset_ns in (0, 50 * ms, 17 * ms):  # intervals starting anywhere
        for t in wheel_ns:
            mean = h.mean_yaw_rate_b_rps(t - offset_ns - 100 * ms, t - offset_ns)
            assert mean == pytest.approx(rate_rps, abs=1e-6)
    # clipped to the recorded span; an empty interval is the interpolated rate; outside: None
    newest_ns = h.newest()[0]
    assert h.mean_yaw_rate_b_rps(newest_ns - 100 * ms, newest_ns + 500 * ms) == pytest.approx(
        h.mean_yaw_rate_b_rps(newest_ns - 100 * ms, newest_ns))
    assert h.mean_yaw_rate_b_rps(1234 * ms, 1234 * ms) == h.at(1234 * ms).yaw_rate_b_rps
    assert h.mean_yaw_rate_b_rps(newest_ns + ms, newest_ns + 100 * ms) is None


# ---------------------------------------------------------------------------- supervisor
def test_filter_verdicts():
    p = Params()
    st, P = level_state(), P0.copy()
    assert check_filter(p, st, P) == check_filter(p, st, P)
    ok = check_filter(p, st, P)
    assert not ok.reset and ok.repaired_P is None and ok.recover_reason is None
    bad = P.copy()
    bad[0, 0] = math.nan
    assert check_filter(p, st, bad).reset
    lost = P.copy()
    lost[3, 3] = -1e-3
    v = check_filter(p, st, lost)
    assert np.linalg.eigvalsh(v.repaired_P).min() > 0.0 and v.recover_reason is None
    fast = level_state(v_eb_n=(3.0 * p.max_wheel_speed_mps, 0.0, 0.0))
    v = check_filter(p, fast, P)
    assert v.recover_reason.startswith('divergence') and v.b_a is None
    biased = level_state()
    biased.b_g = np.array([0.0, 0.0, 20.0 * p.initial_gyro_bias_std])
    v = check_filter(p, biased, P)
    assert 'biases out of bounds' in v.recover_reason
    assert v.b_g[2] == pytest.approx(p.initial_gyro_bias_std)
    assert biased.b_g[2] > p.initial_gyro_bias_std  # decided, not done


def test_imu_step_decisions_and_counts():
    p = Params()
    sup = Supervisor(p)
    f, w = [0.0, 0.0, -9.8], [0.0, 0.0, 0.0]
    assert sup.imu_step(1, 0.004, f, w, True) is GapAction.NONE
    gap = 0.5 * (p.max_imu_gap_s + p.recovery_gap_s)
    assert sup.imu_step(2, gap, f, w, True) is GapAction.INTERRUPT
    assert sup.imu_step(3, 2.0 * p.recovery_gap_s, f, w, True) is GapAction.RECOVER
    assert sup.imu_step(4, 2.0 * p.recovery_gap_s, f, w, False) is GapAction.INTERRUPT
    assert sup.counters['imu_gaps'] == 3
    assert [t for t, _ in sup.events] == [2, 3, 4]


def test_recovery_window_and_wheel_timeout():
    p = Params()
    sup = Supervisor(p)
    sup.start_recovery(0, 'IMU gap')
    end = int(p.recovery_s * 1e9)
    assert sup.recovering(end - 1) and not sup.recovering(end)
    assert sup.counters['recoveries'] == 1
    timeout = int(p.wheel_timeout_s * 1e9)
    assert sup.wheels_stale(timeout, 0) is None
    assert sup.wheels_stale(timeout + 1, 0) == timeout + 1  # no wheel data at all
    assert sup.wheels_stale(timeout + 2, 0) is None  # once per timeout
    assert sup.accept_wheel(WheelSample(timeout + 3, 0.5), timeout + 2)
    assert not sup.accept_wheel(WheelSample(timeout + 3, 0.5), timeout + 3)  # not after it
    assert not sup.accept_wheel(WheelSample(timeout + 4, math.inf), timeout + 4)
    assert sup.wheels_stale(2 * timeout + 3, 0) is None
    assert sup.wheels_stale(2 * timeout + 4, 0) == 2 * timeout + 4
    assert sup.counters['wheel_samples'] == 1 and sup.counters['wheel_rejected'] == 2


def test_wheel_timeout_is_judged_on_arrivals_and_reported_in_the_wheel_clock():
    """Wheel stamps 0.7 s behind the IMU (timeout 0.5 s) arriving every 20 ms: no dropout.
    When they stop, "unknown" once per timeout, stamped in the wheel clock."""
    sup = Supervisor(Params(wheel_timeout_s=0.5))
    lag, step = 700_000_000, 20_000_000
    for k in range(100):
        imu_now = 1_000_000_000 + k * step
        assert sup.accept_wheel(WheelSample(imu_now - lag, 0.5), imu_now)
        assert sup.wheels_stale(imu_now + step // 2, 0) is None
    assert sup.wheel_arrival_ns == imu_now
    stale = sup.wheels_stale(imu_now + 600_000_000, 0)
    assert stale == imu_now - lag + 600_000_000


# ---------------------------------------------------------------------------- wheel aid, outputs
def test_wheel_aid_decisions():
    hold, off = WheelAid(Params()), WheelAid(Params(wheel_aid='off'))
    d = hold.reanchor(1.0, turning=False)
    assert d.z_mps == 1.0 and d.repair and not d.anchor
    assert d.var_mps2 == pytest.approx(Params().wheel_aid_std_mps ** 2 + 0.1 ** 2)
    assert hold.reanchor(1.0, turning=True) is None
    assert off.reanchor(1.0, turning=False) is None
    wheel = WheelSample(1, 1.0)
    est = slip_estimate(wheel, 0.9, 0.0, 1e-4, Params(), False, 1.0)
    assert off.decide(wheel, None, est, np.eye(3), False) is None


@pytest.mark.parametrize('v, w, s', [(0.8, 1.0, 0.2), (1.0, 0.8, -0.2), (1.0, 1.0, 0.0)])
def test_slip_output_is_eq_1_with_its_class(v, w, s):
    est = slip_estimate(WheelSample(7, w, w + 0.1, w - 0.1), v, 0.0, 1e-4, Params(), False, 1.0)
    assert est.slip_ratio == pytest.approx(s)
    assert est.slip_class == (1 if abs(s) <= 0.2 + 1e-12 else 2)
    assert est.body_speed_std_mps == pytest.approx(0.01)
    assert est.slip_ratio_left is not None and est.stamp_ns == 7
    at_rest = slip_estimate(WheelSample(7, w), v, 0.0, 1e-4, Params(), True, 1.0)
    assert at_rest.slip_class == 0 and at_rest.slip_ratio == 0.0
    unknown = unknown_slip(7, w)
    assert unknown.slip_class == -1 and math.isnan(unknown.slip_ratio)
    assert slip_before_alignment(WheelSample(7, 0.0), Params(), True).slip_class == 0
    assert slip_before_alignment(WheelSample(7, w), Params(), True).slip_class == -1


def test_imu_rate_is_the_median_of_the_first_intervals():
    rate = ImuRate(learn_samples=3)
    assert [rate.add(dt) for dt in (0.01, 0.03, 0.02)] == [False, False, True]
    assert rate.dt_s == 0.02
    assert not rate.add(0.03) and rate.dt_s == pytest.approx(0.0201)


def test_removed_parameters_are_ignored_unknown_ones_refused():
    assert 'max_wheel_latency_s' in REMOVED_PARAMETERS
    assert Params.from_dict({'max_wheel_latency_s': 0.5}) == Params()
    with pytest.raises(ParameterError, match='unknown parameter'):
        Params.from_dict({'max_wheel_latency': 0.5})
    assert BG.start == 12 and POS.start == 6  # the layout these tests index by hand


def test_renamed_parameters_load_under_their_old_name_with_a_warning_naming_the_new():
    assert Params.from_dict({'wheel_aid_std': 0.05}).wheel_aid_std_mps == 0.05
    assert Params.from_dict({'wheel_aid_std': 0.05, 'wheel_aid_std_mps': 0.03}) \
        .wheel_aid_std_mps == 0.03  # the new name wins
    assert renamed_in(['wheel_radius', 'turn_rate_threshold']) == [
        'parameter turn_rate_threshold is renamed turn_rate_threshold_rps (the old name still '
        'loads; rename it)']
    names = {f.name for f in dataclasses.fields(Params)}
    assert set(RENAMED_PARAMETERS.values()) <= names and not set(RENAMED_PARAMETERS) & names


INTERFACE = {'wheel_radius', 'track_width', 'wheel_input', 'wheel_joint_names',
             'imu_to_base_rpy', 'imu_to_base_xyz', 'planet'}
"""The node's public parameters (and ``initial_*``): named as users' launch files set them."""
UNIT_SUFFIX = {'m': '_m', 's': '_s', 'm/s': '_mps', 'm/s^2': '_mps2', 'rad/s': '_rps',
               'Hz': '_hz', 'deg': '_deg', 'm/s^2/sqrt(Hz)': '_mps2_rthz',
               'rad/s/sqrt(Hz)': '_rps_rthz', 'm^2/s^5': '_m2ps5', 'rad^2/s^3': '_rad2ps3'}


def test_every_physical_parameter_but_the_interface_ends_with_its_unit():
    for f in dataclasses.fields(Params):
        unit = f.metadata['unit']
        if unit and f.name not in INTERFACE and not f.name.startswith('initial_'):
            assert f.name.endswith(UNIT_SUFFIX[unit]), (f.name, unit)


def test_parameter_groups_partition_the_schema_and_are_frozen():
    p = Params(wheel_radius=0.2, wheel_aid_std_mps=0.04)
    views = [getattr(p, g) for g in GROUPS]
    names = [f.name for v in views for f in dataclasses.fields(v)]
    assert names == [f.name for f in dataclasses.fields(Params)]  # each once, schema order
    assert p.rover.wheel_radius == 0.2 and p.slip_model.wheel_aid_std_mps == 0.04
    assert not hasattr(p.rover, 'wheel_aid_std_mps')
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.node.odom_frame = 'map'


def test_relevel_after_a_recovery_takes_the_tilt_from_the_specific_force():
    """A state whose attitude was kept across a long gap (level, heading 1 rad) while the
    rover now climbs at 10 deg: re-levelled to 10 deg pitch, heading and position kept,
    velocity from the rim speed; position variance not shrunk."""
    from slip_estimator.core.alignment import AlignmentStart
    from slip_estimator.core.filter_start import relevel
    from slip_estimator.core.frames import dcm_to_rpy

    p = Params()
    st = level_state(heading_rad=1.0)
    pitch = math.radians(10.0)
    f_b = np.array([9.8 * math.sin(pitch), 0.0, -9.8 * math.cos(pitch)])  # FRD, nose up
    P = P0.copy()
    P[POS, POS] *= 100.0
    P_new = relevel(st, P, AlignmentStart(f_b, None, 0.4), p, EARTH)
    roll, pitch_est, yaw = dcm_to_rpy(st.C_b_n)
    assert pitch_est == pytest.approx(pitch, abs=1e-9) and roll == pytest.approx(0.0, abs=1e-9)
    assert yaw == pytest.approx(1.0)
    assert np.allclose(st.v_eb_n, st.C_b_n[:, 0] * 0.4)
    assert np.array_equal(st.llh, LLH)
    assert np.all(np.diag(P_new)[POS] >= np.diag(P)[POS])
    assert np.allclose(P_new, P_new.T, rtol=0, atol=1e-18)
    assert np.linalg.eigvalsh(P_new).min() > -1e-12  # PSD to round-off (max variance 1)


def test_wheel_yaw_aid_is_tight_driving_straight_loose_in_turns_and_rate_independent():
    """The aid's R: a differential of ~0 constrains the gyro z bias tightly whatever the
    effective track; a turn only loosely (R grows with the differential x the track's
    uncertainty); the differential-slip share carries the same information per second at any
    wheel rate (R x rate constant); nothing at rest, without sides or before an interval."""
    from slip_estimator.core.yaw_aid import WheelYawAid

    p = Params(track_width=0.5)
    aid = WheelYawAid(p, EARTH)
    st = NavState(np.eye(3), np.zeros(3), np.array([0.7, 0.0, 300.0]), np.zeros(3), np.zeros(3))
    straight = aid.variance_rps2(0.0, 0.5, 0.0, 0.1)
    turn = aid.variance_rps2(-0.4, 0.5, 0.0, 0.1)
    assert turn > 10.0 * straight
    slip_only = 2.0 * p.wheel_yaw_rate_std_rps ** 2 * p.wheel_yaw_rate_correlation_s
    enc = 2.0 * p.wheel_speed_std_mps ** 2 / 0.5 ** 2
    for rate_hz in (5.0, 10.0, 100.0):
        assert (aid.variance_rps2(0.0, 0.5, 0.0, 1.0 / rate_hz) - enc) / rate_hz == \
            pytest.approx(slip_only)
    w = WheelSample(0, 0.8, 0.8, 0.8)
    assert aid.constraint(w, 0.0, st, 1e-4, moving=True) is None  # no interval yet
    w = WheelSample(100_000_000, 0.8, 0.7, 0.9)  # right faster: a left turn, FRD z < 0
    c = aid.constraint(w, 0.0, st, 1e-4, moving=True)
    assert c.name == 'wheel_yaw' and c.innovation[0] == pytest.approx(
        -0.2 / 0.5 - EARTH.omega_ie_rps * math.sin(0.7), rel=1e-6)
    assert aid.constraint(WheelSample(200_000_000, 0.8, 0.8, 0.8), 0.0, st, 1e-4,
                          moving=False) is None
    assert aid.constraint(WheelSample(300_000_000, 0.8), 0.0, st, 1e-4, moving=True) is None
    paper = WheelYawAid(Params(track_width=0.5, wheel_aid='off'), EARTH)  # the paper's method
    assert [paper.constraint(WheelSample(k * 100_000_000, 0.8, 0.7, 0.9), 0.0, st, 1e-4, True)
            for k in range(3)] == [None] * 3


def test_wheel_yaw_aid_lets_go_while_wheels_and_gyro_disagree_persistently():
    """A ground that yaws the robot beyond the declared unexplained yaw rate (wheels straight,
    gyro 0.02 rad/s) raises R through the running innovation mean within seconds; when they
    agree again it falls back to the declared one."""
    from slip_estimator.core.yaw_aid import WheelYawAid

    aid = WheelYawAid(Params(track_width=0.5), EARTH)
    st = NavState(np.eye(3), np.zeros(3), np.array([0.0, 0.0, 300.0]), np.zeros(3), np.zeros(3))
    R = []
    for k in range(101):
        yaw = 0.02 if 10 <= k < 60 else 0.0
        c = aid.constraint(WheelSample(k * 100_000_000, 0.8, 0.8, 0.8), yaw, st, 1e-4, True)
        if c is not None:
            R.append(c.R[0, 0])
    assert R[55] > 3.0 * R[5]  # after 4.5 s of disagreement (the ground share 10x)
    assert R[-1] == pytest.approx(R[5], rel=0.2)  # 4 s after they agree again


def test_a_medium_reading_within_its_own_error_of_low_is_published_low_and_unresolved():
    """s = 0.3 read with a 1-sigma of 0.01 is medium. s = 0.22 read with 0.1 is beyond 0.2 with
    P = Phi(0.02 / 0.1) = 0.58 < RESOLVED_P: published low, unresolved, with that one-sided
    P(medium+), unless the slip model holds a medium slip it resolves (0.3: Phi(1) = 0.84);
    not a low hold, nor a medium one whose 1-sigma is too wide to place it (0.22 +- 1.0: the
    end of a chain of changes on a consumer IMU). A start (rim 0.3 m/s, body 0.4: s = -0.25)
    is medium while the rim is steady; unresolved when the rim moved by 0.1 m/s since the
    last sample (within its timing the rim speed could be 0.4: no slip)."""
    p, wheel = Params(), WheelSample(7, 1.0)
    sure = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.04)
    assert sure.slip_class == 2 and sure.resolved and sure.p_medium_or_worse > 0.99
    for held in (None, 0.04, 0.3):
        est = slip_estimate(wheel, 0.78, 0.0, 0.1 ** 2, p, False, 1.0, held_slip=held)
        assert est.p_medium_or_worse == pytest.approx(
            p_beyond_medium_bound(0.22, est.slip_ratio_std))
        assert p_beyond_medium_bound(0.22, est.slip_ratio_std) < RESOLVED_P
        assert (est.slip_class, est.resolved) == ((2, True) if held == 0.3 else (1, False))
    wide = slip_estimate(wheel, 0.78, 0.0, 1.0, p, False, 1.0, held_slip=0.22)
    assert wide.slip_class == 1 and not wide.resolved and wide.p_medium_or_worse < RESOLVED_P
    start = WheelSample(7, 0.3)
    assert slip_estimate(start, 0.4, 0.0, 1e-4, p, False, 1.0).slip_class == 2
    late = slip_estimate(start, 0.4, 0.0, 1e-4, p, False, 1.0, rim_timing_var_mps2=0.1 ** 2)
    assert late.slip_class == 1 and not late.resolved
    slight = slip_estimate(start, 0.4, 0.0, 1e-4, p, False, 1.0, rim_timing_var_mps2=0.01 ** 2)
    assert slight.slip_class == 2 and slight.resolved
    assert slip_estimate(WheelSample(7, 0.0), 0.0, 0.0, 1e-4, p, True, 1.0).resolved


def test_the_rim_timing_variance_is_the_rims_change_since_the_last_sample():
    aid = WheelAid(Params())
    assert aid.rim_timing_var_mps2(WheelSample(0, 0.2)) == 0.0  # no sample before
    aid.stopping(WheelSample(0, 0.2))
    assert aid.rim_timing_var_mps2(WheelSample(100_000_000, 0.3)) == pytest.approx(0.01)
    assert aid.rim_timing_var_mps2(WheelSample(0, 0.3)) == 0.0  # not after the last one

def test_wheels_that_just_stopped_hold_the_body_for_the_stop_time():
    """The rim speed falls below the moving threshold: for STOP_S the body is taken to stop
    with the wheels (an INS speed left from a held slip is not a slide), and so is the sample
    the stop's zero-speed aid comes with (the INS speed before the aid); then a body still
    moving reads as slip again (a slide that lasts, or a failed encoder); moving wheels end
    it. Without the slip model's aid (``wheel_aid: off``) the stop time alone."""
    ns = 1_000_000_000
    for mode in ('hold', 'off'):
        aid = WheelAid(Params().replace(wheel_aid=mode))
        assert not aid.stopping(WheelSample(0, 0.3))
        assert aid.stopping(WheelSample(ns, 0.01))
        assert aid.stopping(WheelSample(ns + 4 * ns // 10, 0.0))
        t_aid = ns + 5 * ns // 10
        assert aid.stopping(WheelSample(t_aid, 0.0)) == (mode == 'hold')
        if mode == 'hold':  # (WheelAid.decide: the rim below the threshold is not moving)
            zero = aid.slip_model.step(t_aid, 0.0, 0.05, 0.05, False, False)
            assert zero is not None and zero.z_mps == 0.0
        assert not aid.stopping(WheelSample(ns + 6 * ns // 10, 0.0))
        assert not aid.stopping(WheelSample(2 * ns, 0.3))
        assert aid.stopping(WheelSample(3 * ns, 0.0))
    sliding = slip_estimate(WheelSample(ns, 0.0), 0.1, 0.0, 1e-4, Params(), False, 1.0)
    stopping = slip_estimate(WheelSample(ns, 0.0), 0.1, 0.0, 1e-4, Params(), True, 1.0)
    assert sliding.slip_class == 4 and stopping.slip_class == 0


def test_a_rim_slowing_through_the_threshold_by_the_stamp_is_a_stop():
    """The rim speed describes wheel_latency_s before the stamp (a count difference at 10 Hz:
    50 ms). Slowing at 1 m/s^2, the last sample above the threshold (0.04 m/s at the middle
    of its interval) stands for 0 m/s at its stamp (0.02 is the threshold): a stop. The same
    sample with no latency, a rim that speeds up, or a steady slow rim is still moving."""
    ns = 100_000_000
    late = Params().replace(wheel_latency_s=0.05)
    seen = []
    for params in (late, Params()):
        aid = WheelAid(params)
        seen.append([aid.stopping(WheelSample(k * ns, w)) for k, w in enumerate((0.14, 0.04))])
    assert seen == [[False, True], [False, False]]
    for rims in ((0.04, 0.14), (0.03, 0.03, 0.03)):
        aid = WheelAid(late)
        assert not any(aid.stopping(WheelSample(k * ns, w)) for k, w in enumerate(rims))


def test_the_odometry_guard_is_told_whether_the_rim_speed_is_steady():
    """Braking 1.0 -> 0.6 m/s between two wheel samples: the guard's verdict carries an
    unsteady rim (its count difference lags the body: the fused twist is published); a
    following 0.6 m/s is steady (``WheelAid.stopping`` sees every sample)."""
    ns = 100_000_000
    aid = WheelAid(Params())
    est = slip_estimate(WheelSample(ns, 0.6), 0.6, 0.0, 1e-4, Params(), False, 1.0)
    steady = []
    for k, w in enumerate((1.0, 0.6, 0.6)):
        aid.stopping(WheelSample(k * ns, w))
        steady.append(aid.odometry_decision(est).rim_steady)
    assert steady == [False, False, True]


@pytest.mark.parametrize('rate_hz', [10.0, 50.0])
def test_the_rim_memory_knows_when_the_rim_began_to_move(rate_hz):
    # A commanded rate change: 0.5 m/s, then a ramp to 0.6 m/s over 0.5 s starting at 1.0 s.
    rim = RimMemory()
    t_s = np.arange(0.0, 1.8, 1.0 / rate_hz)
    w = 0.5 + 0.1 * np.clip((t_s - 1.0) / 0.5, 0.0, 1.0)
    steady = [rim.add(int(round(t * 1e9)), float(x)) for t, x in zip(t_s, w)]
    assert not steady[0] and all(steady[1:])  # 0.02 m/s per sample at 10 Hz is within 5 %
    assert rim.moved_mps(0.6) == pytest.approx(0.1)
    # the last sample within 10 % of the change from the end (0.51 m/s at 1.05 s)
    assert rim.onset_ns(0.6) * 1e-9 == pytest.approx(1.05, abs=1.0 / rate_hz)
    assert not rim.add(int(1.9e9), 0.7)  # a jump is not steady
    # 5 % of the new rim speed plus 1 cm/s: 1.0 -> 1.059 m/s is steady, 1.0 -> 0.939 is not
    assert rim_steady(1.0, 1.059) and not rim_steady(1.0, 0.939) and not rim_steady(None, 1.0)
    rim.add(int((1.9 + MEMORY_S) * 1e9), 0.7)
    assert rim.moved_mps(0.7) == pytest.approx(0.0)  # the ramp is forgotten


def test_the_stop_clock_counts_still_wheels_and_waits_for_the_stops_aid() -> None:
    """Still wheels are 'stopping' for STOP_S, then until the stop's zero-speed aid is given;
    a moving rim ends the stop and forgets the aid."""
    ns = 1_000_000_000
    clock = StopClock(0.02)
    assert clock.still_ns(0, 0.5) is None and not clock.stopping(0, 0.5)
    t = [round(k * 0.1 * ns) for k in range(10)]
    assert [clock.still_ns(x, 0.0) for x in t[:3]] == [0, t[1], t[2]]
    stop_k = round(STOP_S / 0.1)
    assert all(clock.stopping(x, 0.0) for x in t[:stop_k])
    assert clock.stopping(t[stop_k], 0.0)  # the stop's aid is not given yet
    assert not clock.stopping(t[stop_k], 0.0, awaits_aid=False)
    clock.rest_aided = True
    assert not clock.stopping(t[stop_k + 1], 0.0)
    assert clock.still_ns(t[stop_k + 2], -0.03) is None  # reversing: moving again
    assert not clock.rest_aided and clock.still_ns(t[stop_k + 3], 0.0) == 0


def test_still_wheels_bring_the_zero_speed_aid_after_stop_s_with_the_rest_offset() -> None:
    """No aid while the body is taken to be stopping; from STOP_S on each still sample is the
    rest's, and the offset is the mean INS speed once three samples beyond the ZUPT's 1-sigma
    have been seen (0 before, and 0 within it)."""
    ns = 1_000_000_000
    clock = StopClock(0.02)
    t = [round(k * 0.1 * ns) for k in range(10)]
    stop_k = round(STOP_S / 0.1)
    offsets = [clock.zero_speed_aid(x, clock.still_ns(x, 0.0), -0.02, 0.01) for x in t]
    assert offsets[:stop_k] == [None] * stop_k and not clock.stopping(t[-1], 0.0)
    assert offsets[stop_k:stop_k + 2] == [0.0, 0.0]  # fewer than three samples
    assert offsets[stop_k + 2:] == pytest.approx([-0.02] * (len(t) - stop_k - 2))
    assert clock.zero_speed_aid(t[-1], clock.still_ns(t[-1], 0.0), -0.02, 0.03) == 0.0


def test_a_change_continues_from_the_aided_mean_before_its_onset() -> None:
    """The anchor is the mean over the ANCHOR_S before the onset, or the oldest sample where
    none is that old."""
    ns = 1_000_000_000
    rec = AidedRecord(5.0)
    assert rec.before(ns) is None
    for k in range(30):  # 10 Hz, z = 0.5 m/s, free speed rising 0.01 m/s per sample
        rec.add(round(k * 0.1 * ns), 0.5, 0.5, 0.01 * k, 0.0)
    onset = round(2.0 * ns)
    m = rec.before(onset)
    n = round(ANCHOR_S / 0.1) + 1  # samples in [onset - ANCHOR_S, onset]
    assert m.v_free_mps == pytest.approx(0.01 * (20 - (n - 1) / 2))
    assert m.last_ns == onset
    early = rec.before(round(-1.0 * ns))  # before the first sample: the oldest one
    assert early.v_free_mps == 0.0 and early.t_ns == 0



@pytest.mark.parametrize('heading_deg', [0.0, 90.0, 215.0])
def test_the_free_ins_reading_variance_follows_tilt_bias_and_their_correlation(heading_deg):
    """Closed form at rest, noise negligible: a pitch-axis tilt sigma s gives (g s T)^2 over T; an
    x accelerometer bias sigma b gives (b T)^2; a tilt about the forward axis gives nothing;
    and a tilt fully correlated with the bias so that g tilt - b is known (what ZUPTs at rest
    teach) gives nothing either. Signs follow the filter's own F, whatever the heading."""
    p = Params().replace(accel_noise_density_mps2_rthz=1e-6, gyro_noise_density_rps_rthz=1e-6)
    flt = started_filter(p, heading_rad=math.radians(heading_deg))
    g, T = 9.8, 2.0
    psi = math.radians(heading_deg)
    fwd_tilt = np.array([math.cos(psi), math.sin(psi), 0.0])  # roll axis, NED
    pitch_tilt = np.array([-math.sin(psi), math.cos(psi), 0.0])  # pitch axis, NED
    s, b = math.radians(0.5), 0.05
    def var(P):
        flt.P = P
        return flt.forward_reading_var_mps2((T,))[0]
    P = np.zeros((N_ERR, N_ERR))
    P[ATT, ATT] = s * s * np.outer(pitch_tilt, pitch_tilt)
    assert var(P) == pytest.approx((g * s * T) ** 2, rel=1e-3)
    P = np.zeros((N_ERR, N_ERR))
    P[ATT, ATT] = s * s * np.outer(fwd_tilt, fwd_tilt)
    assert var(P) == pytest.approx(0.0, abs=1e-6 * (g * s * T) ** 2)
    P = np.zeros((N_ERR, N_ERR))
    P[BA.start, BA.start] = b * b
    assert var(P) == pytest.approx((b * T) ** 2, rel=1e-3)
    # Tilt and bias in the one combination that moves no acceleration: found from F itself
    # by trying both signs; exactly one of them cancels (the other doubles).
    both = []
    for sign in (1.0, -1.0):
        x = np.zeros(N_ERR)
        x[ATT] = (b / g) * pitch_tilt
        x[BA.start] = sign * b
        both.append(var(np.outer(x, x)))
    assert min(both) == pytest.approx(0.0, abs=1e-9) and max(both) == pytest.approx(
        (2 * b * T) ** 2, rel=1e-3)


def test_the_gyro_bias_prior_grows_with_the_measured_grade():
    """An IMU measured r times noisier than the default gyro density gets the default turn-on
    bias sigma times sqrt(r) when that is left at its default; a declared one is kept, and a
    gyro quieter than the default changes nothing."""
    from slip_estimator.core.params import with_message_noise

    default = Params()
    dt_s = 1.0 / 30.0
    consumer = with_message_noise(default, 0.05 ** 2, 0.02 ** 2, dt_s, raise_only=True)
    r = 0.02 * math.sqrt(dt_s) / default.gyro_noise_density_rps_rthz
    assert consumer.gyro_noise_density_rps_rthz == pytest.approx(0.02 * math.sqrt(dt_s))
    assert consumer.initial_gyro_bias_std == pytest.approx(
        default.initial_gyro_bias_std * math.sqrt(r))
    declared = with_message_noise(default.replace(initial_gyro_bias_std=0.001), 0.05 ** 2,
                                  0.02 ** 2, dt_s)
    assert declared.initial_gyro_bias_std == 0.001
    quiet = with_message_noise(default, 1e-8, 1e-10, dt_s)
    assert quiet.initial_gyro_bias_std == default.initial_gyro_bias_std


_SCALE = RunawayScale(0.0625, 0.02)  # checked beyond 4 x 0.0625 = 0.25 m/s^2 removed


def _taken_back_then(v_after_mps, rim_after_mps, removed_mps2=-0.3, scale=_SCALE):
    """A take-back that removed ``removed_mps2`` (pitch and bias parts) at 1.0 m/s north,
    checked against ``scale``, then the INS's forward speed 1 s later; returns the restoring
    error state or None."""
    h = ForwardSpeedHistory((0.0, 0.0, 0.0))
    h.record(0, level_state(v_eb_n=(1.0, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.01)
    dx = np.zeros(N_ERR)
    dx[ATT], dx[BA] = (0.0, 0.02, 0.0), (0.01, 0.0, 0.0)
    h.taken_back(scale, Correction(0.0, removed_mps2, dx),
                 Correction(-0.1, 0.0, np.ones(N_ERR)))
    assert h.take_back_refuted(0.8, np.array([1.0, 0.0, 0.0])) is None  # rim 0.8 noted
    h.record(500_000_000, level_state(v_eb_n=(1.0, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.01)
    assert h.take_back_refuted(0.8, np.array([1.0, 0.0, 0.0])) is None  # not yet 1 s on
    h.record(1_000_000_000, level_state(v_eb_n=(v_after_mps, 0.0, 0.0)), [0.0, 0.0, 0.0], 0.01)
    restore = h.take_back_refuted(rim_after_mps, np.array([1.0, 0.0, 0.0]))
    assert h.take_back_refuted(rim_after_mps, np.array([1.0, 0.0, 0.0])) is None  # once
    return restore


def test_a_take_back_the_ins_runs_away_from_is_restored():
    # removed -0.3 m/s^2 and the INS lost 0.3 m/s in the next second at a steady rim: restore
    # the tilt and bias taken back (the anchor's parts too) and the 0.3 m/s lost
    restore = _taken_back_then(0.7, 0.8)
    assert restore[ATT] == pytest.approx([-1.0, -1.02, -1.0])
    assert restore[BA] == pytest.approx([-1.01, -1.0, -1.0])
    assert restore[VEL] == pytest.approx([-0.3, 0.0, 0.0])  # correct(): v - dx[VEL] = 1.0
    assert not restore[POS].any() and not restore[BG].any()
    # the INS stayed level (a true change), ran away by too much or the other way, or the
    # rim moved (the body may have followed it): kept
    for v_after, rim_after in ((1.0, 0.8), (0.5, 0.8), (1.3, 0.8), (0.7, 0.85)):
        assert _taken_back_then(v_after, rim_after) is None


def test_the_take_back_check_scales_with_the_measured_noise():
    # the scale: the coarser of the 1-s spread per second (0.05) and g times the tilt 1-sigma
    # (0.004 x 10 = 0.04); the rim tolerance is the aid's measured innovation scatter
    assert runaway_scale(0.05 ** 2, 0.004, 10.0, 0.03 ** 2) == pytest.approx((0.05, 0.03))
    assert runaway_scale(0.01 ** 2, 0.006, 10.0, 0.0) == pytest.approx((0.06, 0.0))
    assert TAKE_BACK_CHECK_S == SCALES_S[0]
    # removed exactly RUNAWAY_SIGMA (4) x 0.0625 = 0.25 m/s^2 is checked, and restored when
    # the INS ran away by that; just under it is not checked at all
    assert _taken_back_then(0.75, 0.8, removed_mps2=-0.25) is not None
    assert _taken_back_then(0.75, 0.8, removed_mps2=-0.2499) is None
    # the same take-back on an IMU twice as coarse is within its routine levelling
    coarse = RunawayScale(0.125, 0.02)
    assert _taken_back_then(0.7, 0.8, scale=coarse) is None
    assert _taken_back_then(0.5, 0.8, removed_mps2=-0.5, scale=coarse) is not None
    # the rim: a move just under the measured tolerance is steady, one at it is not
    assert _taken_back_then(0.7, 0.8 - 0.0199) is not None
    assert _taken_back_then(0.7, 0.8 - 0.0201) is None
    assert _taken_back_then(0.7, 0.8 - 0.0201, scale=RunawayScale(0.0625, 0.05)) is not None


def test_a_take_back_at_a_patch_the_body_keeps_slowing_through_is_kept():
    # The traced firing on a true change (sim `measured` seed 3, 427.8 s): a patch of slip 0.6
    # entered over a 3.0-s ramp; the alarm fired 1.7 s in and took back 0.226 m/s^2; over the
    # next second the body kept slowing (0.157 m/s) and the INS with it (0.241 m/s, 1.07 x
    # the rate removed) at a steady rim. The take-back was right (restoring it moved the
    # speed error +0.07 -> +0.31 m/s). That IMU's 1-s spread was 0.060 m/s and g times its
    # tilt 1-sigma 0.049 m/s^2: 0.226 is under 4 x 0.060, not checked, where the constant
    # 0.2 m/s^2 restored it.
    measured = runaway_scale(0.060 ** 2, 0.049 / 9.81, 9.81, 0.028 ** 2)
    assert _taken_back_then(1.0 - 0.241, 0.8, removed_mps2=-0.226, scale=measured) is None
    assert _taken_back_then(1.0 - 0.241, 0.8, removed_mps2=-0.226,
                            scale=RunawayScale(0.2 / RUNAWAY_SIGMA, 0.02)) is not None
    # the false take-backs on ground that never slips were 4.4-9.5 times that IMU's scale
    # (seed 2 at 469.5 s: 0.222 m/s^2 removed, spread 0.051, g tilt 0.052): still restored
    noslip = runaway_scale(0.051 ** 2, 0.052 / 9.81, 9.81, 0.073 ** 2)
    assert _taken_back_then(1.0 - 0.191, 0.8, removed_mps2=-0.222, scale=noslip) is not None
