"""Error-state system model: system matrix F, transition matrix Phi and process noise Q.

Paper eq. 9-14 and appendix eq. 31-47 (Groves 2013 eq. 14.63-14.72 and 14.80-14.82). The PDF's
garbled entries are taken from Groves: F22 has the third row
``(-2 v_N/R_N', -2 v_E/R_E' - 2 w_ie cos L, 0)`` (eq. 34 lost it), F23 is eq. 36's 3x3 body
(eq. 36 printed a spurious first row), and eq. 44 must read ``T F21 F21^T T``.
Here ``R_N' = R_N(L) + h`` and ``R_E' = R_E(L) + h``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from slip_estimator.core.planet import Planet, radii_of_curvature, surface_gravity
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState


def geocentric_surface_radius(planet: Planet, L_rad: float) -> float:
    """Geocentric radius of the ellipsoid surface r_eS^e(L), m (Groves eq. 2.137)."""
    _, R_E = radii_of_curvature(planet, L_rad)
    return R_E * math.sqrt(math.cos(L_rad) ** 2 + (1.0 - planet.e2) ** 2 * math.sin(L_rad) ** 2)


def curvilinear_to_ned(planet: Planet, L_rad: float, h_m: float) -> np.ndarray:
    """``T_r(n)^p`` (eq. 47): takes a NED displacement (m) to (dL, dlambda, dh)."""
    return np.diag(curvilinear_to_ned_diag(planet, L_rad, h_m))


def curvilinear_to_ned_diag(planet: Planet, L_rad: float, h_m: float) -> np.ndarray:
    """The diagonal of :func:`curvilinear_to_ned` (``T @ x == T_diag * x``)."""
    return np.array(_curvilinear_to_ned_floats(planet, L_rad, h_m))


def _curvilinear_to_ned_floats(planet: Planet, L_rad: float,
                               h_m: float) -> tuple[float, float, float]:
    """:func:`curvilinear_to_ned_diag` as three floats."""
    R_N, R_E = radii_of_curvature(planet, L_rad)
    return 1.0 / (R_N + h_m), 1.0 / ((R_E + h_m) * math.cos(L_rad)), -1.0


def _flat_indices(blocks: tuple[tuple[slice, slice], ...]) -> np.ndarray:
    """Row-major flat indices into a 15x15 matrix of the 3x3 blocks ``(rows, cols)``."""
    return np.array([r * N_ERR + c for rows, cols in blocks
                     for r in range(rows.start, rows.stop) for c in range(cols.start, cols.stop)])


# The non-zero blocks of F in the order system_matrix lists their entries.
_F_BLOCKS = _flat_indices(((ATT, ATT), (ATT, VEL), (ATT, POS), (ATT, BG), (VEL, ATT),
                           (VEL, VEL), (VEL, POS), (VEL, BA), (POS, VEL), (POS, POS)))


def system_matrix(state: NavState, f_ib_n: np.ndarray | Sequence[float],
                  planet: Planet) -> np.ndarray:
    """Continuous-time error-state system matrix F (15x15), paper eq. 9 and 31-38.

    Written as one list of the entries of its non-zero 3x3 blocks (row-major), put into the
    matrix in one operation: F is built at every covariance propagation.
    """
    # The state as floats: after a strapdown step it holds them, and making its arrays here
    # only to read them back as floats cost more than the rest of the float arithmetic.
    C, (vN, vE, vD), (L, _, h) = state.floats()
    fN, fE, fD = f_ib_n.tolist() if isinstance(f_ib_n, np.ndarray) else map(float, f_ib_n)
    w = planet.omega_ie_rps
    R_N, R_E = radii_of_curvature(planet, L)
    RN, RE = R_N + h, R_E + h
    sL, cL, tL = math.sin(L), math.cos(L), math.tan(L)
    # omega_in_n = omega_ie_n + omega_en_n (F11 = -[omega_in_n x]).
    wN, wE, wD = w * cL + vE / RE, -vN / RN, -w * sL - vE * tL / RE
    g0 = surface_gravity(planet, L)
    r_eS = geocentric_surface_radius(planet, L)
    values = [
        # F11 = -[omega_in_n x]
        0.0, wD, -wE,
        -wD, 0.0, wN,
        wE, -wN, 0.0,
        # F12
        0.0, -1.0 / RE, 0.0,
        1.0 / RN, 0.0, 0.0,
        0.0, tL / RE, 0.0,
        # F13
        w * sL, 0.0, vE / RE ** 2,
        0.0, 0.0, -vN / RN ** 2,
        w * cL + vE / (RE * cL ** 2), 0.0, -vE * tL / RE ** 2,
        # F15 = C_b_n
        *C,
        # F21 = -[f_ib_n x]
        0.0, fD, -fE,
        -fD, 0.0, fN,
        fE, -fN, 0.0,
        # F22
        vD / RN, -2.0 * vE * tL / RE - 2.0 * w * sL, vN / RN,
        vE * tL / RE + 2.0 * w * sL, (vN * tL + vD) / RE, vE / RE + 2.0 * w * cL,
        -2.0 * vN / RN, -2.0 * vE / RE - 2.0 * w * cL, 0.0,
        # F23
        -vE ** 2 / (RE * cL ** 2) - 2.0 * vE * w * cL, 0.0,
        vE ** 2 * tL / RE ** 2 - vN * vD / RN ** 2,
        vN * vE / (RE * cL ** 2) + 2.0 * vN * w * cL - 2.0 * vD * w * sL, 0.0,
        -(vN * vE * tL + vE * vD) / RE ** 2,
        2.0 * vE * w * sL, 0.0, vE ** 2 / RE ** 2 + vN ** 2 / RN ** 2 - 2.0 * g0 / r_eS,
        # F24 = C_b_n
        *C,
        # F32 = T_r(n)^p (curvilinear_to_ned)
        1.0 / RN, 0.0, 0.0,
        0.0, 1.0 / (RE * cL), 0.0,
        0.0, 0.0, -1.0,
        # F33
        0.0, 0.0, -vN / RN ** 2,
        vE * sL / (RE * cL ** 2), 0.0, -vE / (RE ** 2 * cL),
        0.0, 0.0, 0.0,
    ]
    F = np.zeros(N_ERR * N_ERR)
    F[_F_BLOCKS] = values
    return F.reshape(N_ERR, N_ERR)


# process_noise computes ten 3x3 blocks of Q as one stack: the eight off-diagonal blocks of one
# triangle (their mirror images are the transposes), then Q22 and Q33 without their diagonal
# terms, which are added with the diagonal of Q22's and Q32's scaled identity parts.
_Q_BLOCKS = ((VEL, ATT), (POS, ATT), (POS, VEL), (POS, BA), (POS, BG), (ATT, BG), (VEL, BA),
             (VEL, BG), (VEL, VEL), (POS, POS))
_Q_FLAT = _flat_indices(_Q_BLOCKS)
_Q_MIRROR = _flat_indices(tuple((c, r) for r, c in _Q_BLOCKS[:8])).reshape(8, 3, 3) \
    .transpose(0, 2, 1).ravel()
_Q_DIAGONAL = np.r_[np.arange(N_ERR) * (N_ERR + 1),  # the diagonal of Q
                    [r * N_ERR + c for r, c in zip(range(6, 9), range(3, 6))],  # diag of Q32
                    [r * N_ERR + c for r, c in zip(range(3, 6), range(6, 9))]]  # diag of Q23


def process_noise(state: NavState, F: np.ndarray, tau_s: float, S_rg: float, S_ra: float,
                  S_bad: float, S_bgd: float, planet: Planet) -> np.ndarray:
    """Discrete process noise Q (paper eq. 14, 39-47).

    Parameters
    ----------
    S_rg, S_ra : gyro / accelerometer white-noise PSD, rad^2/s and m^2/s^3.
    S_bad, S_bgd : accelerometer / gyro bias-variation PSD, m^2/s^5 and rad^2/s^3.

    ``T_r(n)^p`` is diagonal, so products with it are written as row / column scalings. Every
    block is ``coefficient * rows * X`` (Q33 also scaled by columns) with X one of F21,
    F21 F21^T, C, F21 C and rows either T's diagonal or ones, plus a scaled identity or T on
    some diagonals: the blocks are computed as one stack (the covariance propagation runs
    this at every epoch).
    """
    t = tau_s
    t2, t3, t4, t5 = t * t, t ** 3, t ** 4, t ** 5
    C = state.C_b_n
    F21 = F[VEL, ATT]
    L, _, h = state.floats()[2]  # floats: numpy scalars make the arithmetic slower
    T0, T1, T2 = _curvilinear_to_ned_floats(planet, L, h)
    FFt = F21 @ F21.T
    F21C = F21 @ C
    # The coefficient of each block (see _Q_BLOCKS), times its row scale (T's diagonal or
    # one), as floats; Q31 and Q22 share one coefficient.
    c_21 = S_rg * t2 / 2.0 + S_bgd * t4 / 4.0
    c_31 = S_rg * t3 / 3.0 + S_bgd * t5 / 5.0
    c_32 = S_rg * t4 / 4.0 + S_bgd * t ** 6 / 6.0
    c_34, c_35 = S_bad * t3 / 3.0, S_bgd * t4 / 4.0
    c_15, c_24, c_25 = S_bgd * t2 / 2.0, S_bad * t2 / 2.0, S_bgd * t3 / 3.0
    c_33 = S_rg * t5 / 5.0 + S_bgd * t ** 7 / 7.0
    # One flat tuple through np.fromiter (np.array on nested lists of floats took three
    # times as long).
    scale = np.fromiter((c_21, c_21, c_21, c_31 * T0, c_31 * T1, c_31 * T2,
                         c_32 * T0, c_32 * T1, c_32 * T2, c_34 * T0, c_34 * T1, c_34 * T2,
                         c_35 * T0, c_35 * T1, c_35 * T2, c_15, c_15, c_15, c_24, c_24, c_24,
                         c_25, c_25, c_25, c_31, c_31, c_31, c_33 * T0, c_33 * T1, c_33 * T2),
                        float, 30)
    blocks = scale.reshape(10, 3, 1) * np.array([F21, F21, FFt, C, F21C, C, C, F21C, FFt, FFt])
    blocks[9] *= np.array((T0, T1, T2))
    values = blocks.ravel()
    Q = np.zeros(N_ERR * N_ERR)
    Q[_Q_FLAT] = values
    Q[_Q_MIRROR] = values[:72]
    a_att, a_vel = S_rg * t + S_bgd * t3 / 3.0, S_ra * t + S_bad * t3 / 3.0
    a_pos, a_32 = S_ra * t3 / 3.0 + S_bad * t5 / 5.0, S_ra * t2 / 2.0 + S_bad * t4 / 4.0
    a_ba, a_bg = S_bad * t, S_bgd * t
    Q[_Q_DIAGONAL] += np.fromiter((a_att, a_att, a_att, a_vel, a_vel, a_vel,
                                   a_pos * (T0 * T0), a_pos * (T1 * T1), a_pos * (T2 * T2),
                                   a_ba, a_ba, a_ba, a_bg, a_bg, a_bg, a_32 * T0, a_32 * T1,
                                   a_32 * T2, a_32 * T0, a_32 * T1, a_32 * T2), float, 21)
    return Q.reshape(N_ERR, N_ERR)
