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

    ``T_r(n)^p`` is diagonal, so products with it are written as row / column scalings.
    """
    t = tau_s
    t2, t3, t4, t5 = t * t, t ** 3, t ** 4, t ** 5
    C = state.C_b_n
    F21 = F[VEL, ATT]
    Td = np.diag(curvilinear_to_ned(planet, state.llh[0], state.llh[2]))
    Tc = Td[:, None]  # T @ X == Tc * X ;  X @ T == X * Td
    FFt = F21 @ F21.T
    F21C = F21 @ C
    I3 = np.eye(3)
    a_rg2, a_rg3 = S_rg * t2 / 2.0 + S_bgd * t4 / 4.0, S_rg * t3 / 3.0 + S_bgd * t5 / 5.0
    Q21 = a_rg2 * F21
    Q31 = a_rg3 * Tc * F21
    Q32 = ((S_ra * t2 / 2.0 + S_bad * t4 / 4.0) * np.diag(Td)
           + (S_rg * t4 / 4.0 + S_bgd * t ** 6 / 6.0) * Tc * FFt)
    Q34 = S_bad * t3 / 3.0 * Tc * C
    Q35 = S_bgd * t4 / 4.0 * Tc * F21C
    Q15 = S_bgd * t2 / 2.0 * C
    Q24 = S_bad * t2 / 2.0 * C
    Q25 = S_bgd * t3 / 3.0 * F21C
    Q = np.zeros((N_ERR, N_ERR))
    Q[ATT, ATT] = (S_rg * t + S_bgd * t3 / 3.0) * I3
    Q[VEL, VEL] = (S_ra * t + S_bad * t3 / 3.0) * I3 + a_rg3 * FFt
    Q[POS, POS] = ((S_ra * t3 / 3.0 + S_bad * t5 / 5.0) * np.diag(Td * Td)
                   + (S_rg * t5 / 5.0 + S_bgd * t ** 7 / 7.0) * Tc * FFt * Td)
    Q[BA, BA] = S_bad * t * I3
    Q[BG, BG] = S_bgd * t * I3
    for (r, c), block in (((VEL, ATT), Q21), ((POS, ATT), Q31), ((POS, VEL), Q32),
                          ((POS, BA), Q34), ((POS, BG), Q35), ((ATT, BG), Q15),
                          ((VEL, BA), Q24), ((VEL, BG), Q25)):
        Q[r, c] = block
        Q[c, r] = block.T
    return Q
