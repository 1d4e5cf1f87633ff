"""Error-state system model: system matrix F, transition matrix Phi and process noise Q.

Paper eq. 9-14 and appendix eq. 31-47 (Groves 2013 eq. 14.63-14.72 and 14.80-14.82). The PDF's
garbled entries are taken from Groves: F22 has the third row
``(-2 v_N/R_N', -2 v_E/R_E' - 2 w_ie cos L, 0)`` (eq. 34 lost it), F23 is eq. 36's 3x3 body
(eq. 36 printed a spurious first row), and eq. 44 must read ``T F21 F21^T T``.
Here ``R_N' = R_N(L) + h`` and ``R_E' = R_E(L) + h``.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.frames import skew
from slip_estimator.core.planet import Planet, radii_of_curvature, surface_gravity
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState


def geocentric_surface_radius(planet: Planet, L_rad: float) -> float:
    """Geocentric radius of the ellipsoid surface r_eS^e(L), m (Groves eq. 2.137)."""
    _, R_E = radii_of_curvature(planet, L_rad)
    return R_E * math.sqrt(math.cos(L_rad) ** 2 + (1.0 - planet.e2) ** 2 * math.sin(L_rad) ** 2)


def curvilinear_to_ned(planet: Planet, L_rad: float, h_m: float) -> np.ndarray:
    """``T_r(n)^p`` (eq. 47): takes a NED displacement (m) to (dL, dlambda, dh)."""
    R_N, R_E = radii_of_curvature(planet, L_rad)
    return np.diag([1.0 / (R_N + h_m), 1.0 / ((R_E + h_m) * math.cos(L_rad)), -1.0])


def system_matrix(state: NavState, f_ib_n: np.ndarray, planet: Planet) -> np.ndarray:
    """Continuous-time error-state system matrix F (15x15), paper eq. 9 and 31-38."""
    L, _, h = state.llh
    vN, vE, vD = state.v_eb_n
    w = planet.omega_ie_rps
    R_N, R_E = radii_of_curvature(planet, L)
    RN, RE = R_N + h, R_E + h
    sL, cL, tL = math.sin(L), math.cos(L), math.tan(L)
    w_in_n = np.array([w * cL + vE / RE, -vN / RN, -w * sL - vE * tL / RE])

    F = np.zeros((N_ERR, N_ERR))
    F[ATT, ATT] = -skew(w_in_n)
    F[ATT, VEL] = [[0.0, -1.0 / RE, 0.0], [1.0 / RN, 0.0, 0.0], [0.0, tL / RE, 0.0]]
    F[ATT, POS] = [[w * sL, 0.0, vE / RE ** 2],
                   [0.0, 0.0, -vN / RN ** 2],
                   [w * cL + vE / (RE * cL ** 2), 0.0, -vE * tL / RE ** 2]]
    F[ATT, BG] = state.C_b_n
    F[VEL, ATT] = -skew(f_ib_n)
    F[VEL, VEL] = [[vD / RN, -2.0 * vE * tL / RE - 2.0 * w * sL, vN / RN],
                   [vE * tL / RE + 2.0 * w * sL, (vN * tL + vD) / RE, vE / RE + 2.0 * w * cL],
                   [-2.0 * vN / RN, -2.0 * vE / RE - 2.0 * w * cL, 0.0]]
    g0 = surface_gravity(planet, L)
    r_eS = geocentric_surface_radius(planet, L)
    F[VEL, POS] = [
        [-vE ** 2 / (RE * cL ** 2) - 2.0 * vE * w * cL, 0.0,
         vE ** 2 * tL / RE ** 2 - vN * vD / RN ** 2],
        [vN * vE / (RE * cL ** 2) + 2.0 * vN * w * cL - 2.0 * vD * w * sL, 0.0,
         -(vN * vE * tL + vE * vD) / RE ** 2],
        [2.0 * vE * w * sL, 0.0, vE ** 2 / RE ** 2 + vN ** 2 / RN ** 2 - 2.0 * g0 / r_eS]]
    F[VEL, BA] = state.C_b_n
    F[POS, VEL] = curvilinear_to_ned(planet, L, h)
    F[POS, POS] = [[0.0, 0.0, -vN / RN ** 2],
                   [vE * sL / (RE * cL ** 2), 0.0, -vE / (RE ** 2 * cL)],
                   [0.0, 0.0, 0.0]]
    return F


def transition_matrix(F: np.ndarray, tau_s: float) -> np.ndarray:
    """First-order state transition matrix ``Phi = I + F tau`` (paper eq. 11)."""
    return np.eye(N_ERR) + F * tau_s


def process_noise(state: NavState, F: np.ndarray, tau_s: float, S_rg: float, S_ra: float,
                  S_bad: float, S_bgd: float, planet: Planet) -> np.ndarray:
    """Discrete process noise Q (paper eq. 14, 39-47).

    Parameters
    ----------
    S_rg, S_ra : gyro / accelerometer white-noise PSD, rad^2/s and m^2/s^3.
    S_bad, S_bgd : accelerometer / gyro bias-variation PSD, m^2/s^5 and rad^2/s^3.
    """
    t = tau_s
    C = state.C_b_n
    F21 = F[VEL, ATT]
    T = curvilinear_to_ned(planet, state.llh[0], state.llh[2])
    FFt = F21 @ F21.T
    I3 = np.eye(3)
    Q = np.zeros((N_ERR, N_ERR))
    Q11 = (S_rg * t + S_bgd * t ** 3 / 3.0) * I3
    Q21 = (S_rg * t ** 2 / 2.0 + S_bgd * t ** 4 / 4.0) * F21
    Q22 = (S_ra * t + S_bad * t ** 3 / 3.0) * I3 + (S_rg * t ** 3 / 3.0 + S_bgd * t ** 5 / 5.0) * FFt
    Q31 = (S_rg * t ** 3 / 3.0 + S_bgd * t ** 5 / 5.0) * T @ F21
    Q32 = ((S_ra * t ** 2 / 2.0 + S_bad * t ** 4 / 4.0) * T
           + (S_rg * t ** 4 / 4.0 + S_bgd * t ** 6 / 6.0) * T @ FFt)
    Q33 = ((S_ra * t ** 3 / 3.0 + S_bad * t ** 5 / 5.0) * T @ T
           + (S_rg * t ** 5 / 5.0 + S_bgd * t ** 7 / 7.0) * T @ FFt @ T)
    Q34 = S_bad * t ** 3 / 3.0 * T @ C
    Q35 = S_bgd * t ** 4 / 4.0 * T @ F21 @ C
    Q15 = S_bgd * t ** 2 / 2.0 * C
    Q24 = S_bad * t ** 2 / 2.0 * C
    Q25 = S_bgd * t ** 3 / 3.0 * F21 @ C
    Q[ATT, ATT] = Q11
    Q[VEL, ATT] = Q21
    Q[ATT, VEL] = Q21.T
    Q[VEL, VEL] = Q22
    Q[POS, ATT] = Q31
    Q[ATT, POS] = Q31.T
    Q[POS, VEL] = Q32
    Q[VEL, POS] = Q32.T
    Q[POS, POS] = Q33
    Q[POS, BA] = Q34
    Q[BA, POS] = Q34.T
    Q[POS, BG] = Q35
    Q[BG, POS] = Q35.T
    Q[ATT, BG] = Q15
    Q[BG, ATT] = Q15.T
    Q[VEL, BA] = Q24
    Q[BA, VEL] = Q24.T
    Q[VEL, BG] = Q25
    Q[BG, VEL] = Q25.T
    Q[BA, BA] = S_bad * t * I3
    Q[BG, BG] = S_bgd * t * I3
    return Q
