"""The fast paths equal the straightforward ones.

* The decimated covariance propagation (``covariance_decimation = 10``, the default) against
  the reference path (``= 1``) on a simulated drive: an approximation, within the stated
  tolerances below.
* Every function rewritten for speed against the literal formulas it replaced: bit-identical
  where the rewrite performs the same floating-point operations (strapdown step, F, Q, window
  variance, Kalman steps, measurement Jacobians, residual monitor, the lag monitor's
  correlation), to round-off where it does not (``odometry()`` on floats, 1e-12 relative).
* The NaN guard gives the same verdicts as the recursive field walk it replaced, and the slip
  messages it no longer checks cannot carry a NaN.

No timing assertions: speed is shown by ``slip-estimator bench``.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from slip_estimator.core import frames, kalman
from slip_estimator.core.detectors import ImuWindow, StationaryDetector
from slip_estimator.core.error_model import (
    curvilinear_to_ned,
    geocentric_surface_radius,
    process_noise,
    system_matrix,
)
from slip_estimator.core.estimator import SlipEstimator
from slip_estimator.core.mechanization import mechanize, mechanize_step, rodrigues
from slip_estimator.core.planet import (
    EARTH,
    MARS,
    earth_rate_n,
    gravity_down,
    llh_to_local_enu,
    radii_of_curvature,
    surface_gravity,
)
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState
from slip_estimator.core.types import SlipEstimate
from slip_estimator.streams import feed, from_simulation, records

# --- decimated propagation vs the reference path ---------------------------------------------
# Tolerances of covariance_decimation = 10 against 1. Observed on this drive: body speed
# 0.4 mm/s median, 1.7 mm/s at the 99th percentile and 2.6 cm/s once, at the sample where the
# rover stops (the zero-velocity update falls on a propagation epoch, up to 40 ms apart in
# the two paths); slip 0.012 while moving; a few slip classes differ at stops.
BODY_SPEED_TOL_P99_MPS = 0.005
BODY_SPEED_TOL_MAX_MPS = 0.05
SLIP_TOL_MOVING = 0.03  # |rim speed| >= MOVING_RIM_MPS; near a stop the ratio is ill-posed
MOVING_RIM_MPS = 0.1
CLASS_AGREEMENT = 0.98


def _slip_estimates(params, recs) -> dict[int, SlipEstimate]:
    return {e.stamp_ns: e for e in feed(SlipEstimator(params), recs)}


def _simulated(scenario, duration_s: float):
    """Parameters and core records of a simulated drive."""
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import sim_params

    result = simulate(scenario.replace(duration_s=duration_s))
    params = sim_params(result)
    return params, list(records(from_simulation(result, params)))


@pytest.fixture(scope='module')
def decimated_and_reference():
    from slip_estimator.sim import short_scenario

    params, recs = _simulated(short_scenario(0), 64.0)
    assert params.covariance_decimation == 10
    fast = _slip_estimates(params, recs)
    reference = _slip_estimates(params.replace(covariance_decimation=1), recs)
    return fast, reference


def test_decimated_propagation_matches_the_reference_path(decimated_and_reference):
    fast, reference = decimated_and_reference
    assert fast.keys() == reference.keys() and len(fast) > 500
    moving = [t for t, e in fast.items() if abs(e.wheel_speed_mps) >= MOVING_RIM_MPS
              and math.isfinite(e.slip_ratio) and math.isfinite(reference[t].slip_ratio)]
    assert len(moving) > 200  # the drive does drive (with medium, high and extreme slip)
    assert max(abs(fast[t].slip_ratio - reference[t].slip_ratio) for t in moving) \
        <= SLIP_TOL_MOVING
    dv = [abs(e.body_speed_mps - reference[t].body_speed_mps) for t, e in fast.items()
          if math.isfinite(e.body_speed_mps) and math.isfinite(reference[t].body_speed_mps)]
    assert np.percentile(dv, 99) <= BODY_SPEED_TOL_P99_MPS
    assert max(dv) <= BODY_SPEED_TOL_MAX_MPS
    same_class = sum(fast[t].slip_class == reference[t].slip_class for t in fast)
    assert same_class >= CLASS_AGREEMENT * len(fast)


def test_reference_comparison_can_fail(decimated_and_reference):
    """Scratch check: a 5 % speed error while moving is outside the tolerances above."""
    _, reference = decimated_and_reference
    moving = [e for e in reference.values() if abs(e.wheel_speed_mps) >= MOVING_RIM_MPS]
    assert np.percentile([abs(e.body_speed_mps * 0.05) for e in moving], 50) \
        > BODY_SPEED_TOL_P99_MPS


# --- strapdown step ----------------------------------------------------------------------------
def mechanize_literal(state: NavState, f_ib_b, omega_ib_b, tau_s, planet):
    """The strapdown step with the planet functions called as written in the papers."""
    L, lam, h = state.llh
    vN, vE, vD = state.v_eb_n
    fx, fy, fz = f_ib_b - state.b_a
    wx, wy, wz = (omega_ib_b - state.b_g) * tau_s
    sL, cL = math.sin(L), math.cos(L)
    w = planet.omega_ie_rps
    R_N, R_E = radii_of_curvature(planet, L)
    RN, RE = R_N + h, R_E + h
    ie_N, ie_D = w * cL, -w * sL
    en_N, en_E, en_D = vE / RE, -vN / RN, -vE * sL / (cL * RE)
    C = state.C_b_n
    R = np.array(rodrigues(wx, wy, wz)).reshape(3, 3)
    oN, oE, oD = (ie_N + en_N) * tau_s, en_E * tau_s, (ie_D + en_D) * tau_s
    Omega = np.array([[0.0, -oD, oE], [oD, 0.0, -oN], [-oE, oN, 0.0]])
    n = np.empty((3, 3))
    for i, j in itertools.product(range(3), range(3)):
        n[i, j] = (C[i, 0] * R[0, j] + C[i, 1] * R[1, j] + C[i, 2] * R[2, j]
                   - (Omega[i, 0] * C[0, j] + Omega[i, 1] * C[1, j] + Omega[i, 2] * C[2, j]))
    f_n = [0.5 * ((C[i, 0] + n[i, 0]) * fx + (C[i, 1] + n[i, 1]) * fy
                  + (C[i, 2] + n[i, 2]) * fz) for i in range(3)]
    gD = gravity_down(planet, L, h)
    aN, aE, aD = en_N + 2.0 * ie_N, en_E, en_D + 2.0 * ie_D
    cor = (aE * vD - aD * vE, aD * vN - aN * vD, aN * vE - aE * vN)
    vN1 = vN + (f_n[0] - cor[0]) * tau_s
    vE1 = vE + (f_n[1] - cor[1]) * tau_s
    vD1 = vD + (f_n[2] + gD - cor[2]) * tau_s
    h1 = h - 0.5 * tau_s * (vD + vD1)
    L1 = L + 0.5 * tau_s * (vN / RN + vN1 / (R_N + h1))
    _, R_E1 = radii_of_curvature(planet, L1)
    lam1 = lam + 0.5 * tau_s * (vE / (RE * cL) + vE1 / ((R_E1 + h1) * math.cos(L1)))
    return n, np.array([vN1, vE1, vD1]), np.array([L1, lam1, h1]), np.array(f_n)


def random_state(rng: np.random.Generator) -> NavState:
    return NavState(frames.rpy_to_dcm(*rng.uniform(-math.pi, math.pi, 3)),
                    rng.normal(0.0, 1.0, 3), np.array([rng.uniform(-1.4, 1.4),
                                                       rng.uniform(-3.0, 3.0),
                                                       rng.uniform(-100.0, 3000.0)]),
                    rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.005, 3))


@pytest.mark.parametrize('planet', [EARTH, MARS])
def test_mechanize_step_equals_the_literal_formulas(planet):
    """Cached planet constants and the shared sin L give the same numbers to the bit."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        state = random_state(rng)
        f, w = rng.normal(0.0, 3.0, 3) + [0.0, 0.0, -9.8], rng.normal(0.0, 0.5, 3)
        tau = rng.uniform(1e-3, 2e-2)
        C, v, llh, f_n = mechanize_literal(state.copy(), f, w, tau, planet)
        fast = state.copy()
        assert np.array_equal(mechanize(fast, f, w, tau, planet), f_n)
        assert np.array_equal(fast.C_b_n, C) and np.array_equal(fast.v_eb_n, v)
        assert np.array_equal(fast.llh, llh)
        assert mechanize_step(state.copy(), f.tolist(), w.tolist(), tau, planet) \
            == tuple(f_n.tolist())


def test_nav_state_floats_and_arrays_are_one_state():
    """The strapdown step writes floats; reading an attribute makes its array, which is then
    the state (changed in place, the next step starts from the change). A chain of steps
    with reads and in-place changes in between equals the literal step on arrays, to the
    bit."""
    rng = np.random.default_rng(17)
    state = random_state(rng)
    ref = state.copy()
    for k in range(60):
        f, w = rng.normal(0.0, 3.0, 3) + [0.0, 0.0, -9.8], rng.normal(0.0, 0.5, 3)
        tau = rng.uniform(1e-3, 2e-2)
        f_n = mechanize_step(state, f.tolist(), w.tolist(), tau, MARS)
        ref.C_b_n, ref.v_eb_n, ref.llh, f_n_ref = mechanize_literal(ref, f, w, tau, MARS)
        assert f_n == tuple(f_n_ref.tolist())
        C, v, llh = state.floats()
        assert list(C) == ref.C_b_n.ravel().tolist() and list(v) == ref.v_eb_n.tolist()
        assert list(llh) == ref.llh.tolist()
        if k % 3 == 1:  # an array read, then a change in place
            state.v_eb_n[k % 3] += 0.25
            ref.v_eb_n[k % 3] += 0.25
        if k % 5 == 2:
            state.C_b_n[0, 1] *= 1.0 + 1e-9
            ref.C_b_n[0, 1] *= 1.0 + 1e-9
            state.llh[2] -= 1.0
            ref.llh[2] -= 1.0
    for name in ('C_b_n', 'v_eb_n', 'llh', 'b_a', 'b_g'):
        assert np.array_equal(getattr(state, name), getattr(ref, name)), name
    assert repr(state) == repr(ref)


# --- error model -------------------------------------------------------------------------------
def system_matrix_blocks(state: NavState, f_ib_n, planet) -> np.ndarray:
    """F assembled block by block (paper eq. 31-38), as it was written before."""
    L, _, h = state.llh
    vN, vE, vD = state.v_eb_n
    w = planet.omega_ie_rps
    R_N, R_E = radii_of_curvature(planet, L)
    RN, RE = R_N + h, R_E + h
    sL, cL, tL = math.sin(L), math.cos(L), math.tan(L)
    w_in_n = np.array([w * cL + vE / RE, -vN / RN, -w * sL - vE * tL / RE])
    F = np.zeros((N_ERR, N_ERR))
    F[ATT, ATT] = -frames.skew(w_in_n)
    F[ATT, VEL] = [[0.0, -1.0 / RE, 0.0], [1.0 / RN, 0.0, 0.0], [0.0, tL / RE, 0.0]]
    F[ATT, POS] = [[w * sL, 0.0, vE / RE ** 2], [0.0, 0.0, -vN / RN ** 2],
                   [w * cL + vE / (RE * cL ** 2), 0.0, -vE * tL / RE ** 2]]
    F[ATT, BG] = state.C_b_n
    F[VEL, ATT] = -frames.skew(np.asarray(f_ib_n))
    F[VEL, VEL] = [[vD / RN, -2.0 * vE * tL / RE - 2.0 * w * sL, vN / RN],
                   [vE * tL / RE + 2.0 * w * sL, (vN * tL + vD) / RE, vE / RE + 2.0 * w * cL],
                   [-2.0 * vN / RN, -2.0 * vE / RE - 2.0 * w * cL, 0.0]]
    g0, r_eS = surface_gravity(planet, L), geocentric_surface_radius(planet, L)
    F[VEL, POS] = [
        [-vE ** 2 / (RE * cL ** 2) - 2.0 * vE * w * cL, 0.0,
         vE ** 2 * tL / RE ** 2 - vN * vD / RN ** 2],
        [vN * vE / (RE * cL ** 2) + 2.0 * vN * w * cL - 2.0 * vD * w * sL, 0.0,
         -(vN * vE * tL + vE * vD) / RE ** 2],
        [2.0 * vE * w * sL, 0.0, vE ** 2 / RE ** 2 + vN ** 2 / RN ** 2 - 2.0 * g0 / r_eS]]
    F[VEL, BA] = state.C_b_n
    F[POS, VEL] = curvilinear_to_ned(planet, L, h)
    F[POS, POS] = [[0.0, 0.0, -vN / RN ** 2],
                   [vE * sL / (RE * cL ** 2), 0.0, -vE / (RE ** 2 * cL)], [0.0, 0.0, 0.0]]
    return F


def process_noise_blocks(state, F, t, S_rg, S_ra, S_bad, S_bgd, planet) -> np.ndarray:
    """Q assembled block by block with T as row/column scalings, as it was written before."""
    t2, t3, t4, t5 = t * t, t ** 3, t ** 4, t ** 5
    C, F21, I3 = state.C_b_n, F[VEL, ATT], np.eye(3)
    Td = np.diag(curvilinear_to_ned(planet, state.llh[0], state.llh[2]))
    Tc = Td[:, None]
    FFt, F21C = F21 @ F21.T, F21 @ C
    a_rg2, a_rg3 = S_rg * t2 / 2.0 + S_bgd * t4 / 4.0, S_rg * t3 / 3.0 + S_bgd * t5 / 5.0
    Q = np.zeros((N_ERR, N_ERR))
    Q[ATT, ATT] = (S_rg * t + S_bgd * t3 / 3.0) * I3
    Q[VEL, VEL] = (S_ra * t + S_bad * t3 / 3.0) * I3 + a_rg3 * FFt
    Q[POS, POS] = ((S_ra * t3 / 3.0 + S_bad * t5 / 5.0) * np.diag(Td * Td)
                   + (S_rg * t5 / 5.0 + S_bgd * t ** 7 / 7.0) * Tc * FFt * Td)
    Q[BA, BA] = S_bad * t * I3
    Q[BG, BG] = S_bgd * t * I3
    for (r, c), block in (
            ((VEL, ATT), a_rg2 * F21), ((POS, ATT), a_rg3 * Tc * F21),
            ((POS, VEL), (S_ra * t2 / 2.0 + S_bad * t4 / 4.0) * np.diag(Td)
             + (S_rg * t4 / 4.0 + S_bgd * t ** 6 / 6.0) * Tc * FFt),
            ((POS, BA), S_bad * t3 / 3.0 * Tc * C), ((POS, BG), S_bgd * t4 / 4.0 * Tc * F21C),
            ((ATT, BG), S_bgd * t2 / 2.0 * C), ((VEL, BA), S_bad * t2 / 2.0 * C),
            ((VEL, BG), S_bgd * t3 / 3.0 * F21C)):
        Q[r, c] = block
        Q[c, r] = block.T
    return Q


@pytest.mark.parametrize('planet', [EARTH, MARS])
def test_system_matrix_and_process_noise_equal_the_block_formulas(planet):
    rng = np.random.default_rng(11)
    for _ in range(100):
        state = random_state(rng)
        f_n = rng.normal(0.0, 3.0, 3) + [0.0, 0.0, -9.8]
        F = system_matrix(state, f_n, planet)
        assert np.array_equal(F, system_matrix_blocks(state, f_n, planet))
        assert np.array_equal(system_matrix(state, tuple(f_n.tolist()), planet), F)
        args = (rng.uniform(1e-3, 0.1), *rng.uniform(1e-12, 1e-4, 4))
        assert np.array_equal(process_noise(state, F, *args, planet),
                              process_noise_blocks(state, F, *args, planet))


# --- detector window ---------------------------------------------------------------------------
def test_imu_window_statistics_equal_numpy():
    """Queued samples, the oldest-first buffer and the cached variance give exactly
    ``samples().var(axis=0)`` of the last n samples, in any interleaving of adds and reads."""
    rng = np.random.default_rng(3)
    size = 25
    win, det = ImuWindow(size), StationaryDetector(size, 0.05, 0.01, 0.005, 10 ** 9)
    history: list[np.ndarray] = []
    for k in range(400):
        row = rng.normal(0.0, [0.02, 0.03, 0.04, 0.004, 0.005, 0.02]) + [0, 0, -9.8, 0, 0, 0]
        if k == 150:
            row = row * 10.0  # a jolt: not steady for a window
        history.append(row)
        win.add(row[:3].tolist(), row[3:].tolist())
        det.add_imu(row[:3], row[3:])  # arrays are accepted too
        if k % 7 == 0 or rng.uniform() < 0.2:
            expect = np.array(history[-size:])
            assert win.n == len(expect) and np.array_equal(win.samples(), expect)
            assert np.array_equal(win.variance(), expect.var(axis=0))
            std = expect.std(axis=0)
            steady = bool(len(expect) == size and std[:3].max() <= 0.05
                          and std[3:].max() <= 0.01)
            assert det.imu_steady() == steady
    win.clear()
    assert win.n == 0 and not win.full


# --- odometry ----------------------------------------------------------------------------------
def quaternion_of(C: np.ndarray) -> np.ndarray:
    """Shepperd's method on a matrix (numpy), as dcm_to_quat_wxyz was written before."""
    tr = C[0, 0] + C[1, 1] + C[2, 2]
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = np.array([0.25 * s, (C[2, 1] - C[1, 2]) / s, (C[0, 2] - C[2, 0]) / s,
                      (C[1, 0] - C[0, 1]) / s])
    elif C[0, 0] > C[1, 1] and C[0, 0] > C[2, 2]:
        s = 2.0 * math.sqrt(1.0 + C[0, 0] - C[1, 1] - C[2, 2])
        q = np.array([(C[2, 1] - C[1, 2]) / s, 0.25 * s, (C[0, 1] + C[1, 0]) / s,
                      (C[0, 2] + C[2, 0]) / s])
    elif C[1, 1] > C[2, 2]:
        s = 2.0 * math.sqrt(1.0 + C[1, 1] - C[0, 0] - C[2, 2])
        q = np.array([(C[0, 2] - C[2, 0]) / s, (C[0, 1] + C[1, 0]) / s, 0.25 * s,
                      (C[1, 2] + C[2, 1]) / s])
    else:
        s = 2.0 * math.sqrt(1.0 + C[2, 2] - C[0, 0] - C[1, 1])
        q = np.array([(C[1, 0] - C[0, 1]) / s, (C[0, 2] + C[2, 0]) / s,
                      (C[1, 2] + C[2, 1]) / s, 0.25 * s])
    q /= np.linalg.norm(q)
    return q if q[0] >= 0.0 else -q


def odometry_matrices(est: SlipEstimator):
    """fused_odometry() as matrix formulas: p, q, v, w, pose and twist covariance."""
    st = est.state
    r_bw_n = st.C_b_n @ est.l_bw_b
    T = curvilinear_to_ned(est.planet, st.llh[0], st.llh[2])
    p_o = llh_to_local_enu(est.planet, st.llh + T @ r_bw_n, est.odom_frame.llh0)
    C_base_odom = frames.C_ENU_NED @ st.C_b_n @ frames.C_FLU_FRD
    w_b = est.omega_ib_b - st.b_g - st.C_b_n.T @ earth_rate_n(est.planet, st.llh[0])
    v_b = st.C_b_n.T @ st.v_eb_n + np.cross(w_b, est.l_bw_b)
    M = np.zeros((6, 6))
    M[:3, :3] = frames.C_ENU_NED @ np.linalg.inv(T)
    M[3:, 3:] = frames.C_ENU_NED
    idx = np.r_[POS, ATT]
    pose = M @ est.filter.P[np.ix_(idx, idx)] @ M.T
    M[:3, :3] = frames.C_FLU_FRD @ st.C_b_n.T
    M[3:, 3:] = frames.C_FLU_FRD
    idx = np.r_[VEL, BG]
    twist = M @ est.filter.P[np.ix_(idx, idx)] @ M.T
    twist[3:, 3:] += np.eye(3) * est.params.gyro_noise_density_rps_rthz ** 2 / est.imu_rate.dt_s
    return (p_o, quaternion_of(C_base_odom), frames.C_FLU_FRD @ v_b, frames.C_FLU_FRD @ w_b,
            kalman.symmetrize(pose), kalman.symmetrize(twist))


def test_odometry_equals_the_matrix_formulas():
    """fused_odometry() on floats (scaled-permutation covariance, Shepperd quaternion) against the
    matrix formulas, with a lever arm, along a simulated drive: equal to round-off."""
    from slip_estimator.sim import short_scenario

    params, recs = _simulated(short_scenario(2), 30.0)
    params = params.replace(imu_to_base_xyz=(0.12, -0.05, 0.3))
    est = SlipEstimator(params)
    count = [0, 0]  # IMU samples, checked

    def check(_sample) -> None:
        count[0] += 1
        if (count[0] - 1) % 97 or not est.aligned:
            return
        odo = est.fused_odometry()
        p, q, v, w, pose, twist = odometry_matrices(est)
        for fast, ref in ((odo.p_ob_o, p), (odo.q_ob_wxyz, q),
                          (odo.v_ob_b, v), (odo.omega_ob_b, w),
                          (odo.pose_covariance, pose), (odo.twist_covariance, twist)):
            np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=1e-14 * np.abs(ref).max())
        count[1] += 1

    feed(est, recs, check)
    assert count[1] > 40


def test_quaternion_of_every_branch():
    """Shepperd's four branches on floats against the matrix version and the inverse map."""
    rng = np.random.default_rng(5)
    for angle, axis in itertools.product((0.1, 2.0, math.pi - 1e-3, math.pi),
                                         np.eye(3).tolist() + [rng.normal(size=3)]):
        C = frames.rotvec_to_dcm(angle * np.asarray(axis) / np.linalg.norm(axis))
        q = frames.dcm_to_quat_wxyz(C)
        np.testing.assert_allclose(q, quaternion_of(C), rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(frames.quat_wxyz_to_dcm(q), C, atol=1e-14)


# --- NaN guard -----------------------------------------------------------------------------------
_INT_TYPES = frozenset({'boolean', 'octet', 'char', 'byte', 'int8', 'uint8', 'int16', 'uint16',
                        'int32', 'uint32', 'int64', 'uint64', 'builtin_interfaces/Time',
                        'builtin_interfaces/Duration'})


def message_is_finite_walk(msg) -> bool:
    """The guard as a plain recursive walk over the fields (how it was written before)."""
    from slip_estimator.ros.finite import text_is_finite

    for name, kind in msg.get_fields_and_field_types().items():
        if kind.split('[')[0].removeprefix('sequence<').rstrip('>') in _INT_TYPES:
            continue
        value = getattr(msg, name)
        items = value if isinstance(value, (list, tuple)) or type(value).__name__ == 'array' \
            else [value]
        if isinstance(value, np.ndarray):
            if value.dtype.kind == 'f' and not np.isfinite(value).all():
                return False
            continue
        for item in items:
            if isinstance(item, float) and not math.isfinite(item):
                return False
            if isinstance(item, str) and not text_is_finite(item):
                return False
            if hasattr(item, 'get_fields_and_field_types') and not message_is_finite_walk(item):
                return False
    return True


def _sample_messages():
    from slip_estimator.core.types import Health, OdometryEstimate
    from slip_estimator.ros import publish

    odo = OdometryEstimate(1_234_567_890_123, np.array([1.0, -2.0, 3.0]),
                           np.array([0.5, 0.5, -0.5, 0.5]), np.array([0.1, 0.2, 0.3]),
                           np.array([-0.01, 0.02, -0.03]), np.eye(6), 2.0 * np.eye(6))
    est = SlipEstimate(1_000, 0.1, 0.01, 1, 0.5, 0.01, 0.55, 0.05, 0.15)
    health = Health(1, 'running: suspected: something', {'a': 1.5, 'b': [0.1, 0.2], 'c': 3})
    return {
        'odometry': lambda: publish.odometry_to_msg(odo, 'odom', 'base_link'),
        'slip': lambda: publish.slip_to_diagnostic_array(est, 'base_link'),
        'ratio': lambda: publish.slip_to_vector3(est, 'base_link'),
        'health': lambda: publish.health_to_diagnostic_array(health, 5, 'base_link'),
    }


def _corruptions(msg):
    """(path, value) pairs that put a non-finite float or text in each kind of field."""
    from nav_msgs.msg import Odometry

    if isinstance(msg, Odometry):
        yield from ((('pose', 'pose', 'position', 'x'), math.nan),
                    (('pose', 'pose', 'orientation', 'w'), math.inf),
                    (('twist', 'twist', 'angular', 'z'), -math.inf),
                    (('child_frame_id',), 'nan'), (('header', 'frame_id'), ' -Infinity'))
        yield (('pose', 'covariance', 7), math.nan)
        yield (('twist', 'covariance', 35), math.inf)
    elif hasattr(msg, 'vector'):
        yield from ((('vector', 'x'), math.nan), (('vector', 'z'), math.inf),
                    (('header', 'frame_id'), 'inf'))
    else:
        yield from ((('status', 0, 'message'), 'NaN'), (('status', 0, 'values', 2, 'value'),
                                                          '1e999'),
                    (('status', 0, 'values', 0, 'key'), '-nan'),
                    (('status', 0, 'hardware_id'), 'inf'))


def _set(msg, path, value):
    obj = msg
    for key in path[:-1]:
        obj = obj[key] if isinstance(key, int) else getattr(obj, key)
    if isinstance(path[-1], int):
        obj[path[-1]] = value
    else:
        setattr(obj, path[-1], value)


def test_guard_gives_the_verdicts_of_the_field_walk():
    from slip_estimator.ros.finite import message_is_finite

    for name, make in _sample_messages().items():
        msg = make()
        assert message_is_finite(msg) and message_is_finite_walk(msg), name
        corruptions = list(_corruptions(msg))
        assert corruptions, name
        for path, value in corruptions:
            bad = make()
            _set(bad, path, value)
            assert not message_is_finite_walk(bad), (name, path)
            assert not message_is_finite(bad), (name, path)
    # Huge but finite values overflow a sum of squares; the guard then checks each element.
    huge = _sample_messages()['odometry']()
    huge.pose.covariance[0] = 1e300
    huge.pose.pose.position.x = 1.7e308
    huge.pose.pose.position.y = 1.7e308
    assert message_is_finite(huge) and message_is_finite_walk(huge)


def test_text_is_finite_agrees_with_float():
    from slip_estimator.ros.finite import text_is_finite

    for text in ('nan', 'NaN', ' -inf', '+Infinity', '1e999', '-1e999 ', 'odom', 'base_link',
                 '0.5', 'unknown', '.5', '\u0661e999', ' nan ', 'inf', 'in', '', 'x' * 20,
                 'true', '12', '-0'):
        try:
            expect = not text or math.isfinite(float(text)) if len(text) <= 12 else True
        except ValueError:
            expect = True
        assert text_is_finite(text) == expect, text


def test_slot_built_messages_equal_the_constructed_ones(monkeypatch):
    """msgbuild.build writes message slots directly; every output converter gives the same
    message (equal, same repr, same fields after serialisation) as through the generated
    constructors."""
    from rclpy.serialization import deserialize_message, serialize_message

    from slip_estimator.ros import convert, msgbuild, publish

    assert msgbuild.FAST_BUILD  # the slot builder is in use on this ROS distribution
    stamps = (1_234_567_890_123, -1_500_000_000, 0)

    def outputs():
        out = []
        for stamp in stamps:
            out += [make() for make in _sample_messages().values()]
            out.append(publish.stale_diagnostic_array('no IMU data', stamp, 'base_link',
                                                      {'x': 1.0, 'y': 'text'}))
            out.append(convert.ns_to_stamp(stamp))
        return out

    fast = outputs()
    monkeypatch.setattr(msgbuild, 'FAST_BUILD', False)
    reference = outputs()
    assert len(fast) == len(reference)
    for a, b in zip(fast, reference):
        assert a == b and repr(a) == repr(b)
        # Bytes are compared through a round trip: rclpy leaves CDR padding bytes
        # uninitialised, so two serialisations of one message may differ in them.
        assert deserialize_message(serialize_message(a), type(b)) == b
    assert (fast[-1].sec, fast[-1].nanosec) == (0, 0)
    assert (fast[-7].sec, fast[-7].nanosec) == (-2, 500_000_000)


@pytest.mark.parametrize('field', ['slip_ratio', 'slip_ratio_std', 'body_speed_mps',
                                   'body_speed_std_mps', 'wheel_speed_mps', 'slip_ratio_left',
                                   'slip_ratio_right', 'p_medium_or_worse'])
@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
def test_slip_messages_are_finite_by_construction(field, bad):
    """The adapter publishes slip messages without the guard: whatever non-finite value a
    SlipEstimate carries, the messages built from it have none."""
    from dataclasses import replace

    from slip_estimator.ros.finite import message_is_finite
    from slip_estimator.ros.publish import slip_to_diagnostic_array, slip_to_vector3

    for cls in (-1, 0, 2, 4):
        est = replace(SlipEstimate(1_000, 0.1, 0.01, cls, 0.5, 0.01, 0.55, 0.05, 0.15),
                      **{field: bad})
        diag = slip_to_diagnostic_array(est, 'base_link')
        assert message_is_finite_walk(diag) and message_is_finite(diag)
        vec = slip_to_vector3(est, 'base_link')
        assert vec is None or (message_is_finite_walk(vec) and message_is_finite(vec))


def test_adapter_checks_slip_messages_when_the_frame_reads_as_nan():
    """The one way a slip message could carry a non-finite text: the frame name."""
    from slip_estimator.core.params import Params
    from slip_estimator.ros.adapter import SlipEstimatorAdapter
    from slip_estimator.ros.topics import TOPIC_SLIP

    for frame, dropped in (('base_link', 0), ('nan', 1)):
        adapter = SlipEstimatorAdapter(Params(base_frame=frame))
        out = adapter.slip_messages([SlipEstimate(1, 0.1, 0.01, 1, 0.5, 0.01, 0.55)])
        assert adapter.counters.dropped_non_finite[TOPIC_SLIP] == dropped
        assert len(out) == 2 - 2 * dropped


# --- Kalman steps ------------------------------------------------------------------------------
def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


@pytest.mark.parametrize('consider', [None, [2, 14]])
def test_kalman_steps_equal_the_literal_formulas(consider):
    """predict and update (in-place sums, halving in place) give the textbook expressions to
    the bit: ``sym(Phi P Phi^T + Q)``, Joseph form with the gain from np.linalg.solve."""
    rng = np.random.default_rng(19)
    eye = np.eye(N_ERR)
    for m in (1, 2, 3):
        for _ in range(60):
            A = rng.normal(size=(N_ERR, N_ERR))
            P = A @ A.T + rng.uniform(1e-6, 1.0) * eye
            Phi = eye + rng.normal(0.0, 0.05, (N_ERR, N_ERR))
            Q = np.diag(rng.uniform(1e-9, 1e-3, N_ERR))
            assert np.array_equal(kalman.predict(P, Phi, Q), _sym(Phi @ P @ Phi.T + Q))
            assert np.array_equal(kalman.symmetrize(P + A), _sym(P + A))
            H, nu = rng.normal(size=(m, N_ERR)), rng.normal(size=m)
            R = np.diag(rng.uniform(1e-4, 1.0, m))
            dx, P_new, rec = kalman.update(P, nu, H, R, consider=consider)
            PHt = P @ H.T
            S = _sym(H @ PHt + R)
            K = np.linalg.solve(S, PHt.T).T
            if consider is not None:
                K[consider, :] = 0.0
            IKH = eye - K @ H
            assert np.array_equal(rec.S, S) and rec.nis == float(nu @ np.linalg.solve(S, nu))
            assert np.array_equal(dx, K @ nu)
            assert np.array_equal(P_new, _sym(IKH @ P @ IKH.T + K @ R @ K.T))


# --- Kalman solve ------------------------------------------------------------------------------
def test_kalman_solve_equals_numpy_and_raises_where_it_does():
    rng = np.random.default_rng(13)
    for m in (1, 2, 3):
        for _ in range(200):
            A = rng.normal(size=(m, m))
            S = A @ A.T + rng.uniform(1e-6, 1.0) * np.eye(m)
            b, B = rng.normal(size=m), rng.normal(size=(m, N_ERR))
            assert np.array_equal(kalman.solve(S, b), np.linalg.solve(S, b))
            assert np.array_equal(kalman.solve(S, B), np.linalg.solve(S, B))
    with pytest.raises(np.linalg.LinAlgError), np.errstate(invalid='ignore'):
        kalman.solve(np.zeros((2, 2)), np.ones(2))
    nan = kalman.solve(np.full((1, 1), np.nan), np.ones(1))
    assert np.isnan(nan).all()


# --- measurement Jacobians, residual monitor ---------------------------------------------------
def test_measurement_rows_and_skew_equal_the_literal_forms():
    """``skew`` of an array equals that of its floats; the NHC Jacobian's rows (a slice where
    they are consecutive) equal the fancy-indexed rows of the full matrix; ZUPT and ZARU
    carry -I where the literal forms put ``-np.eye(3)``."""
    from slip_estimator.core.measurements import NonHolonomic, ZeroAngularRate, ZeroVelocity

    rng = np.random.default_rng(23)
    for _ in range(50):
        state = random_state(rng)
        v = rng.normal(size=3)
        x, y, z = v.tolist()
        literal = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
        assert np.array_equal(frames.skew(v), literal)
        assert np.array_equal(frames.skew(v.tolist()), literal)
        nhc = NonHolonomic(EARTH, rng.normal(0.0, 0.3, 3))
        full = nhc.jacobian(state, (0, 1, 2))
        w_ib_b = rng.normal(0.0, 0.3, 3)
        v_full = nhc.innovation(state, w_ib_b, (0, 1, 2))
        for rows in ((0,), (1, 2), (2,), (0, 2), (0, 1)):
            assert np.array_equal(nhc.jacobian(state, rows), full[list(rows)])
            assert np.array_equal(nhc.innovation(state, w_ib_b, rows), v_full[list(rows)])
        C_n_b = state.C_b_n.T
        assert np.array_equal(full[:, ATT], -C_n_b @ frames.skew(state.v_eb_n))
        zaru = ZeroAngularRate(EARTH).jacobian(state)
        assert np.array_equal(zaru[:, ATT], C_n_b @ frames.skew(
            earth_rate_n(EARTH, state.llh[0])))
        assert np.array_equal(zaru[:, BG], -np.eye(3))
        assert np.array_equal(ZeroVelocity().jacobian(state)[:, VEL], -np.eye(3))


def test_residual_monitor_rows_equal_one_update_per_row():
    """An update with one channel per row moves every channel as one single-row update
    per row (the monitor's former path, slicing the arrays row by row)."""
    from slip_estimator.core.diagnosis import ResidualMonitor

    rng = np.random.default_rng(29)
    by_rows, one_by_one = ResidualMonitor(), ResidualMonitor()
    for _ in range(200):
        A = rng.normal(size=(2, 2))
        S, nu = A @ A.T + 1e-3 * np.eye(2), rng.normal(size=2)
        by_rows.add_update('nhc', nu, S, ('nhc_lateral', 'nhc_vertical'))
        for i, channel in enumerate(('nhc_lateral', 'nhc_vertical')):
            one_by_one.add(channel, nu[i:i + 1], S[i:i + 1, i:i + 1])
        by_rows.add_update('zupt', nu, S)
        one_by_one.add('zupt', nu, S)
    assert by_rows.mean == one_by_one.mean and by_rows.count == one_by_one.count
    assert np.array_equal(list(by_rows.mean_square.values()),
                          list(one_by_one.mean_square.values()), equal_nan=True)


# --- wheel/IMU lag monitor ---------------------------------------------------------------------
def correlation_vs_lag_literal(t_fast, x_fast, t_slow, y, lags, window_s=0.1):
    """The lag loop as first written: per lag, np.std and np.corrcoef."""
    c = np.concatenate([[0.0], np.cumsum(x_fast)])
    out = np.full(len(lags), np.nan)
    for k, lag in enumerate(lags):
        tq = t_slow - lag
        i0 = np.searchsorted(t_fast, tq - 0.5 * window_s)
        i1 = np.searchsorted(t_fast, tq + 0.5 * window_s)
        ok = i1 > i0
        if ok.sum() < 3:
            continue
        mean = (c[i1[ok]] - c[i0[ok]]) / (i1[ok] - i0[ok])
        if mean.std() > 0.0 and y[ok].std() > 0.0:
            out[k] = float(np.corrcoef(mean, y[ok])[0, 1])
    return out


def test_lag_correlation_equals_the_per_lag_formulas():
    """Every lag at once, the correlation and the spread test without np.corrcoef and
    np.std: bit-identical, also where windows are empty at the ends, the wheel series is
    constant or has too few samples in reach."""
    from slip_estimator.core.timing import _spread, correlation_vs_lag

    rng = np.random.default_rng(31)
    lags = np.arange(-0.4, 0.4 + 1e-9, 0.01)
    for trial in range(40):
        t_fast = np.sort(rng.uniform(0.0, 30.0, rng.integers(200, 1600)))
        t_slow = np.sort(rng.uniform(-1.0, 31.0, rng.integers(3, 320)))
        x = np.sin(t_fast * rng.uniform(0.2, 2.0)) + rng.normal(0.0, 0.3, len(t_fast))
        y = np.sin(t_slow - 0.05) + rng.normal(0.0, 0.3, len(t_slow))
        if trial % 5 == 0:
            y = np.full(len(t_slow), 0.1)
        assert np.array_equal(correlation_vs_lag(t_fast, x, t_slow, y, lags),
                              correlation_vs_lag_literal(t_fast, x, t_slow, y, lags),
                              equal_nan=True)
    # The mean of equal values need not be exact (0.1 * 7 / 7): np.std then is not 0.
    for x in ([0.1] * 7, [0.1] * 3 + [0.3], [1.0] * 5, [0.0, 0.0], [1.0, float('nan')],
              [1e-170, 0.0, 0.0]):
        a = np.array(x)
        assert _spread(a) == bool(a.std() > 0.0)
