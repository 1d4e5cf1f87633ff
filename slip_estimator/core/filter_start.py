"""The filter's starting point: the navigation state and its covariance from an alignment
(:class:`~slip_estimator.core.alignment.AlignmentStart`: levelled at rest, or in motion from
the rim speed), after a re-levelling, and after a recovery.

Levelling (Groves sec. 5.6.2) puts the horizontal accelerometer bias into roll and pitch, so
the initial covariance correlates them (:func:`initial_covariance`); heading and position are
the configured ones. An in-motion start widens tilt and velocity to what the wheel-derived
acceleration and the rim speed leave (:func:`in_motion_covariance`).

Only the standard library and numpy are used.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core import frames
from slip_estimator.core.alignment import AlignmentStart, level
from slip_estimator.core.error_model import curvilinear_to_ned
from slip_estimator.core.params import Params
from slip_estimator.core.planet import Planet, earth_rate_n, gravity_n
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState

_MOTION_TILT_STD_RAD = 0.02  # roll/pitch 1-sigma after an in-motion start (wheel-derived accel)


def aligned_state(start: AlignmentStart, planet: Planet, l_bw_b: np.ndarray,
                  heading_rad: float, llh_base: np.ndarray) -> NavState:
    """The navigation state after levelling on ``start.f_b`` (Groves sec. 5.6.2; roll and
    pitch ``start.tilt_rp_rad`` instead when given): heading and base_link position
    ``llh_base`` from the parameters, the IMU lever arm ``-l_bw_b`` taken off; gyro bias
    from the mean rate at rest less the planet rate (zero in motion); velocity
    from the rim speed along body x in motion, zero at rest."""
    roll, pitch = level(start.f_b) if start.tilt_rp_rad is None else start.tilt_rp_rad
    C_b_n = frames.rpy_to_dcm(roll, pitch, heading_rad)
    r_imu_b = -l_bw_b
    llh = llh_base - curvilinear_to_ned(planet, llh_base[0], llh_base[2]) @ (-(C_b_n @ r_imu_b))
    b_g = (np.zeros(3) if start.omega_ib_b is None
           else start.omega_ib_b - C_b_n.T @ earth_rate_n(planet, llh[0]))
    return NavState(C_b_n, np.zeros(3), llh, np.zeros(3), b_g)


def initial_covariance(p: Params, planet: Planet, state: NavState,
                       f_b: np.ndarray) -> np.ndarray:
    """Initial P. Levelling absorbs the horizontal accelerometer bias into roll/pitch, so the
    tilt error equals ``-C b_a / g`` (Groves eq. 5.103); P carries that correlation, otherwise
    the first acceleration is mistaken for a tilt change."""
    g = float(np.linalg.norm(f_b))
    T = curvilinear_to_ned(planet, state.llh[0], state.llh[2])
    d = np.zeros(N_ERR)
    d[ATT] = [p.initial_attitude_std ** 2, p.initial_attitude_std ** 2,
              p.initial_heading_std ** 2]
    d[VEL] = p.initial_velocity_std ** 2
    d[POS] = (np.diag(T) * 0.01) ** 2
    d[BA] = p.initial_accel_bias_std ** 2
    d[BG] = p.initial_gyro_bias_std ** 2
    J = np.eye(N_ERR)
    C = state.C_b_n
    J[0, BA] = -C[1] / g
    J[1, BA] = C[0] / g
    return J @ np.diag(d) @ J.T


def in_motion_covariance(P: np.ndarray, speed_mps: float, attitude_std_rad: float) -> None:
    """Widen an initial P (in place) for an in-motion start: roll/pitch to the wheel-derived
    acceleration's error, velocity to 0.1 m/s plus 20 % of the speed."""
    d = P.diagonal().copy()
    tilt_var = max(attitude_std_rad, _MOTION_TILT_STD_RAD) ** 2
    P[0, 0] += tilt_var - d[0]
    P[1, 1] += tilt_var - d[1]
    P[VEL, VEL] = (0.1 + 0.2 * abs(speed_mps)) ** 2


def relevel(state: NavState, P: np.ndarray, start: AlignmentStart, p: Params,
            planet: Planet) -> np.ndarray:
    """Re-level ``state`` in place on ``start`` (in motion: roll and pitch from the specific
    force less the wheel-derived acceleration, heading and position kept, velocity from the
    rim speed) and return its covariance: the in-motion prior, with the position and heading
    variances of ``P`` where larger."""
    roll, pitch = level(start.f_b)
    state.C_b_n = frames.rpy_to_dcm(roll, pitch, float(frames.dcm_to_rpy(state.C_b_n)[2]))
    state.v_eb_n = state.C_b_n[:, 0] * start.speed_mps
    P_new = initial_covariance(p, planet, state, start.f_b)
    in_motion_covariance(P_new, start.speed_mps, p.initial_attitude_std)
    P_new[POS, POS] = np.maximum(P_new[POS, POS], P[POS, POS])
    P_new[2, 2] = max(P_new[2, 2], P[2, 2])
    return P_new


def recovery_covariance(p: Params, planet: Planet, state: NavState, gap_s: float) -> np.ndarray:
    """P after a recovery: the initial one, velocity 1 m/s, position widened by how far the
    rover may have driven during ``gap_s``; correlations dropped."""
    P = initial_covariance(p, planet, state, -gravity_n(planet, state.llh[0], state.llh[2]))
    T = curvilinear_to_ned(planet, state.llh[0], state.llh[2])
    d = np.diag(P).copy()
    d[VEL] = 1.0
    d[POS] = (np.diag(T) * (0.01 + p.max_wheel_speed_mps * gap_s)) ** 2
    return np.diag(d)


def filter_start(start: AlignmentStart, p: Params, planet: Planet,
                 l_bw_b: np.ndarray) -> tuple[NavState, np.ndarray]:
    """The filter's state and covariance after the alignment ``start``: levelled, at the
    configured position and heading; in motion, moving at the rim speed along body x with a
    widened covariance (:func:`in_motion_covariance`)."""
    llh = np.array([math.radians(p.initial_latitude_deg), math.radians(p.initial_longitude_deg),
                    p.initial_height_m])
    st = aligned_state(start, planet, l_bw_b, math.radians(p.initial_heading_deg), llh)
    P = initial_covariance(p, planet, st, start.f_b)
    if start.speed_mps is not None:
        st.v_eb_n = st.C_b_n[:, 0] * start.speed_mps
        in_motion_covariance(P, start.speed_mps, p.initial_attitude_std)
    return st, P
