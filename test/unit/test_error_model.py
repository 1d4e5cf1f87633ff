"""The error-state model against finite differences of the nonlinear mechanization and
measurement functions (Groves' F and our H must describe what the code actually does)."""
import math

import numpy as np
import pytest

from slip_estimator.core.error_model import process_noise, system_matrix
from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.core.mechanization import mechanize
from slip_estimator.core.measurements import (ForwardSpeed, NonHolonomic, WheelYawRate,
                                              ZeroAngularRate, ZeroVelocity)
from slip_estimator.core.planet import EARTH, MARS
from slip_estimator.core.state import N_ERR, NavState, correct, difference

# Error-state scales: rad, m/s, (rad, rad, m), m/s^2, rad/s.
SCALE = np.array([1e-3] * 3 + [1e-2] * 3 + [1e-7, 1e-7, 1e-1] + [1e-2] * 3 + [1e-3] * 3)


def nominal_state(planet=EARTH) -> NavState:
    return NavState(rpy_to_dcm(0.1, -0.2, 2.0), np.array([0.6, -0.4, 0.05]),
                    np.array([math.radians(39.6), math.radians(-79.9), 310.0]),
                    np.array([0.01, -0.02, 0.03]), np.array([1e-3, -2e-3, 5e-4]))


BLOCKS = [slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)]


@pytest.mark.parametrize('planet', [EARTH, MARS])
@pytest.mark.parametrize('src', range(5))
def test_system_matrix_matches_finite_difference_of_mechanization(planet, src):
    """Perturb one error block at a time; every block of F (also the tiny transport-rate
    terms) must predict the error growth of two mechanizations that differ by that error."""
    rng = np.random.default_rng(src)
    f_meas = np.array([0.3, -0.2, -planet.g_equator_mps2])
    w_meas = np.array([0.02, -0.01, 0.3])
    tau = 1e-3
    est = nominal_state(planet)
    f_n = est.C_b_n @ (f_meas - est.b_a)
    F = system_matrix(est, f_n, planet)
    dx0 = np.zeros(N_ERR)
    dx0[BLOCKS[src]] = rng.standard_normal(3) * SCALE[BLOCKS[src]] * 1e-2
    truth = correct(est.copy(), dx0)
    assert np.allclose(difference(est, truth), dx0, rtol=1e-6, atol=1e-18)
    est1, truth1 = est.copy(), truth.copy()
    mechanize(est1, f_meas, w_meas, tau, planet)
    mechanize(truth1, f_meas, w_meas, tau, planet)
    dxdot = (difference(est1, truth1) - dx0) / tau
    expected = F @ dx0
    for dst in BLOCKS:
        scale = np.abs(expected[dst]).max()
        # Allowed: 3 % of the block, the O(tau) discretisation term tau/2 F^2 dx, and the
        # numerical resolution of the finite difference.
        second_order = np.abs(tau * (F @ F @ dx0)[dst]).max()
        floor = 1e-9 * SCALE[dst].max()
        assert np.allclose(dxdot[dst], expected[dst], rtol=0,
                           atol=0.03 * scale + second_order + floor), (
            dst, dxdot[dst], expected[dst])


def _check_jacobian(model_innovation, H, est, rng):
    z0 = model_innovation(est)
    for _ in range(5):
        dx = rng.standard_normal(N_ERR) * SCALE * 1e-3
        truth = correct(est.copy(), dx)
        # innovation(est) - innovation(truth) = h(truth) - h(est) ~ H dx
        lhs = z0 - model_innovation(truth)
        assert np.allclose(lhs, H @ dx, rtol=1e-3, atol=1e-3 * np.abs(H @ dx).max())


def test_zupt_jacobian():
    est = nominal_state()
    _check_jacobian(ZeroVelocity().innovation, ZeroVelocity().jacobian(est), est,
                    np.random.default_rng(2))


def test_zaru_jacobian():
    est = nominal_state()
    m = ZeroAngularRate(EARTH)
    w = np.array([1e-4, -2e-4, 3e-5])
    _check_jacobian(lambda s: m.innovation(s, w), m.jacobian(est), est, np.random.default_rng(3))


def test_zaru_covariance_is_never_below_the_gyro_scatter_in_the_window():
    """R of a mean over T = 0.1 s: the declared white noise N_g^2 / T, or the scatter of single
    samples dt apart over the samples averaged, s^2 dt / T, per axis, whichever is larger."""
    m = ZeroAngularRate(EARTH, 1e-5, 2e-4)
    declared = 1e-10 + 4e-8 / 0.1
    assert np.allclose(m.covariance(0.1), np.eye(3) * declared)
    scatter = np.array([0.02 ** 2, 1e-12, 0.01 ** 2])  # 30 Hz: 3 samples in the mean
    R = m.covariance(0.1, scatter, 1.0 / 30.0)
    assert np.allclose(np.diag(R), [1e-10 + 0.02 ** 2 / 3.0, declared, 1e-10 + 0.01 ** 2 / 3.0])
    assert not R[~np.eye(3, dtype=bool)].any()


@pytest.mark.parametrize('rows', [(1, 2), (2,)])
def test_nhc_jacobian_with_lever_arm(rows):
    est = nominal_state()
    m = NonHolonomic(EARTH, np.array([-0.2, 0.1, 0.3]))
    w = np.array([0.05, -0.02, 0.4])
    _check_jacobian(lambda s: m.innovation(s, w, rows), m.jacobian(est, rows), est,
                    np.random.default_rng(4))


def test_forward_speed_jacobian_with_lever_arm():
    """The wheel aid's model: h(x) is the forward velocity of the wheel-contact point."""
    est = nominal_state()
    l_bw_b = np.array([-0.2, 0.1, 0.3])
    m, point = ForwardSpeed(EARTH, l_bw_b), NonHolonomic(EARTH, l_bw_b)
    w = np.array([0.05, -0.02, 0.4])
    _check_jacobian(lambda s: m.innovation(0.7, point.point_velocity_b(s, w)[0]),
                    m.jacobian(est), est, np.random.default_rng(5))


def test_wheel_yaw_rate_jacobian():
    """The wheel yaw-rate aid: h(x) is the gyro z rate less its bias and the planet rate."""
    est = nominal_state()
    m = WheelYawRate(EARTH)
    _check_jacobian(lambda s: m.innovation(s, 0.3, -0.25), m.jacobian(est), est,
                    np.random.default_rng(6))


def test_wheel_yaw_rate_closed_form():
    """Level, heading north, at latitude L: the gyro z reads -w_ie sin L (FRD) plus its bias
    when the body does not turn, so a wheel differential of zero gives a zero innovation when
    the bias is right and the bias error otherwise; H picks -b_g[2]."""
    L = math.radians(39.6)
    st = NavState(np.eye(3), np.zeros(3), np.array([L, 0.0, 300.0]), np.zeros(3),
                  np.array([0.0, 0.0, 0.004]))
    m = WheelYawRate(EARTH)
    w_z = -EARTH.omega_ie_rps * math.sin(L) + 0.004
    assert m.innovation(st, w_z, 0.0)[0] == pytest.approx(0.0, abs=1e-12)
    assert m.innovation(st, w_z + 0.01, 0.0)[0] == pytest.approx(-0.01)
    assert m.jacobian(st)[0, 14] == -1.0 and np.count_nonzero(m.jacobian(st)[0, 3:14]) == 0


def test_process_noise_is_symmetric_positive_semidefinite():
    est = nominal_state()
    F = system_matrix(est, np.array([0.1, 0.2, -9.8]), EARTH)
    Q = process_noise(est, F, 0.02, 4e-8, 4e-6, 1e-7, 1e-11, EARTH)
    assert np.allclose(Q, Q.T, atol=0)
    assert np.linalg.eigvalsh(Q).min() > -1e-20


def test_process_noise_matches_the_literal_paper_equations():
    """Q is computed with diagonal scalings for speed; eq. 39-47 written literally must agree."""
    from slip_estimator.core.error_model import curvilinear_to_ned
    est = nominal_state()
    F = system_matrix(est, np.array([0.1, 0.2, -9.8]), EARTH)
    t, S_rg, S_ra, S_bad, S_bgd = 0.04, 4e-8, 4e-6, 1e-7, 1e-11
    C, F21, I3 = est.C_b_n, F[3:6, 0:3], np.eye(3)
    T = curvilinear_to_ned(EARTH, est.llh[0], est.llh[2])
    blocks = {
        (0, 0): (S_rg * t + S_bgd * t ** 3 / 3) * I3,
        (1, 0): (S_rg * t ** 2 / 2 + S_bgd * t ** 4 / 4) * F21,
        (1, 1): (S_ra * t + S_bad * t ** 3 / 3) * I3
        + (S_rg * t ** 3 / 3 + S_bgd * t ** 5 / 5) * F21 @ F21.T,
        (2, 0): (S_rg * t ** 3 / 3 + S_bgd * t ** 5 / 5) * T @ F21,
        (2, 1): (S_ra * t ** 2 / 2 + S_bad * t ** 4 / 4) * T
        + (S_rg * t ** 4 / 4 + S_bgd * t ** 6 / 6) * T @ F21 @ F21.T,
        (2, 2): (S_ra * t ** 3 / 3 + S_bad * t ** 5 / 5) * T @ T
        + (S_rg * t ** 5 / 5 + S_bgd * t ** 7 / 7) * T @ F21 @ F21.T @ T,
        (2, 3): S_bad * t ** 3 / 3 * T @ C,
        (2, 4): S_bgd * t ** 4 / 4 * T @ F21 @ C,
        (0, 4): S_bgd * t ** 2 / 2 * C,
        (1, 3): S_bad * t ** 2 / 2 * C,
        (1, 4): S_bgd * t ** 3 / 3 * F21 @ C,
        (3, 3): S_bad * t * I3,
        (4, 4): S_bgd * t * I3,
    }
    Q_ref = np.zeros((N_ERR, N_ERR))
    for (i, j), b in blocks.items():
        Q_ref[3 * i:3 * i + 3, 3 * j:3 * j + 3] = b
        Q_ref[3 * j:3 * j + 3, 3 * i:3 * i + 3] = b.T
    Q = process_noise(est, F, t, S_rg, S_ra, S_bad, S_bgd, EARTH)
    assert np.allclose(Q, Q_ref, rtol=1e-12, atol=0.0)
