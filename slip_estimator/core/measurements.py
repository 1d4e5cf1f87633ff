"""Pseudo-measurement models (paper eq. 17-23), each with ``innovation`` and ``H``.

Every model compares a physical constraint with the current estimate and returns the
innovation ``z - h(x_est)`` and the Jacobian H such that ``innovation ~ H dx + noise`` with
the error-state conventions of :mod:`slip_estimator.core.state`. Analytic Jacobians are checked
against finite differences in the tests.
"""
from __future__ import annotations

import numpy as np

from slip_estimator.core.frames import cross, skew
from slip_estimator.core.planet import Planet, earth_rate_n
from slip_estimator.core.state import ATT, BG, N_ERR, VEL, NavState


class ZeroVelocity:
    """ZUPT: the IMU point is at rest, ``v_eb_n = 0`` (paper eq. 17-18)."""

    name = 'zupt'
    dof = 3

    def innovation(self, state: NavState) -> np.ndarray:
        """``0 - v_eb_n``, m/s."""
        return -state.v_eb_n

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = (0, -I, 0, 0, 0)``."""
        H = np.zeros((3, N_ERR))
        H[:, VEL] = -np.eye(3)
        return H


class ZeroAngularRate:
    """ZARU: the body does not rotate w.r.t. the planet, so the gyros sense the planet rate.

    The paper's eq. 19 sets the measured rate to zero; at rest the gyros read
    ``C_n_b omega_ie_n`` (15 deg/h on Earth, ten times the ADIS16495 bias), so we keep it,
    otherwise the planet rate is absorbed into the gyro bias and the heading drifts.
    """

    name = 'zaru'
    dof = 3

    def __init__(self, planet: Planet) -> None:
        self.planet = planet

    def innovation(self, state: NavState, omega_ib_b_mean: np.ndarray) -> np.ndarray:
        """``C_n_b omega_ie_n - (omega_ib_b - b_g)``, rad/s, with the window-mean gyro rate."""
        w_ie_b = state.C_b_n.T @ earth_rate_n(self.planet, state.llh[0])
        return w_ie_b - (omega_ib_b_mean - state.b_g)

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = (C_n_b [omega_ie_n x], 0, 0, 0, -I)`` (paper eq. 20 plus the planet rate)."""
        H = np.zeros((3, N_ERR))
        H[:, ATT] = state.C_b_n.T @ skew(earth_rate_n(self.planet, state.llh[0]))
        H[:, BG] = -np.eye(3)
        return H


class NonHolonomic:
    """Non-holonomic constraint: no lateral and no vertical velocity of the wheel-contact point.

    ``v_wb_b = C_n_b v_eb_n + omega_eb_b x l_bw_b`` with ``l_bw_b`` the lever arm from the IMU to
    the constrained point (base_link origin, between the wheels) in b (paper eq. 21).
    ``rows`` selects the components: (1, 2) lateral and vertical, (2,) vertical only (while
    a skid-steer turn violates the lateral constraint).
    Unlike eq. 22-23, H includes the attitude and gyro-bias coupling.
    """

    name = 'nhc'

    def __init__(self, planet: Planet, l_bw_b: np.ndarray) -> None:
        self.planet = planet
        self.l_bw_b = np.asarray(l_bw_b, dtype=float)
        self._skew_l = skew(self.l_bw_b)

    def point_velocity_b(self, state: NavState, omega_ib_b: np.ndarray) -> np.ndarray:
        """Velocity of the constrained point resolved in b, m/s."""
        return self.point_velocity_from_rate_b(state, self.body_rate_b(state, omega_ib_b))

    def body_rate_b(self, state: NavState, omega_ib_b: np.ndarray) -> np.ndarray:
        """``omega_eb_b``: body rate w.r.t. the planet, bias-corrected, resolved in b, rad/s."""
        return omega_ib_b - state.b_g - state.C_b_n.T @ earth_rate_n(self.planet, state.llh[0])

    def point_velocity_from_rate_b(self, state: NavState, omega_eb_b: np.ndarray) -> np.ndarray:
        """:meth:`point_velocity_b` from the body rate w.r.t. the planet (see
        :meth:`body_rate_b`), m/s."""
        return state.C_b_n.T @ state.v_eb_n + cross(omega_eb_b, self.l_bw_b)

    def innovation(self, state: NavState, omega_ib_b: np.ndarray,
                   rows: tuple[int, ...] = (1, 2)) -> np.ndarray:
        """``0 - v_wb_b[rows]``, m/s."""
        return -self.point_velocity_b(state, omega_ib_b)[list(rows)]

    def jacobian(self, state: NavState, rows: tuple[int, ...] = (1, 2)) -> np.ndarray:
        """``H = -rows( C_n_b [v x], C_n_b, 0, 0, -[l x] )``."""
        C_n_b = state.C_b_n.T
        H = np.zeros((3, N_ERR))
        H[:, ATT] = -C_n_b @ skew(state.v_eb_n)
        H[:, VEL] = -C_n_b
        H[:, BG] = self._skew_l
        return H[list(rows)]
