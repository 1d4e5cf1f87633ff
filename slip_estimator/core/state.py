"""The navigation state and the one definition of the 15-element error-state layout.

Error state (paper eq. 8, Groves 2013 sec. 14.2), every element "estimate minus truth" except
the biases, which are the residual biases not yet fed back ("truth minus estimate"):

=========  ======  =====================================================================
slice      size    meaning
=========  ======  =====================================================================
ATT        3       attitude error psi, rad: ``C_b_n_est = (I + [psi x]) C_b_n_true``
VEL        3       velocity error of v_eb_n, m/s (NED)
POS        3       curvilinear position error (dL rad, dlambda rad, dh m)
BA         3       residual accelerometer bias in b, m/s^2
BG         3       residual gyro bias in b, rad/s
=========  ======  =====================================================================

Closed-loop correction (:func:`correct`): ``C_b_n <- exp(-[psi x]) C_b_n``,
``v <- v - dv``, ``p <- p - dp``, ``b <- b + db``. The paper's eq. 26-27 print "+" for velocity
and position; with its own innovation signs (eq. 17-18) the correction must subtract.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slip_estimator.core.frames import rotvec_to_dcm

ATT = slice(0, 3)
VEL = slice(3, 6)
POS = slice(6, 9)
BA = slice(9, 12)
BG = slice(12, 15)
N_ERR = 15


@dataclass(slots=True)
class NavState:
    """Total navigation state of the IMU point.

    Attributes
    ----------
    C_b_n : body (FRD) to NED direction-cosine matrix.
    v_eb_n : velocity w.r.t. the planet, NED, m/s.
    llh : latitude (rad), longitude (rad), ellipsoidal height (m).
    b_a : accelerometer bias estimate in b, m/s^2 (subtracted from the measurement).
    b_g : gyro bias estimate in b, rad/s (subtracted from the measurement).
    """

    C_b_n: np.ndarray
    v_eb_n: np.ndarray
    llh: np.ndarray
    b_a: np.ndarray
    b_g: np.ndarray

    def copy(self) -> NavState:
        """Deep copy."""
        return NavState(self.C_b_n.copy(), self.v_eb_n.copy(), self.llh.copy(),
                        self.b_a.copy(), self.b_g.copy())


def correct(state: NavState, dx: np.ndarray) -> NavState:
    """Feed an estimated error state back into the total state (closed loop, in place)."""
    state.C_b_n = rotvec_to_dcm(-dx[ATT]) @ state.C_b_n
    state.v_eb_n = state.v_eb_n - dx[VEL]
    state.llh = state.llh - dx[POS]
    state.b_a = state.b_a + dx[BA]
    state.b_g = state.b_g + dx[BG]
    return state


def difference(estimate: NavState, truth: NavState) -> np.ndarray:
    """Error state of ``estimate`` w.r.t. ``truth`` (inverse of :func:`correct`, small errors)."""
    dC = estimate.C_b_n @ truth.C_b_n.T
    psi = 0.5 * np.array([dC[2, 1] - dC[1, 2], dC[0, 2] - dC[2, 0], dC[1, 0] - dC[0, 1]])
    dx = np.empty(N_ERR)
    dx[ATT] = psi
    dx[VEL] = estimate.v_eb_n - truth.v_eb_n
    dx[POS] = estimate.llh - truth.llh
    dx[BA] = truth.b_a - estimate.b_a
    dx[BG] = truth.b_g - estimate.b_g
    return dx
