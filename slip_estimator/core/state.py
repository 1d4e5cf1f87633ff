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

from collections.abc import Sequence

import numpy as np

from slip_estimator.core.frames import rotvec_to_dcm

ATT = slice(0, 3)
VEL = slice(3, 6)
POS = slice(6, 9)
BA = slice(9, 12)
BG = slice(12, 15)
N_ERR = 15


class NavState:
    """Total navigation state of the IMU point.

    Attributes
    ----------
    C_b_n : body (FRD) to NED direction-cosine matrix.
    v_eb_n : velocity w.r.t. the planet, NED, m/s.
    llh : latitude (rad), longitude (rad), ellipsoidal height (m).
    b_a : accelerometer bias estimate in b, m/s^2 (subtracted from the measurement).
    b_g : gyro bias estimate in b, rad/s (subtracted from the measurement).

    The strapdown step runs at the IMU rate and works on Python floats; making three arrays
    of its result at every sample (and lists of them again at the next) was about 30 % of
    the step's time (5.1 against 3.7 us per step, timeit). So attitude, velocity and
    position are held either as arrays or as the floats the strapdown step wrote last
    (:meth:`set_floats`), whichever was written last: reading an attribute makes its array
    then (the same values), and from then on the array is the state (it may be changed in
    place). :meth:`floats` reads the three as tuples of floats without making arrays.
    """

    __slots__ = ('_C', '_v', '_llh', '_C_f', '_v_f', '_llh_f', 'b_a', 'b_g')

    def __init__(self, C_b_n: np.ndarray, v_eb_n: np.ndarray, llh: np.ndarray,
                 b_a: np.ndarray, b_g: np.ndarray) -> None:
        self._C, self._v, self._llh = C_b_n, v_eb_n, llh
        self._C_f = self._v_f = self._llh_f = None
        self.b_a, self.b_g = b_a, b_g

    @property
    def C_b_n(self) -> np.ndarray:
        if self._C is None:
            self._C = np.array(self._C_f).reshape(3, 3)
            self._C_f = None
        return self._C

    @C_b_n.setter
    def C_b_n(self, value: np.ndarray) -> None:
        self._C, self._C_f = value, None

    @property
    def v_eb_n(self) -> np.ndarray:
        if self._v is None:
            self._v = np.array(self._v_f)
            self._v_f = None
        return self._v

    @v_eb_n.setter
    def v_eb_n(self, value: np.ndarray) -> None:
        self._v, self._v_f = value, None

    @property
    def llh(self) -> np.ndarray:
        if self._llh is None:
            self._llh = np.array(self._llh_f)
            self._llh_f = None
        return self._llh

    @llh.setter
    def llh(self, value: np.ndarray) -> None:
        self._llh, self._llh_f = value, None

    def floats(self) -> tuple[Sequence[float], Sequence[float], Sequence[float]]:
        """``C_b_n`` (row-major, 9 floats), ``v_eb_n`` and ``llh`` as sequences of floats."""
        C, v, llh = self._C_f, self._v_f, self._llh_f
        return (self._C.ravel().tolist() if C is None else C,
                self._v.tolist() if v is None else v,
                self._llh.tolist() if llh is None else llh)

    def set_floats(self, C_b_n: tuple[float, ...], v_eb_n: tuple[float, float, float],
                   llh: tuple[float, float, float]) -> None:
        """Write attitude (row-major 9-tuple), velocity and position as floats."""
        self._C_f, self._v_f, self._llh_f = C_b_n, v_eb_n, llh
        self._C = self._v = self._llh = None

    def copy(self) -> NavState:
        """Deep copy."""
        return NavState(self.C_b_n.copy(), self.v_eb_n.copy(), self.llh.copy(),
                        self.b_a.copy(), self.b_g.copy())

    def __repr__(self) -> str:
        return (f'NavState(C_b_n={self.C_b_n!r}, v_eb_n={self.v_eb_n!r}, llh={self.llh!r}, '
                f'b_a={self.b_a!r}, b_g={self.b_g!r})')


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
