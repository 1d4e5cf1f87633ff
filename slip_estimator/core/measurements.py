"""Measurement models (paper eq. 17-23, and the wheel aid's forward speed), each with
``innovation``, ``jacobian`` (H) and ``covariance`` (R).

Every model compares a physical constraint (or an aid value) with the current estimate and
returns the innovation ``z - h(x_est)``, the Jacobian H such that ``innovation ~ H dx + noise``
with the error-state conventions of :mod:`slip_estimator.core.state`, and its own noise
covariance R. Analytic Jacobians are checked against finite differences in the tests.
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from slip_estimator.core.frames import cross, skew
from slip_estimator.core.planet import Planet, earth_rate_n
from slip_estimator.core.state import ATT, BG, N_ERR, VEL, NavState


_MINUS_EYE_3 = -np.eye(3)
_MINUS_EYE_3.flags.writeable = False


def _rows(a: np.ndarray, rows: tuple[int, ...]) -> np.ndarray:
    """``a[list(rows)]``; a slice (a view, the same values, without the fancy index) where
    the rows are consecutive, as every caller's are."""
    if rows[-1] - rows[0] == len(rows) - 1:
        return a[rows[0]:rows[-1] + 1]
    return a[list(rows)]


class ZeroVelocity:
    """ZUPT: the IMU point is at rest, ``v_eb_n = 0`` (paper eq. 17-18)."""

    name = 'zupt'
    dof = 3

    def __init__(self, velocity_std_mps: float = 0.01) -> None:
        self.velocity_std_mps = velocity_std_mps

    def covariance(self) -> np.ndarray:
        """``R = sigma_v^2 I``, m^2/s^2."""
        return np.eye(3) * self.velocity_std_mps ** 2

    def innovation(self, state: NavState) -> np.ndarray:
        """``0 - v_eb_n``, m/s."""
        return -state.v_eb_n

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = (0, -I, 0, 0, 0)``."""
        H = np.zeros((3, N_ERR))
        H[:, VEL] = _MINUS_EYE_3
        return H


class ZeroAngularRate:
    """ZARU: the body does not rotate w.r.t. the planet, so the gyros sense the planet rate.

    The paper's eq. 19 sets the measured rate to zero; at rest the gyros read
    ``C_n_b omega_ie_n`` (15 deg/h on Earth, ten times the ADIS16495 bias), so we keep it,
    otherwise the planet rate is absorbed into the gyro bias and the heading drifts.
    """

    name = 'zaru'
    dof = 3

    def __init__(self, planet: Planet, rate_std_rps: float = 0.001,
                 gyro_noise_density_rps_rthz: float = 0.0) -> None:
        self.planet = planet
        self.rate_std_rps = rate_std_rps
        self.gyro_noise_density_rps_rthz = gyro_noise_density_rps_rthz

    def covariance(self, period_s: float, sample_var_rps2: np.ndarray | None = None,
                   dt_s: float = 0.0) -> np.ndarray:
        """``R = diag(sigma_w^2 + max(N_g^2, s^2 dt) / T)``, rad^2/s^2: the constraint's own
        spread plus the gyro noise of a mean over ``T = period_s``: the white noise of the
        parameters, or, when larger, that of the scatter ``s^2`` (per axis) of single samples
        ``dt_s`` apart in the IMU window now. The parameters' noise may not be the IMU's: a
        robot that starts moving learns it at its first stop, after ZARU has begun (a consumer
        gyro at 0.02 rad/s per sample against the default 2e-4 rad/s/sqrt(Hz): R 300 times
        too small, its first updates took the bias from a few samples and turned the heading
        by the bias-heading correlation, 26 deg on the simulated no-slip seed 1)."""
        white = np.full(3, self.gyro_noise_density_rps_rthz ** 2)
        if sample_var_rps2 is not None:
            white = np.maximum(white, np.asarray(sample_var_rps2) * dt_s)
        return np.diag(self.rate_std_rps ** 2 + white / period_s)

    def innovation(self, state: NavState, omega_ib_b_mean: np.ndarray) -> np.ndarray:
        """``C_n_b omega_ie_n - (omega_ib_b - b_g)``, rad/s, with the window-mean gyro rate."""
        w_ie_b = state.C_b_n.T @ earth_rate_n(self.planet, state.llh[0])
        return w_ie_b - (omega_ib_b_mean - state.b_g)

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = (C_n_b [omega_ie_n x], 0, 0, 0, -I)`` (paper eq. 20 plus the planet rate)."""
        H = np.zeros((3, N_ERR))
        H[:, ATT] = state.C_b_n.T @ skew(earth_rate_n(self.planet, state.llh[0]))
        H[:, BG] = _MINUS_EYE_3
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
    channels = {1: 'nhc_lateral', 2: 'nhc_vertical'}

    def __init__(self, planet: Planet, l_bw_b: np.ndarray, lateral_std_mps: float = 0.05,
                 vertical_std_mps: float = 0.05) -> None:
        self.planet = planet
        self.l_bw_b = np.asarray(l_bw_b, dtype=float)
        self._skew_l = skew(self.l_bw_b)
        self._std_mps = {1: lateral_std_mps, 2: vertical_std_mps}

    def covariance(self, rows: tuple[int, ...] = (1, 2)) -> np.ndarray:
        """``R = diag(sigma_rows^2)``, m^2/s^2."""
        return np.diag([self._std_mps[r] ** 2 for r in rows])

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
        return -_rows(self.point_velocity_b(state, omega_ib_b), rows)

    def jacobian(self, state: NavState, rows: tuple[int, ...] = (1, 2)) -> np.ndarray:
        """``H = -rows( C_n_b [v x], C_n_b, 0, 0, -[l x] )``."""
        C_n_b = state.C_b_n.T
        H = np.zeros((3, N_ERR))
        H[:, ATT] = -C_n_b @ skew(state.v_eb_n)
        H[:, VEL] = -C_n_b
        H[:, BG] = self._skew_l
        return _rows(H, rows)


class ForwardSpeed:
    """Wheel aid: the forward velocity of the wheel-contact point equals an aid value
    ``z_mps`` (the rim speed through the held slip, ``r w g(s_hold)``, or the rim speed itself
    while recovering). ``h(x)`` is row 0 of :meth:`NonHolonomic.point_velocity_b`, so H is the
    forward row of the non-holonomic Jacobian; R is the variance the aid's decision states.
    """

    name = 'wheel'

    def __init__(self, planet: Planet, l_bw_b: np.ndarray) -> None:
        self._point = NonHolonomic(planet, l_bw_b)

    def innovation(self, z_mps: float, v_fwd_mps: float) -> np.ndarray:
        """``z - v_fwd``, m/s, with ``v_fwd`` the INS forward speed at the aid's instant."""
        return np.array([z_mps - v_fwd_mps])

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = -row_x( C_n_b [v x], C_n_b, 0, 0, -[l x] )``, shape (1, 15)."""
        return self._point.jacobian(state, (0,))

    def covariance(self, var_mps2: float) -> np.ndarray:
        """``R = [[var]]``, m^2/s^2."""
        return np.array([[var_mps2]])


class WheelYawRate:
    """Wheel yaw-rate aid: the body's rate about its z axis w.r.t. the planet is the one the
    wheel differential gives, ``omega_eb_b[2] = z = -(rim_R - rim_L) / B_eff`` (b is FRD, z
    down: a left turn, right rim faster, is negative; ``B_eff`` the effective track,
    :mod:`slip_estimator.core.track_width`). ``h(x) = omega_ib_b[2] - b_g[2] - (C_n_b
    omega_ie_n)[2]``, the z row of :class:`ZeroAngularRate` (which is this model with z = 0):
    while the robot drives without stopping it is what observes the gyro z bias. R is the
    variance the caller states (encoder and gyro noise, the track width's uncertainty and the
    yaw rate the differential does not explain: :mod:`slip_estimator.core.yaw_aid`).
    """

    name = 'wheel_yaw'

    def __init__(self, planet: Planet) -> None:
        self._zaru = ZeroAngularRate(planet)

    def innovation(self, state: NavState, omega_ib_z_rps: float, z_rps: float) -> np.ndarray:
        """``z - (omega_ib_b[2] - b_g[2] - (C_n_b omega_ie_n)[2])``, rad/s, with the gyro z
        rate ``omega_ib_z_rps`` (bias included) at the wheel sample's instant."""
        w_ie_z = float(state.C_b_n[:, 2] @ earth_rate_n(self._zaru.planet, state.llh[0]))
        return np.array([z_rps - (omega_ib_z_rps - float(state.b_g[2]) - w_ie_z)])

    def jacobian(self, state: NavState) -> np.ndarray:
        """``H = row_z(C_n_b [omega_ie_n x], 0, 0, 0, -I)``, shape (1, 15)."""
        return self._zaru.jacobian(state)[2:3]

    def covariance(self, var_rps2: float) -> np.ndarray:
        """``R = [[var]]``, rad^2/s^2."""
        return np.array([[var_rps2]])


class Constraint(NamedTuple):
    """One pseudo-measurement to apply: model name, ``z - h(x)``, H, R, and the names of its
    rows for the residual monitor (None: the model's name)."""

    name: str
    innovation: np.ndarray
    H: np.ndarray
    R: np.ndarray
    channels: tuple[str, ...] | None = None


class PseudoMeasurements:
    """What the rover's physics allow now: ZUPT + ZARU at rest, else the non-holonomic
    constraint (vertical only while a skid-steer turn violates the lateral one)."""

    def __init__(self, zupt: ZeroVelocity, zaru: ZeroAngularRate, nhc: NonHolonomic) -> None:
        self.zupt, self.zaru, self.nhc = zupt, zaru, nhc

    def select(self, state: NavState, omega_ib_b_mean: np.ndarray, period_s: float,
               stationary: bool, turning: bool, gyro_var_rps2: np.ndarray | None = None,
               dt_s: float = 0.0) -> Iterator[Constraint]:
        """The constraints in order, each evaluated when the previous one has been applied
        (``state`` is then the corrected one): a generator, to be consumed one by one.
        ``gyro_var_rps2``: the gyro scatter per axis in the IMU window (samples ``dt_s``
        apart), for ZARU (:meth:`ZeroAngularRate.covariance`)."""
        if stationary:
            yield Constraint('zupt', self.zupt.innovation(state), self.zupt.jacobian(state),
                             self.zupt.covariance())
            yield Constraint('zaru', self.zaru.innovation(state, omega_ib_b_mean),
                             self.zaru.jacobian(state),
                             self.zaru.covariance(period_s, gyro_var_rps2, dt_s))
            return
        rows = (2,) if turning else (1, 2)
        nhc = self.nhc
        yield Constraint('nhc', nhc.innovation(state, omega_ib_b_mean, rows),
                         nhc.jacobian(state, rows), nhc.covariance(rows),
                         tuple(nhc.channels[r] for r in rows))
