"""The error-state filter: navigation state and its covariance, predict and correct.

* **Predict.** The strapdown mechanization runs at the full IMU rate (:meth:`mechanize`); the
  covariance is propagated every ``covariance_decimation`` samples over the accumulated
  interval (:meth:`predict_covariance`, second-order Phi, the process noise inflated by the
  vibration seen now, :func:`vibration_psd`).
* **Correct.** :meth:`update` is one measurement update with a soft chi-square gate (Joseph
  form, :mod:`slip_estimator.core.kalman`); :meth:`anchor` an ungated one (a known jump of
  the INS error); both close the loop on the state and return what the correction did to the
  forward motion (:class:`~slip_estimator.core.history.Correction`), for whoever keeps a
  record of the past. Every update leaves an :class:`~slip_estimator.core.kalman.UpdateRecord`
  in :attr:`last_records` and moves the running NIS mean of its model.
* **Heading from the gyro, not from body-frame velocity.** The non-holonomic constraint, the
  forward-speed aid and its anchors constrain the velocity in the body frame, which a rotation
  of the whole solution about the vertical leaves unchanged: they hold no heading information,
  and an EKF linearised at changing estimates gains spurious information along that
  unobservable direction (Huang, Mourikis & Roumeliotis 2010, observability-constrained EKF),
  so heading and z bias get pulled and the filter grows over-confident. Their only route to
  the gyro z bias is the centripetal coupling (yaw rate against lateral acceleration over
  speed), where a consumer accelerometer's lateral bias of 0.06 m/s^2 at 0.9 m/s reads as
  0.07 rad/s. Heading and gyro z bias are therefore consider states of these updates
  (:data:`BODY_VELOCITY_CONSIDER`): they come from the gyro, ZARU at rest and the wheel
  yaw-rate aid, and the velocity follows the body's heading (the constraint turns v, not the
  body). With ``wheel_aid: off`` (the paper's method) they correct every state, as there.
* **A stop holds no heading information either.** ZUPT (zero velocity) is unchanged by the
  same rotation about the vertical, so it too leaves heading and gyro z bias alone. ZARU
  measures the gyro bias at rest, and its only route to the heading is the bias-heading
  correlation the drive built, which assumes that the bias the drive integrated is the one
  at rest. On a consumer gyro it is not: the bias the wheel yaw-rate aid holds while driving
  also carries the motion's errors (vibration rectification, scale factor in turns, the
  effective track), the rest shows the static bias alone, and the correlation turned their
  difference into heading (a 10-s stop of the simulated vibrating no-slip robot, seed 1:
  +6 deg, 3.8 -> 9.8 deg of heading error, against a true change of none). ZARU therefore
  keeps the heading as a consider state (:data:`REST_RATE_CONSIDER`) that keeps only the
  share ``P_bb / (P_bb + J)`` of its gain: ``J`` (:attr:`rest_bias_jump_var_rps2`, set by the
  updater at each stop) is the variance by which the rest's z bias may differ from the
  drive's, from the gyro scatter the drive showed beyond the rest's. A gyro that did not
  vibrate keeps the correlation's correction (an industrial IMU, where the bias is one
  bias: the simulated fifty_hz robot), a vibrating one keeps the heading the gyro and the
  wheel yaw-rate aid made (before the first stop after driving: a pure consider state).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from slip_estimator.core import frames, kalman
from slip_estimator.core.detectors import ImuWindow
from slip_estimator.core.error_model import process_noise, system_matrix
from slip_estimator.core.history import Correction
from slip_estimator.core.mechanization import mechanize_step
from slip_estimator.core.params import Params
from slip_estimator.core.planet import Planet, radii_of_curvature
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState, correct

_EYE_15 = np.eye(N_ERR)
_EYE_15.flags.writeable = False
BODY_VELOCITY_CONSIDER = [ATT.start + 2, BG.start + 2]
"""Heading error (down component of psi) and gyro z bias: not corrected by body-frame velocity
and ZUPT updates (module docstring)."""
_BODY_VELOCITY_MODELS = frozenset({'nhc', 'wheel', 'zupt'})
REST_RATE_CONSIDER = [ATT.start + 2]
"""Heading error: not corrected by ZARU (module docstring)."""


class UpdateOutcome(NamedTuple):
    """What one gated update did."""

    record: kalman.UpdateRecord
    gated: bool
    """the innovation was beyond the gate: applied with R inflated onto it"""
    correction: Correction | None
    """None when the update could not be applied (non-finite NIS)"""


def vibration_psd(S: tuple[float, float, float, float], fraction: float, window: ImuWindow,
                  dt_s: float) -> tuple[float, float, float, float]:
    """Process-noise PSDs (S_rg, S_ra, S_bad, S_bgd) inflated by the vibration seen now.

    Driving over rough ground shakes a rover's IMU by orders of magnitude more than the
    sensor noise (Pathfinder: 1-3 m/s^2 and 0.1 rad/s RMS driving, 0.015 and 0.001 at rest).
    Strapdown integration of it leaves errors (sampling, coning/sculling, g-sensitivity) that
    a fixed white-noise model ignores, and an over-confident filter then turns constraint
    residuals into wild attitude corrections. A fraction of the spread in the IMU ``window``
    (the stationarity detector's) is therefore added as white noise:
    ``S = N^2 + k^2 (sigma^2 - N^2 / dt) dt`` (only the spread beyond the sensor noise,
    so a rover at rest keeps the plain noise model).
    """
    S_rg, S_ra, S_bad, S_bgd = S
    k = fraction
    if k <= 0.0 or window.n < 2:
        return S
    var = window.variance().tolist()  # finite: samples are checked
    # Only the spread beyond the white noise already in S (sigma^2 = S / dt per sample).
    excess_g = max(0.0, max(var[3:]) - S_rg / dt_s)
    excess_a = max(0.0, max(var[:3]) - S_ra / dt_s)
    return S_rg + k * k * excess_g * dt_s, S_ra + k * k * excess_a * dt_s, S_bad, S_bgd


class ErrorStateFilter:
    """15-state error-state EKF around a strapdown INS (see the module docstring)."""

    def __init__(self, params: Params, planet: Planet) -> None:
        self.planet = planet
        self._decimation = params.covariance_decimation
        aided = params.wheel_aid != 'off'
        self._consider = BODY_VELOCITY_CONSIDER if aided else None
        self._rest_consider = REST_RATE_CONSIDER if aided else None
        self._vibration_fraction = params.vibration_noise_fraction
        self.use_noise(params)
        self._gate = {k: kalman.chi2_threshold(k, params.innovation_gate_probability)
                      for k in (1, 2, 3)}
        self.state: NavState | None = None
        self.P = np.zeros((N_ERR, N_ERR))
        self.g_mps2 = 0.0
        self.rest_bias_jump_var_rps2 = math.inf  # J of _rest_heading_share (inf: consider)
        self.nis_mean = {'zupt': float('nan'), 'zaru': float('nan'), 'nhc': float('nan'),
                         'wheel': float('nan'), 'wheel_yaw': float('nan')}
        self.last_records: list[kalman.UpdateRecord] = []
        self.clear_accumulators()
        # Gyro rate summed since the last update epoch (the pseudo-measurements' mean rate).
        self._rate_sum_rps = [0.0, 0.0, 0.0]
        self._rate_n = 0

    def start(self, state: NavState, P: np.ndarray, g_mps2: float) -> None:
        """Begin from an aligned state with covariance ``P`` (``g_mps2``: gravity there)."""
        self.state, self.P, self.g_mps2 = state, P, g_mps2

    def reopen_levels(self, accel_std_mps2: float) -> None:
        """A stop begins: its zero velocity will measure the horizontal acceleration error
        again (tilt times g plus the accelerometer bias), so the drive's knowledge of it is
        not kept as certain. While driving, the wheel aid taught tilt and bias under held
        slips whose errors the covariance knows nothing of (tilt NEES 4-13 at the stops of
        simulated drives, against 2); the north/east tilt and the body x/y accelerometer bias
        variances are raised to at least ``accel_std_mps2`` of acceleration (tilt: over g;
        correlations kept, so P stays positive semi-definite; a second call changes
        nothing), and the stop's ZUPTs level the INS anew before the next start measures the
        ground."""
        tilt_var = (accel_std_mps2 / self.g_mps2) ** 2
        for i, var in ((ATT.start, tilt_var), (ATT.start + 1, tilt_var),
                       (BA.start, accel_std_mps2 ** 2), (BA.start + 1, accel_std_mps2 ** 2)):
            self.P[i, i] = max(self.P[i, i], var)

    def restart_velocity(self, v_fwd_mps: float,
                         covariance: Callable[[NavState], np.ndarray]) -> None:
        """Recovery: the velocity restarts at ``v_fwd_mps`` along body x, attitude and
        position are kept, P becomes ``covariance(state)``, the interval integrated since the
        last propagation is dropped (it is not the body's)."""
        st = self.state
        st.v_eb_n = st.C_b_n[:, 0] * v_fwd_mps
        st.C_b_n = frames.orthonormalize(st.C_b_n)
        self.P = covariance(st)
        self.clear_accumulators()

    def clear_accumulators(self) -> None:
        """Drop the interval integrated since the last covariance propagation."""
        # Per-sample accumulators as lists of floats (numpy costs ~1 us per 3-vector
        # operation; the element-wise float sums are the same).
        self._acc_tau_s = 0.0
        self._acc_dv_n_mps = [0.0, 0.0, 0.0]  # sum of f_ib_n * dt since the last propagation
        self._acc_n = 0

    def use_noise(self, params: Params) -> None:
        """The process noise from the noise densities and bias PSDs of ``params`` (from now)."""
        noise = params.imu_noise
        self._noise_psd = (noise.gyro_noise_density_rps_rthz ** 2,
                           noise.accel_noise_density_mps2_rthz ** 2,
                           noise.accel_bias_psd_m2ps5, noise.gyro_bias_psd_rad2ps3)

    # ------------------------------------------------------------------ predict
    def mechanize(self, f_b: list[float], w_b: list[float], dt_s: float) -> bool:
        """One strapdown step; True when the covariance propagation is due."""
        fN, fE, fD = mechanize_step(self.state, f_b, w_b, dt_s, self.planet)
        self._acc_tau_s += dt_s
        acc = self._acc_dv_n_mps
        acc[0] += fN * dt_s
        acc[1] += fE * dt_s
        acc[2] += fD * dt_s
        self._acc_n += 1
        acc = self._rate_sum_rps
        acc[0] += w_b[0]
        acc[1] += w_b[1]
        acc[2] += w_b[2]
        self._rate_n += 1
        return self._acc_n >= self._decimation

    def predict_covariance(self, window: ImuWindow, dt_s: float) -> None:
        """Propagate P over the interval accumulated since the last propagation, with the
        vibration in the IMU ``window`` (see :func:`vibration_psd`; nominal IMU step
        ``dt_s``)."""
        if self._acc_n == 0:
            return
        tau = self._acc_tau_s
        a_N, a_E, a_D = self._acc_dv_n_mps
        F = system_matrix(self.state, (a_N / tau, a_E / tau, a_D / tau), self.planet)
        Ft = F * tau
        Phi = Ft + _EYE_15  # Phi = I + F tau + (F tau)^2 / 2
        Ft2 = Ft @ Ft
        Ft2 *= 0.5
        Phi += Ft2
        S = vibration_psd(self._noise_psd, self._vibration_fraction, window, dt_s)
        Q = process_noise(self.state, F, tau, *S, self.planet)
        self.P = kalman.predict(self.P, Phi, Q)
        self.state.C_b_n = frames.orthonormalize(self.state.C_b_n)
        self.clear_accumulators()

    def take_mean_rate(self) -> tuple[np.ndarray, int]:
        """Mean gyro rate (rad/s) since the last call and the number of samples in it."""
        n = self._rate_n
        w_mean = np.array(self._rate_sum_rps) / max(1, n)
        self._rate_sum_rps = [0.0, 0.0, 0.0]
        self._rate_n = 0
        return w_mean, n

    # ------------------------------------------------------------------ correct
    def correct(self, dx: np.ndarray) -> Correction:
        """Close the loop on ``dx``; return what it did to the forward motion."""
        st = self.state
        before = float(st.C_b_n[:, 0] @ st.v_eb_n)
        a_before = self.g_mps2 * float(st.C_b_n[2, 0]) - float(st.b_a[0])
        correct(st, dx)
        return Correction(float(st.C_b_n[:, 0] @ st.v_eb_n) - before,
                          self.g_mps2 * float(st.C_b_n[2, 0]) - float(st.b_a[0]) - a_before,
                          dx)

    def update(self, name: str, innovation: np.ndarray, H: np.ndarray,
               R: np.ndarray) -> UpdateOutcome:
        """One measurement update with a soft chi-square gate.

        A constraint the rover's physics guarantees is never thrown away; an innovation beyond
        the gate means the constraint is momentarily violated (bump, turn, slide) or the filter
        has drifted. Either way the update is applied with R inflated until its NIS sits on
        the gate, so it can only pull the state by a bounded, statistically plausible amount
        (robust Kalman filtering by measurement-noise scaling)."""
        gate = self._gate[len(innovation)]
        consider = self._consider if name in _BODY_VELOCITY_MODELS else \
            self._rest_consider if name == 'zaru' else None
        share = self._rest_heading_share() if name == 'zaru' else 0.0
        dx, P, rec = kalman.update(self.P, innovation, H, R, gate, name, consider, share)
        gated = not rec.accepted and math.isfinite(rec.nis)
        if gated:
            dx, P, _ = kalman.update(self.P, innovation, H, R * (rec.nis / gate), name=name,
                                     consider=consider, consider_share=share)
        self.last_records.append(rec)
        prev = self.nis_mean[name]
        self.nis_mean[name] = rec.nis if math.isnan(prev) else 0.98 * prev + 0.02 * rec.nis
        if not math.isfinite(rec.nis):
            return UpdateOutcome(rec, gated, None)
        self.P = P
        return UpdateOutcome(rec, gated, self.correct(dx))

    def _rest_heading_share(self) -> float:
        """The share of ZARU's heading gain kept: ``P_bb / (P_bb + J)`` with ``J`` the
        variance by which the rest's gyro z bias may differ from the drive's
        (:attr:`rest_bias_jump_var_rps2`; module docstring)."""
        var_bg = float(self.P[BG.start + 2, BG.start + 2])
        return var_bg / (var_bg + self.rest_bias_jump_var_rps2) if var_bg > 0.0 else 0.0

    def anchor(self, innovation: np.ndarray, H: np.ndarray, R: np.ndarray) -> Correction:
        """An ungated forward-speed update: a known jump of the INS error (not a constraint to
        be gated); heading and gyro z bias are consider states, as for the aid itself."""
        dx, self.P, _ = kalman.update(self.P, innovation, H, R, consider=self._consider)
        return self.correct(dx)

    def tilt_std_rad(self) -> float:
        """1-sigma of the attitude's tilt (north and east errors together), rad."""
        i = ATT.start
        return math.sqrt(max(float(self.P[i, i] + self.P[i + 1, i + 1]), 0.0))

    def forward_reading_var_mps2(self, spans_s: tuple[float, ...]) -> list[float]:
        """Variance of the change of the forward-speed error over each of ``spans_s`` of free
        running, m^2/s^2, as this filter's covariance predicts it: what a free-INS reading of
        a speed change over that span cannot resolve.

        The change is ``u^T (Phi(T) - I)[VEL] dx`` (``u``: the body's forward axis in
        navigation axes; ``Phi(T) ~ I + F T + F^2 T^2 / 2`` at rest-like specific force, so
        tilt and accelerometer bias act over ``T`` and the gyro bias over ``T^2 / 2``, with
        their correlations: at rest only ``g tilt - b_a`` is known, and that is what counts),
        plus the angle random walk (``g^2 S_rg T^3 / 3``) and velocity random walk
        (``S_ra T``) of the nominal noise model over the span."""
        st = self.state
        F = system_matrix(st, (0.0, 0.0, -self.g_mps2), self.planet)
        FF = F @ F
        u = st.C_b_n[:, 0]
        S_rg, S_ra = self._noise_psd[0], self._noise_psd[1]
        out = []
        for T in spans_s:
            h = u @ (T * F[VEL] + (0.5 * T * T) * FF[VEL])
            out.append(float(h @ self.P @ h) + self.g_mps2 ** 2 * S_rg * T ** 3 / 3.0
                       + S_ra * T)
        return out

    def variance(self, H: np.ndarray) -> float:
        """``H P H^T`` of a one-row H, from P of the last propagation epoch."""
        return float((H @ self.P @ H.T)[0, 0])

    def decorrelate_cross_track(self) -> None:
        """Forget the correlation of the position's cross-track error (horizontal, across the
        body's forward axis) with every other error, its variance kept (P stays positive
        semi-definite); the along-track and vertical errors keep theirs. The updates that follow
        then move the position sideways only for errors built from here on (no measurement in
        this filter sees the position itself). Where the published track ends a wheels + gyro
        fallback (:meth:`OdometryGuard.wheel`)."""
        st = self.state
        fn, fe = float(st.C_b_n[0, 0]), float(st.C_b_n[1, 0])
        norm = math.hypot(fn, fe)
        if norm < 1e-6:  # the forward axis vertical: no cross-track direction
            return
        L_rad, h_m = float(st.llh[0]), float(st.llh[2])
        R_N, R_E = radii_of_curvature(self.planet, L_rad)
        to_m = np.diag(((R_N + h_m), (R_E + h_m) * math.cos(L_rad)))
        # error states -> (along, cross) metres in place of (dL, dlambda)
        M = np.eye(N_ERR)
        i = POS.start
        M[i:i + 2, i:i + 2] = np.array([[fn, fe], [-fe, fn]]) / norm @ to_m
        P = M @ self.P @ M.T
        c = i + 1
        var = P[c, c]
        P[c, :] = 0.0
        P[:, c] = 0.0
        P[c, c] = var
        M_inv = np.linalg.inv(M)
        self.P = M_inv @ P @ M_inv.T
