"""Strapdown inertial navigation in the local-level NED frame (paper eq. 2-6, Groves sec. 5.4).

Departures from the paper's printed equations, all following Groves (2013):

* eq. 2 is first order in the body rotation; we apply the body increment exactly (Rodrigues)
  and keep the planet and transport rate terms first order (they are ~1e-4 rad/s).
* eq. 3 resolves f_ib in n with the attitude averaged over the interval (Groves eq. 5.84).
* eq. 5 uses v_N(+) twice; the first term must use v_N(-) (Groves eq. 5.56).
* eq. 6 divides the second term by R_P; it is R_E(L(+)) (Groves eq. 5.56).
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.frames import rotvec_to_dcm, skew
from slip_estimator.core.planet import (
    Planet,
    earth_rate_n,
    gravity_n,
    radii_of_curvature,
    transport_rate_n,
)
from slip_estimator.core.state import NavState


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
    L, lam, h = state.llh
    v_old = state.v_eb_n
    f_b = f_ib_b - state.b_a
    w_b = omega_ib_b - state.b_g
    w_ie_n = earth_rate_n(planet, L)
    w_en_n = transport_rate_n(planet, L, h, v_old)
    # Attitude (eq. 2): body rotation exactly, nav-frame rotation to first order.
    C_old = state.C_b_n
    C_new = C_old @ rotvec_to_dcm(w_b * tau_s) - skew(w_ie_n + w_en_n) @ C_old * tau_s
    f_n = 0.5 * (C_old + C_new) @ f_b
    # Velocity (eq. 3).
    g_n = gravity_n(planet, L, h)
    v_new = v_old + (f_n + g_n - np.cross(w_en_n + 2.0 * w_ie_n, v_old)) * tau_s
    # Position (eq. 4-6, corrected).
    R_N, R_E = radii_of_curvature(planet, L)
    h_new = h - 0.5 * tau_s * (v_old[2] + v_new[2])
    L_new = L + 0.5 * tau_s * (v_old[0] / (R_N + h) + v_new[0] / (R_N + h_new))
    _, R_E_new = radii_of_curvature(planet, L_new)
    lam_new = lam + 0.5 * tau_s * (v_old[1] / ((R_E + h) * math.cos(L))
                                   + v_new[1] / ((R_E_new + h_new) * math.cos(L_new)))
    state.C_b_n = C_new
    state.v_eb_n = v_new
    state.llh = np.array([L_new, lam_new, h_new])
    return f_n
