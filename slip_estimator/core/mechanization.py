"""Strapdown inertial navigation in the local-level NED frame (paper eq. 2-6, Groves sec. 5.4).

Departures from the paper's printed equations, all following Groves (2013):

* eq. 2 is first order in the body rotation; we apply the body increment exactly (Rodrigues)
  and keep the planet and transport rate terms first order (they are ~1e-4 rad/s).
* eq. 3 resolves f_ib in n with the attitude averaged over the interval (Groves eq. 5.84).
* eq. 5 uses v_N(+) twice; the first term must use v_N(-) (Groves eq. 5.56).
* eq. 6 divides the second term by R_P; it is R_E(L(+)) (Groves eq. 5.56).

This runs for every IMU sample, so it is written with scalar arithmetic on Python floats (a
3-vector in numpy costs about a microsecond per operation, as much as the whole formula in
floats). The error-model tests check it against Groves' F by finite differences, and the
noiseless simulator runs against the truth.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from slip_estimator.core.planet import Planet
from slip_estimator.core.state import NavState


def rodrigues(x: float, y: float, z: float) -> tuple[float, ...]:
    """``exp([phi x])`` for the rotation vector (x, y, z) rad, row-major 9-tuple of floats."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-12:
        s, c = 1.0 - a2 / 6.0, 0.5 - a2 / 24.0  # sin(a)/a, (1 - cos a)/a^2 to O(a^4)
    else:
        a = math.sqrt(a2)
        s, c = math.sin(a) / a, (1.0 - math.cos(a)) / a2
    return (1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y,
            c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x,
            c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y))


def mechanize(state: NavState, f_ib_b: np.ndarray, omega_ib_b: np.ndarray, tau_s: float,
              planet: Planet) -> np.ndarray:
    """Advance ``state`` (in place) by one IMU interval.

    Parameters
    ----------
    state : navigation state at the start of the interval; biases are subtracted here.
    f_ib_b : measured specific force, b, m/s^2.
    omega_ib_b : measured angular rate, b, rad/s.
    tau_s : interval, s.
    planet : planet model.

    Returns
    -------
    f_ib_n : the bias-corrected specific force resolved in n over the interval, m/s^2 (the
        error-state model needs it, F21).
    """
    return np.array(mechanize_step(state, f_ib_b.tolist(), omega_ib_b.tolist(), tau_s, planet))


def mechanize_step(state: NavState, f_ib_b: Sequence[float], omega_ib_b: Sequence[float],
                   tau_s: float, planet: Planet) -> tuple[float, float, float]:
    """:func:`mechanize` on plain floats (the estimator's per-sample path): the measurements
    as 3-sequences of floats, ``f_ib_n`` returned as a tuple.

    The radii of curvature and the normal gravity are those of :mod:`planet`
    (``radii_of_curvature``, ``gravity_down``) written out with the planet's cached constants
    and sharing ``sin L``: the same floating-point operations, without the calls.
    """
    C, v, llh = state.floats()
    L, lam, h = llh
    vN, vE, vD = v
    ba_x, ba_y, ba_z = state.b_a.tolist()
    bg_x, bg_y, bg_z = state.b_g.tolist()
    fx, fy, fz = f_ib_b[0] - ba_x, f_ib_b[1] - ba_y, f_ib_b[2] - ba_z
    wx = (omega_ib_b[0] - bg_x) * tau_s
    wy = (omega_ib_b[1] - bg_y) * tau_s
    wz = (omega_ib_b[2] - bg_z) * tau_s
    sL, cL = math.sin(L), math.cos(L)
    w, e2, R0, R0_sq, R_N_num, g_e, k, g_h = planet.strapdown_constants
    # radii_of_curvature(planet, L) and surface_gravity(planet, L)
    s2 = sL ** 2
    d = 1.0 - e2 * s2
    sqrt_d = math.sqrt(d)
    R_N, R_E = R_N_num / d ** 1.5, R0 / sqrt_d
    RN, RE = R_N + h, R_E + h
    # Planet rate (Groves 5.41) and transport rate (5.44) in NED.
    ie_N, ie_D = w * cL, -w * sL
    en_N, en_E, en_D = vE / RE, -vN / RN, -vE * sL / (cL * RE)
    # Attitude (eq. 2): body rotation exactly, nav-frame rotation to first order:
    # C+ = C- R(w tau) - [Omega x] C- tau, with Omega = omega_ie + omega_en.
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = C
    r11, r12, r13, r21, r22, r23, r31, r32, r33 = rodrigues(wx, wy, wz)
    oN, oE, oD = (ie_N + en_N) * tau_s, en_E * tau_s, (ie_D + en_D) * tau_s
    n11 = c11 * r11 + c12 * r21 + c13 * r31 - (-oD * c21 + oE * c31)
    n12 = c11 * r12 + c12 * r22 + c13 * r32 - (-oD * c22 + oE * c32)
    n13 = c11 * r13 + c12 * r23 + c13 * r33 - (-oD * c23 + oE * c33)
    n21 = c21 * r11 + c22 * r21 + c23 * r31 - (oD * c11 - oN * c31)
    n22 = c21 * r12 + c22 * r22 + c23 * r32 - (oD * c12 - oN * c32)
    n23 = c21 * r13 + c22 * r23 + c23 * r33 - (oD * c13 - oN * c33)
    n31 = c31 * r11 + c32 * r21 + c33 * r31 - (-oE * c11 + oN * c21)
    n32 = c31 * r12 + c32 * r22 + c33 * r32 - (-oE * c12 + oN * c22)
    n33 = c31 * r13 + c32 * r23 + c33 * r33 - (-oE * c13 + oN * c23)
    # Specific force resolved with the mean attitude of the interval.
    fN = 0.5 * ((c11 + n11) * fx + (c12 + n12) * fy + (c13 + n13) * fz)
    fE = 0.5 * ((c21 + n21) * fx + (c22 + n22) * fy + (c23 + n23) * fz)
    fD = 0.5 * ((c31 + n31) * fx + (c32 + n32) * fy + (c33 + n33) * fz)
    # Gravity (gravity_down(planet, L, h)), Coriolis and transport terms.
    g0 = g_e * (1.0 + k * s2) / sqrt_d
    gD = g0 * (1.0 - g_h * h + 3.0 * h * h / R0_sq)
    aN, aE, aD = en_N + 2.0 * ie_N, en_E, en_D + 2.0 * ie_D
    cN = aE * vD - aD * vE
    cE = aD * vN - aN * vD
    cD = aN * vE - aE * vN
    # Velocity (eq. 3).
    vN1 = vN + (fN - cN) * tau_s
    vE1 = vE + (fE - cE) * tau_s
    vD1 = vD + (fD + gD - cD) * tau_s
    # Position (eq. 4-6, corrected); R_E at the new latitude as in radii_of_curvature.
    h1 = h - 0.5 * tau_s * (vD + vD1)
    L1 = L + 0.5 * tau_s * (vN / RN + vN1 / (R_N + h1))
    R_E1 = R0 / math.sqrt(1.0 - e2 * math.sin(L1) ** 2)
    lam1 = lam + 0.5 * tau_s * (vE / (RE * cL) + vE1 / ((R_E1 + h1) * math.cos(L1)))
    state.set_floats((n11, n12, n13, n21, n22, n23, n31, n32, n33), (vN1, vE1, vD1),
                     (L1, lam1, h1))
    return fN, fE, fD
