"""The estimator facade: IMU and wheel samples in, odometry, slip and health out.

Processing steps for each IMU sample (numbered as in the code):

1. validate the sample and its time step;
2. before alignment: collect a stationary window, then align (roll/pitch from the specific
   force, gyro bias from the mean rate minus the planet rate, heading and position from the
   parameters);
3. strapdown mechanization at the full IMU rate;
4. covariance propagation every ``covariance_decimation`` samples over the accumulated
   interval (second-order Phi; ``covariance_decimation = 1`` is the reference path);
5. at ``update_rate_hz`` (at a propagation epoch): detectors decide, then ZUPT + ZARU
   (stationary) or the non-holonomic constraint (moving; vertical only while turning), with
   a soft chi-square gate; then the filter-health checks (repair, recover, reset);
6. slip for every wheel sample the filter has reached, from the body velocity at the wheel
   sample time.

Beyond the paper: with the paper's pseudo-measurements alone the forward velocity is
unobservable while driving, and gyro noise and vibration drift it by several cm/s within
seconds (0.1 m/s per second on the real Pathfinder logs). ``wheel_aid = 'hold'`` hands each
wheel sample to the slip model (:mod:`slip_estimator.core.slip_model`), which decides whether
the rim speed aids the forward velocity as ``r w g(s_hold)`` (the held slip, not zero slip),
whether the velocity is re-anchored after a slip change it detected on either side (the wheels
or the body, from the filter's forward speed less the aid's own recent corrections), or
whether the INS runs free while a new slip is measured. ``wheel_aid = 'off'`` is the paper's
method.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from slip_estimator.core import frames, kalman
from slip_estimator.core.alignment import MotionStart, level, specific_force_problem
from slip_estimator.core.detectors import StationaryDetector, TurnDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.error_model import (
    curvilinear_to_ned,
    process_noise,
    system_matrix,
)
from slip_estimator.core.measurements import NonHolonomic, ZeroAngularRate, ZeroVelocity
from slip_estimator.core.mechanization import mechanize_step
from slip_estimator.core.params import Params
from slip_estimator.core.planet import (
    PLANETS,
    LocalEnu,
    earth_rate_n,
    gravity_n,
    radii_of_curvature,
)
from slip_estimator.core.slip import slip_class, slip_ratio, slip_ratio_std
from slip_estimator.core.slip_model import SlipModel
from slip_estimator.core.timing import WheelTimingMonitor
from slip_estimator.core.track_width import TrackWidthEstimator
from slip_estimator.core.wheel_odometry import WheelDeadReckoning
from slip_estimator.core.state import ATT, BA, BG, N_ERR, POS, VEL, NavState, correct
from slip_estimator.core.types import (
    MAX_ANGULAR_RATE_RPS,
    MAX_SPECIFIC_FORCE_MPS2,
    Health,
    ImuSample,
    OdometryEstimate,
    SlipEstimate,
    WheelSample,
)

_NS = 1_000_000_000
_RATE_SAMPLES = 10  # IMU intervals whose median sets the nominal rate
_MOTION_TILT_STD_RAD = 0.02  # roll/pitch 1-sigma after an in-motion start (wheel-derived accel)
_HISTORY_S = 2.0
_HISTORY_NS = int(_HISTORY_S * _NS)
_MAX_PENDING_WHEEL = 50
# Odometry covariances. Pose: (position, attitude psi) in odom (ENU) is a signed permutation
# of (POS, ATT) scaled by 1 / T_r(n)^p, written as indices and signs: rows/cols
# (E, N, U) <- (lambda, L, h) and (psi_E, psi_N, psi_U) <- (psi_E, psi_N, -psi_D).
_POSE_IX = np.ix_([7, 6, 8, 1, 0, 2], [7, 6, 8, 1, 0, 2])
_POSE_SIGN = np.array([1.0, 1.0, -1.0, 1.0, 1.0, -1.0])
_TWIST_IX = np.ix_(np.r_[VEL, BG], np.r_[VEL, BG])
_FLU_FRD_SIGN = np.array([1.0, -1.0, -1.0])  # frames.C_FLU_FRD as a diagonal
_EYE_15 = np.eye(N_ERR)
_EYE_15.flags.writeable = False


class SlipEstimator:
    """Strapdown INS + 15-state error-state EKF + detectors + slip computation.

    Samples may be added in any interleaving as they arrive; each call returns the slip
    estimates that became computable (a wheel sample is evaluated once the filter has reached
    its time, so its slip refers to the body velocity at the wheel sample time).
    """

    def __init__(self, params: Params) -> None:
        self.params = params
        self.planet = PLANETS[params.planet]
        p = params
        # Lever arm IMU -> base_link origin (the wheel-contact centre), body frame b.
        r_imu_b = frames.C_FLU_FRD @ np.asarray(p.imu_to_base_xyz, dtype=float)
        self.l_bw_b = -r_imu_b
        self._l_bw_b = tuple(self.l_bw_b.tolist())
        self._wheel_latency_ns = int(p.wheel_latency_s * _NS)
        self._wheel_timeout_ns = int(p.wheel_timeout_s * _NS)
        self._ranges_known = p.accel_range_mps2 > 0.0 or p.gyro_range_rps > 0.0
        self.zupt = ZeroVelocity()
        self.zaru = ZeroAngularRate(self.planet)
        self.nhc = NonHolonomic(self.planet, self.l_bw_b)
        self.turn = TurnDetector(p.turn_rate_threshold)
        self._gate = {k: kalman.chi2_threshold(k, p.innovation_gate_probability)
                      for k in (1, 2, 3)}
        # Counters survive filter resets: they are the node's record of what happened.
        self.counters: dict[str, int] = dict.fromkeys((
            'imu_samples', 'imu_rejected', 'imu_gaps', 'imu_saturated', 'wheel_samples',
            'wheel_rejected', 'wheel_late', 'wheel_future', 'zupt', 'zaru', 'nhc', 'wheel',
            'gated', 'resets', 'recoveries', 'divergence_resets', 'covariance_repairs',
            'slip_estimates', 'slip_unknown'), 0)
        self._events: deque = deque(maxlen=20)
        self.monitor = ResidualMonitor()
        self.timing = WheelTimingMonitor()
        self.track = TrackWidthEstimator(p.track_width)
        self._S = (p.gyro_noise_density ** 2, p.accel_noise_density ** 2, p.accel_bias_psd,
                   p.gyro_bias_psd)
        self._reset_filter()

    # ------------------------------------------------------------------ lifecycle
    def _reset_filter(self) -> None:
        p = self.params
        self.state: NavState | None = None
        self.P = np.zeros((N_ERR, N_ERR))
        self.stamp_ns: int | None = None
        self._nominal_dt = 1.0 / 250.0
        self._first_dts: list[float] | None = []  # until the IMU rate is known
        self.stationary = StationaryDetector(
            max(2, int(round(p.stationary_window_s * 250.0))), p.stationary_accel_std,
            p.stationary_gyro_std, p.stationary_wheel_speed_mps, int(p.wheel_timeout_s * _NS))
        self._align_rows: list[np.ndarray] = []
        self._aligned_ns: int | None = None
        self._motion = MotionStart()
        # ENU yaw of base_link x from the heading (clockwise from north).
        self._wheel_odo = WheelDeadReckoning(math.radians(90.0 - p.initial_heading_deg))
        self.imu_problem: str | None = None
        self._acc_tau = 0.0
        # Per-sample accumulators as lists of floats (numpy costs ~1 us per 3-vector operation;
        # the element-wise float sums are the same).
        self._acc_f_n = [0.0, 0.0, 0.0]  # sum of f_ib_n * dt since the last propagation
        self._acc_n = 0
        self._next_update_ns: int | None = None
        self._since_update = [0.0, 0.0, 0.0]  # sum of omega_ib_b since the last update
        self._since_update_n = 0
        self._omega_ib_b = np.zeros(3)
        self._llh0: np.ndarray | None = None
        self._odom_frame: LocalEnu | None = None
        self._history: deque = deque()
        self._history_shift = 0.0
        self._aid_v, self._aid_a = 0.0, 0.0
        self._pending: deque = deque()
        self._last_wheel_ns: int | None = None
        self._last_stale_ns: int | None = None
        self.is_stationary = False
        self.is_turning = False
        self._recovering_until_ns: int | None = None
        self.nis_mean = {'zupt': float('nan'), 'zaru': float('nan'), 'nhc': float('nan'),
                         'wheel': float('nan')}
        self.slip_model = SlipModel(p)
        self.last_records: list[kalman.UpdateRecord] = []

    @property
    def aligned(self) -> bool:
        """True once the initial alignment is done and the filter runs."""
        return self.state is not None

    # ------------------------------------------------------------------ inputs
    def add_imu(self, sample: ImuSample) -> list[SlipEstimate]:
        """Process one IMU sample; return slip estimates that became due."""
        # 1. validate
        f_b, w_b = sample.f_ib_b, sample.omega_ib_b
        f_l, w_l = f_b.tolist(), w_b.tolist()
        if not math.isfinite(sum(f_l) + sum(w_l)):  # NaN/Inf anywhere
            self.counters['imu_rejected'] += 1
            return []
        if (f_l[0] * f_l[0] + f_l[1] * f_l[1] + f_l[2] * f_l[2] > MAX_SPECIFIC_FORCE_MPS2 ** 2
                or w_l[0] * w_l[0] + w_l[1] * w_l[1] + w_l[2] * w_l[2]
                > MAX_ANGULAR_RATE_RPS ** 2):  # finite but absurd: one step would wreck the INS
            self.counters['imu_rejected'] += 1
            return []
        if self.stamp_ns is not None and sample.stamp_ns <= self.stamp_ns:
            self.counters['imu_rejected'] += 1
            return []
        self.counters['imu_samples'] += 1
        prev_ns, self.stamp_ns = self.stamp_ns, sample.stamp_ns
        self._omega_ib_b = w_b
        self.stationary.add_imu(f_l, w_l)
        self.timing.add_imu(sample.stamp_ns, w_l[2])
        if prev_ns is None:
            return self._slip_before_alignment()
        dt = (sample.stamp_ns - prev_ns) * 1e-9
        if self._ranges_known:
            self._check_saturation(f_l, w_l)
        if dt > self.params.max_imu_gap_s:
            self.counters['imu_gaps'] += 1
            self._event(f'IMU gap of {dt:.2f} s')
            self.slip_model.interrupt()  # no step test across a hole in the INS
            if self.state is not None and dt > self.params.recovery_gap_s:
                # Not integrated across: one sample says nothing about minutes of motion.
                self._recover(sample.stamp_ns, dt, 'IMU gap')
                return self._due_slip()
        elif self._first_dts is not None:
            self._learn_rate(dt)
        else:
            self._nominal_dt = 0.99 * self._nominal_dt + 0.01 * dt
        # 2. alignment
        if self.state is None:
            self._collect_alignment(f_b, w_b, sample.stamp_ns)
            return self._slip_before_alignment()
        # 3. mechanization
        fN, fE, fD = mechanize_step(self.state, f_l, w_l, dt, self.planet)
        self._acc_tau += dt
        acc = self._acc_f_n
        acc[0] += fN * dt
        acc[1] += fE * dt
        acc[2] += fD * dt
        self._acc_n += 1
        acc = self._since_update
        acc[0] += w_l[0]
        acc[1] += w_l[1]
        acc[2] += w_l[2]
        self._since_update_n += 1
        # 4. covariance propagation (decimated), and 5. pseudo-measurements at the first
        # propagation epoch after they are due (so an update never forces an extra propagation)
        if self._acc_n >= self.params.covariance_decimation:
            self._propagate_covariance()
            if sample.stamp_ns >= self._next_update_ns:
                self._pseudo_measurements(sample.stamp_ns)
                self._check_filter_health(sample.stamp_ns)
                if self.state is None:
                    return []
        self._record_history(sample.stamp_ns, w_l, dt)
        # 6. slip
        return self._due_slip()

    def add_wheel(self, sample: WheelSample) -> list[SlipEstimate]:
        """Process one wheel sample; return slip estimates that became due."""
        speeds = [v for v in (sample.rim_speed_mps, sample.rim_speed_left_mps,
                              sample.rim_speed_right_mps) if v is not None]
        if not all(math.isfinite(v) and abs(v) <= self.params.max_wheel_speed_mps
                   for v in speeds):
            self.counters['wheel_rejected'] += 1
            return []
        if self._last_wheel_ns is not None and sample.stamp_ns <= self._last_wheel_ns:
            self.counters['wheel_rejected'] += 1
            return []
        self.counters['wheel_samples'] += 1
        self._last_wheel_ns = sample.stamp_ns
        self._last_stale_ns = None
        self.stationary.add_wheel(sample.stamp_ns, max(abs(v) for v in speeds))
        if sample.rim_speed_left_mps is not None and sample.rim_speed_right_mps is not None:
            self.timing.add_wheel(sample.stamp_ns,
                                  sample.rim_speed_right_mps - sample.rim_speed_left_mps)
        self._pending.append(sample)
        if self.state is None:
            self._motion.add_wheel(sample.stamp_ns, sample.rim_speed_mps)
            self._wheel_odo.add(sample, self.track.width_m)
        if len(self._pending) > _MAX_PENDING_WHEEL:
            # Wheel stamps far ahead of the IMU (clock offset or IMU dropout): keep the newest.
            self._pending.popleft()
            self.counters['wheel_future'] += 1
        if self.state is None:
            return self._slip_before_alignment()
        return self._due_slip()

    # ------------------------------------------------------------------ faults and recovery
    def _event(self, text: str) -> None:
        self._events.append((self.stamp_ns, text))

    def _check_saturation(self, f_b: list[float], w_b: list[float]) -> None:
        p = self.params
        if ((p.accel_range_mps2 > 0.0 and max(map(abs, f_b)) >= 0.999 * p.accel_range_mps2)
                or (p.gyro_range_rps > 0.0
                    and max(map(abs, w_b)) >= 0.999 * p.gyro_range_rps)):
            self.counters['imu_saturated'] += 1
            self._event('IMU at its measurement range (clipping)')

    def _recover(self, stamp_ns: int, gap_s: float, reason: str) -> None:
        """Re-initialise velocity and inflate the covariance after an IMU gap or a divergence.

        Attitude and position are kept (a rover does not teleport, but it may have moved for
        ``gap_s``); velocity restarts from the last wheel speed; slip is "unknown" until
        ``recovery_s`` has passed and the wheel aid has re-anchored the velocity."""
        p = self.params
        st = self.state
        self.counters['recoveries'] += 1
        self._event(f'{reason}: velocity re-initialised, slip unknown for {p.recovery_s:.0f} s')
        rim = self._pending[-1].rim_speed_mps if self._pending else 0.0
        st.v_eb_n = st.C_b_n[:, 0] * rim
        st.C_b_n = frames.orthonormalize(st.C_b_n)
        P = self._initial_covariance(-gravity_n(self.planet, st.llh[0], st.llh[2]))
        T = curvilinear_to_ned(self.planet, st.llh[0], st.llh[2])
        d = np.diag(P).copy()
        d[VEL] = 1.0
        d[POS] = (np.diag(T) * (0.01 + p.max_wheel_speed_mps * gap_s)) ** 2
        self.P = np.diag(d)
        self._acc_tau, self._acc_f_n, self._acc_n = 0.0, [0.0, 0.0, 0.0], 0
        self._history.clear()
        self._aid_v, self._aid_a = 0.0, 0.0
        self.slip_model.reset(from_rest=False)  # the velocity now comes from the rim
        self._recovering_until_ns = stamp_ns + int(p.recovery_s * _NS)
        self._next_update_ns = stamp_ns

    def _check_filter_health(self, stamp_ns: int) -> None:
        """Covariance must stay finite, symmetric and positive definite; the state must stay
        within physical bounds. Repair what can be repaired, otherwise re-initialise."""
        p = self.params
        st = self.state
        # A finite sum has finite terms; only a non-finite sum (NaN/Inf, or an overflow of
        # finite terms) needs the element-wise check.
        if not (math.isfinite(float(self.P.sum()) + sum(st.v_eb_n.tolist())
                              + sum(st.C_b_n.ravel().tolist()) + sum(st.llh.tolist()))
                or (np.isfinite(self.P).all() and np.isfinite(st.v_eb_n).all()
                    and np.isfinite(st.C_b_n).all() and np.isfinite(st.llh).all())):
            self.counters['resets'] += 1
            self._event('non-finite filter state: full reset, re-aligning')
            self._reset_filter()
            return
        if self.P.diagonal().min() <= 0.0:
            w, V = np.linalg.eigh(kalman.symmetrize(self.P))
            self.P = kalman.symmetrize((V * np.maximum(w, 1e-18)) @ V.T)
            self.counters['covariance_repairs'] += 1
            self._event('covariance lost positive definiteness: repaired')
        speed = math.sqrt(st.v_eb_n.dot(st.v_eb_n))  # np.linalg.norm of a vector
        bias_out = (np.abs(st.b_a).max() > 10.0 * p.initial_accel_bias_std
                    or np.abs(st.b_g).max() > 10.0 * p.initial_gyro_bias_std)
        if speed > 2.0 * p.max_wheel_speed_mps or bias_out:
            self.counters['divergence_resets'] += 1
            if bias_out:
                st.b_a = np.clip(st.b_a, -p.initial_accel_bias_std, p.initial_accel_bias_std)
                st.b_g = np.clip(st.b_g, -p.initial_gyro_bias_std, p.initial_gyro_bias_std)
            self._recover(stamp_ns, 0.0, 'divergence (speed %.1f m/s%s)' % (
                speed, ', biases out of bounds' if bias_out else ''))

    # ------------------------------------------------------------------ alignment
    def _collect_alignment(self, f_b: np.ndarray, w_b: np.ndarray, stamp_ns: int) -> None:
        p = self.params
        self._motion.add_imu(stamp_ns, f_b, w_b)
        if not self.stationary.is_stationary(stamp_ns):
            self._align_rows.clear()
            if (stamp_ns - self._motion.first_ns >= p.motion_alignment_after_s * _NS
                    and self._motion.ready(stamp_ns)
                    and not self._imu_refused(self._motion.mean_imu()[0])):
                self._align_in_motion(stamp_ns)
            return
        self._align_rows.append(np.concatenate([f_b, w_b]))
        if len(self._align_rows) * self._nominal_dt >= p.alignment_duration_s:
            rows = np.array(self._align_rows)
            if not self._imu_refused(rows[:, :3].mean(axis=0)):
                self._align(rows[:, :3].mean(axis=0), rows[:, 3:].mean(axis=0), stamp_ns)

    def _learn_rate(self, dt: float) -> None:
        """The IMU's own rate, from the median of its first intervals: every window that is
        defined in seconds (stationarity, alignment) then holds that many of its samples,
        whatever the rate (20-1000 Hz)."""
        self._first_dts.append(dt)
        if len(self._first_dts) < _RATE_SAMPLES:
            return
        self._nominal_dt = float(np.median(self._first_dts))
        self._first_dts = None
        n = max(2, int(round(self.params.stationary_window_s / self._nominal_dt)))
        if n != self.stationary.window_samples:
            self.stationary.resize(n)

    def _imu_refused(self, f_mean_b: np.ndarray) -> bool:
        """An IMU that does not follow REP-145 (gravity removed, g units, mounted otherwise
        than declared) is named and not aligned on: no estimate beats a wrong one."""
        g_n = gravity_n(self.planet, math.radians(self.params.initial_latitude_deg),
                        self.params.initial_height_m)
        self.imu_problem = specific_force_problem(f_mean_b, float(np.linalg.norm(g_n)))
        return self.imu_problem is not None

    def _align_in_motion(self, stamp_ns: int) -> None:
        """No stationary window came (a robot moving from its first second, or an IMU too
        noisy for the stationarity thresholds): level on the specific force less the
        wheel-derived acceleration (:mod:`slip_estimator.core.alignment`), start the velocity
        from the rim speed with a wide covariance, the gyro bias at zero, and report slip
        'unknown' for ``recovery_s`` while the wheels re-anchor the velocity (zero slip
        assumed). A later stop's ZUPT/ZARU refine it."""
        p = self.params
        self._align(self._motion.specific_force(), None, stamp_ns)
        st = self.state
        speed, _ = self._motion.speed_and_accel()
        st.v_eb_n = st.C_b_n[:, 0] * speed
        d = self.P.diagonal().copy()
        tilt_var = max(p.initial_attitude_std, _MOTION_TILT_STD_RAD) ** 2
        self.P[0, 0] += tilt_var - d[0]
        self.P[1, 1] += tilt_var - d[1]
        self.P[VEL, VEL] = (0.1 + 0.2 * abs(speed)) ** 2
        self.slip_model.reset(from_rest=False)
        self._recovering_until_ns = stamp_ns + int(p.recovery_s * _NS)
        self._event(f'aligned in motion (no stationary window in '
                    f'{p.motion_alignment_after_s:.1f} s): slip unknown for {p.recovery_s:.0f} s')

    def _align(self, f: np.ndarray, w: np.ndarray | None, stamp_ns: int) -> None:
        """Levelling from the specific force ``f`` (minus gravity, Groves sec. 5.6.2); the gyro
        bias from the mean rate ``w`` at rest (None in motion: zero)."""
        p = self.params
        roll, pitch = level(f)
        C_b_n = frames.rpy_to_dcm(roll, pitch, math.radians(p.initial_heading_deg))
        llh = np.array([math.radians(p.initial_latitude_deg),
                        math.radians(p.initial_longitude_deg), p.initial_height_m])
        # Position of the IMU; the parameters give base_link's.
        r_imu_b = -self.l_bw_b
        llh = llh - curvilinear_to_ned(self.planet, llh[0], llh[2]) @ (-(C_b_n @ r_imu_b))
        b_g = (np.zeros(3) if w is None
               else w - C_b_n.T @ earth_rate_n(self.planet, llh[0]))
        self.state = NavState(C_b_n, np.zeros(3), llh, np.zeros(3), b_g)
        # Base_link position at alignment: the origin of odom.
        self._g_mps2 = float(np.linalg.norm(f))
        self._llh0 = self._base_llh()
        self._odom_frame = LocalEnu(self.planet, self._llh0)
        self.P = self._initial_covariance(f)
        self._next_update_ns = stamp_ns
        self._aligned_ns = stamp_ns
        self._align_rows = []

    def _initial_covariance(self, f_b: np.ndarray) -> np.ndarray:
        """Initial P. Levelling absorbs the horizontal accelerometer bias into roll/pitch, so
        the tilt error equals ``-C b_a / g`` (Groves eq. 5.103); P carries that correlation,
        otherwise the first acceleration is mistaken for a tilt change."""
        p = self.params
        g = float(np.linalg.norm(f_b))
        T = curvilinear_to_ned(self.planet, self.state.llh[0], self.state.llh[2])
        d = np.zeros(N_ERR)
        d[ATT] = [p.initial_attitude_std ** 2, p.initial_attitude_std ** 2,
                  p.initial_heading_std ** 2]
        d[VEL] = p.initial_velocity_std ** 2
        d[POS] = (np.diag(T) * 0.01) ** 2
        d[BA] = p.initial_accel_bias_std ** 2
        d[BG] = p.initial_gyro_bias_std ** 2
        J = np.eye(N_ERR)
        C = self.state.C_b_n
        J[0, BA] = -C[1] / g
        J[1, BA] = C[0] / g
        return J @ np.diag(d) @ J.T

    # ------------------------------------------------------------------ filter steps
    def _propagate_covariance(self) -> None:
        if self._acc_n == 0:
            return
        tau = self._acc_tau
        a_N, a_E, a_D = self._acc_f_n
        F = system_matrix(self.state, (a_N / tau, a_E / tau, a_D / tau), self.planet)
        Ft = F * tau
        Phi = Ft + _EYE_15  # Phi = I + F tau + (F tau)^2 / 2
        Ft2 = Ft @ Ft
        Ft2 *= 0.5
        Phi += Ft2
        Q = process_noise(self.state, F, tau, *self._vibration_psd(), self.planet)
        self.P = kalman.predict(self.P, Phi, Q)
        self.state.C_b_n = frames.orthonormalize(self.state.C_b_n)
        self._acc_tau = 0.0
        self._acc_f_n = [0.0, 0.0, 0.0]
        self._acc_n = 0

    def _vibration_psd(self) -> tuple[float, float, float, float]:
        """Process-noise PSDs (S_rg, S_ra, S_bad, S_bgd) inflated by the vibration seen now.

        Driving over rough ground shakes a rover's IMU by orders of magnitude more than the
        sensor noise (Pathfinder: 1-3 m/s^2 and 0.1 rad/s RMS driving, 0.015 and 0.001 at rest).
        Strapdown integration of it leaves errors (sampling, coning/sculling, g-sensitivity) that
        a fixed white-noise model ignores, and an over-confident filter then turns constraint
        residuals into wild attitude corrections. A fraction of the window spread is therefore
        added as white noise: ``S = N^2 + k^2 (sigma^2 - N^2 / dt) dt`` (only the spread beyond
        the sensor noise, so a rover at rest keeps the plain noise model).
        """
        S_rg, S_ra, S_bad, S_bgd = self._S
        k = self.params.vibration_noise_fraction
        if k <= 0.0 or self.stationary.window.n < 2:
            return self._S
        var = self.stationary.window.variance().tolist()  # finite: samples are checked
        dt = self._nominal_dt
        # Only the spread beyond the white noise already in S (sigma^2 = S / dt per sample).
        excess_g = max(0.0, max(var[3:]) - S_rg / dt)
        excess_a = max(0.0, max(var[:3]) - S_ra / dt)
        return S_rg + k * k * excess_g * dt, S_ra + k * k * excess_a * dt, S_bad, S_bgd

    def _correct(self, dx: np.ndarray, aid: bool = False) -> None:
        """Close the loop on ``dx``. The forward-speed change is also applied to the recorded
        history (as a running shift), so a wheel sample that describes an earlier instant
        (``wheel_latency_s``) is compared with the corrected, not the superseded, estimate.
        A wheel-aid correction (``aid``) is also recorded for the slip model's free speed."""
        st = self.state
        before = float(st.C_b_n[:, 0] @ st.v_eb_n)
        if aid:
            a_before = self._g_mps2 * float(st.C_b_n[2, 0]) - float(st.b_a[0])
        correct(st, dx)
        change = float(st.C_b_n[:, 0] @ st.v_eb_n) - before
        self._history_shift += change
        if aid:
            self._aid_v += change
            self._aid_a += self._g_mps2 * float(st.C_b_n[2, 0]) - float(st.b_a[0]) - a_before

    def _apply(self, name: str, innovation: np.ndarray, H: np.ndarray, R: np.ndarray,
               channels: tuple[str, ...] | None = None, excluded: bool = False) -> None:
        """One pseudo-measurement update with a soft chi-square gate.

        A constraint the rover's physics guarantees is never thrown away; an innovation beyond
        the gate means the constraint is momentarily violated (bump, turn, slide) or the filter
        has drifted. Either way the update is applied with R inflated until its NIS sits on
        the gate, so it can only pull the state by a bounded, statistically plausible amount
        (robust Kalman filtering by measurement-noise scaling)."""
        gate = self._gate[len(innovation)]
        dx, P, rec = kalman.update(self.P, innovation, H, R, gate, name)
        if not rec.accepted and math.isfinite(rec.nis):
            self.counters['gated'] += 1
            dx, P, _ = kalman.update(self.P, innovation, H, R * (rec.nis / gate), name=name)
        self.last_records.append(rec)
        if math.isfinite(rec.nis):
            if channels is None:
                self.monitor.add(name, innovation, rec.S)
            else:
                for i, channel in enumerate(channels):
                    self.monitor.add(channel, innovation[i:i + 1], rec.S[i:i + 1, i:i + 1])
        prev = self.nis_mean[name]
        self.nis_mean[name] = rec.nis if math.isnan(prev) else 0.98 * prev + 0.02 * rec.nis
        if math.isfinite(rec.nis):
            self.P = P
            self.counters[name] += 1
            self._correct(dx, aid=excluded)

    def _pseudo_measurements(self, stamp_ns: int) -> None:
        p = self.params
        self._propagate_covariance()
        self.last_records = []
        self._next_update_ns = stamp_ns + int(_NS / p.update_rate_hz)
        w_mean = np.array(self._since_update) / max(1, self._since_update_n)
        period = max(1, self._since_update_n) * self._nominal_dt
        self._since_update = [0.0, 0.0, 0.0]
        self._since_update_n = 0
        self.is_stationary = self.stationary.is_stationary(stamp_ns)
        w_nb_b = w_mean - self.state.b_g
        self.is_turning = self.turn.is_turning(w_nb_b, self.state.C_b_n)
        if self.is_stationary:
            self._apply('zupt', self.zupt.innovation(self.state), self.zupt.jacobian(self.state),
                        np.eye(3) * p.zupt_velocity_std ** 2)
            r = p.zaru_rate_std ** 2 + p.gyro_noise_density ** 2 / period
            self._apply('zaru', self.zaru.innovation(self.state, w_mean),
                        self.zaru.jacobian(self.state), np.eye(3) * r)
        else:
            rows = (2,) if self.is_turning else (1, 2)
            sig = {1: p.nhc_lateral_std, 2: p.nhc_vertical_std}
            R = np.diag([sig[r] ** 2 for r in rows])
            names = {1: 'nhc_lateral', 2: 'nhc_vertical'}
            self._apply('nhc', self.nhc.innovation(self.state, w_mean, rows),
                        self.nhc.jacobian(self.state, rows), R, tuple(names[r] for r in rows))

    # ------------------------------------------------------------------ slip
    def _record_history(self, stamp_ns: int, w_b: list[float], dt: float) -> None:
        # Forward component of NonHolonomic.point_velocity_b, in scalars (runs at IMU rate;
        # the planet-rate part of the lever-arm term, < 3e-5 m/s, is left out).
        st = self.state
        _, bg_y, bg_z = st.b_g.tolist()
        wy, wz = w_b[1] - bg_y, w_b[2] - bg_z
        _, ly, lz = self._l_bw_b
        c1, c2, c3 = st.C_b_n[:, 0].tolist()
        vN, vE, vD = st.v_eb_n.tolist()
        v_fwd = (c1 * vN + c2 * vE + c3 * vD) + wy * lz - wz * ly
        # The slip model's free forward speed: the filter's, less what the wheel aid did to it
        # (its velocity jumps, and the along-track acceleration its attitude and
        # accelerometer-bias corrections cause from then on), with that acceleration, so that
        # a speed change over an interval can be taken without the aid corrections made in it
        # (the aid cannot hide a slip step by tilting the INS).
        self._aid_v += self._aid_a * dt
        history = self._history
        history.append((stamp_ns, v_fwd - self._history_shift, wz, v_fwd - self._aid_v,
                        self._aid_a))
        horizon = stamp_ns - _HISTORY_NS
        while history[0][0] < horizon:  # never empties: the newest entry is not older
            history.popleft()

    def _history_at(self, stamp_ns: int) -> tuple[float, float, float, float] | None:
        """Forward speed, yaw rate (FRD), the slip model's free forward speed and the aid's
        along-track acceleration (see :meth:`_record_history`) at ``stamp_ns``, by linear
        interpolation."""
        h = self._history
        if not h or stamp_ns < h[0][0] or stamp_ns > h[-1][0]:
            return None
        lo, hi = 0, len(h) - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if h[mid][0] <= stamp_ns:
                lo = mid
            else:
                hi = mid
        t0, v0, y0, f0, a0 = h[lo]
        t1, v1, y1, f1, a1 = h[hi]
        a = 0.0 if t1 == t0 else (stamp_ns - t0) / (t1 - t0)
        return (v0 + a * (v1 - v0) + self._history_shift, y0 + a * (y1 - y0),
                f0 + a * (f1 - f0), a0 + a * (a1 - a0))

    def covariance(self) -> np.ndarray:
        """Error-state covariance at the time of the last IMU sample (flushes the decimated
        propagation)."""
        if self.state is not None:
            self._propagate_covariance()
        return self.P

    def _forward_speed_variance(self) -> float:
        # P of the last propagation epoch (at most covariance_decimation samples old): the
        # slip sigma does not justify an extra propagation per wheel sample.
        H = self.nhc.jacobian(self.state, (0,))
        return float((H @ self.P @ H.T)[0, 0])

    def _due_slip(self) -> list[SlipEstimate]:
        out: list[SlipEstimate] = []
        while self._pending and self._pending[0].stamp_ns <= self.stamp_ns:
            wheel = self._pending.popleft()
            # The body velocity the wheel speed belongs to: ``wheel_latency_s`` before its stamp.
            at = self._history_at(wheel.stamp_ns - self._wheel_latency_ns)
            if at is None:
                self.counters['wheel_late'] += 1
                continue
            v_hist, yaw_rate_b, v_free, aid_accel = at
            if wheel.rim_speed_left_mps is not None and wheel.rim_speed_right_mps is not None:
                self.track.add(-yaw_rate_b,
                               wheel.rim_speed_right_mps - wheel.rim_speed_left_mps)
            if self._recovering(wheel.stamp_ns):
                # Re-anchor the velocity on the wheels (zero slip assumed, so slip is unknown).
                if self.params.wheel_aid != 'off' and not self.is_turning:
                    w = wheel.rim_speed_mps
                    self._aid_update(w, v_hist, self.params.wheel_aid_std ** 2 + (0.1 * w) ** 2,
                                     excluded=False)
                out.append(self._unknown(wheel.stamp_ns, wheel.rim_speed_mps))
                continue
            est = self._slip(wheel, v_hist, yaw_rate_b)
            out.append(est)
            if self.params.wheel_aid == 'hold':
                self._apply_slip_model(wheel, v_hist, v_free, aid_accel, est)
        out.extend(self._stale_check())
        return out

    def _recovering(self, stamp_ns: int) -> bool:
        if self._recovering_until_ns is None:
            return False
        if stamp_ns >= self._recovering_until_ns:
            self._recovering_until_ns = None
            return False
        return True

    def _apply_slip_model(self, wheel: WheelSample, v_hist: float, v_free: float,
                          aid_accel: float, est: SlipEstimate) -> None:
        """Let the slip model (:mod:`slip_estimator.core.slip_model`) decide the wheel aid."""
        w = wheel.rim_speed_mps
        moving = est.slip_class > 0 and abs(w) >= self.params.moving_speed_threshold
        pitch_rad = -math.asin(max(-1.0, min(1.0, float(self.state.C_b_n[2, 0]))))
        d = self.slip_model.step(wheel.stamp_ns, w, v_hist, v_free, moving, self.is_turning,
                                 pitch_rad, aid_accel)
        if d is None:
            return
        if d.held_slip is not None:
            self.monitor.add_held_slip(d.held_slip)
        if d.anchor:
            # A known jump of the INS error (a change, or a settled measurement): not gated.
            dx, self.P, _ = kalman.update(self.P, np.array([d.z_mps - v_hist]),
                                          self.nhc.jacobian(self.state, (0,)),
                                          np.array([[d.var_mps2]]))
            self._correct(dx, aid=not d.repair)
            return
        self._aid_update(d.z_mps, v_hist, d.var_mps2, excluded=not d.repair)

    def _aid_update(self, z_mps: float, v_hist: float, var: float,
                    excluded: bool = True) -> None:
        """Forward-velocity update of the base point with the aid value ``z_mps`` at the wheel
        sample time (``v_hist`` is the INS value then); ``excluded``: the slip model's free
        speed does not see it."""
        self._apply('wheel', np.array([z_mps - v_hist]), self.nhc.jacobian(self.state, (0,)),
                    np.array([[var]]), excluded=excluded)

    def _slip(self, wheel: WheelSample, v_body: float, yaw_rate_b: float) -> SlipEstimate:
        p = self.params
        var_v = self._forward_speed_variance()
        var_w = p.wheel_speed_std ** 2
        w = wheel.rim_speed_mps
        # "Not moving" when the rim speed is below the threshold and the body speed is not
        # significantly above it (an in-place turn or a stop must not read as extreme slip
        # because of a few cm/s of velocity uncertainty).
        body_threshold = max(p.moving_speed_threshold, 3.0 * math.sqrt(max(var_v, 0.0)))
        # The stationarity detector (IMU still and wheels stopped) says "not moving" outright:
        # a few cm/s of INS error at a stop must not read as a body sliding off its wheels.
        moving = (abs(w) >= p.moving_speed_threshold or abs(v_body) >= body_threshold) \
            and not self.is_stationary
        s = slip_ratio(v_body, w) if moving else 0.0
        s_std = slip_ratio_std(v_body, w, var_v, var_w) if moving else 0.0
        sides = [None, None]
        if wheel.rim_speed_left_mps is not None and wheel.rim_speed_right_mps is not None \
                and moving:
            # FRD yaw rate > 0 turns right: the left track moves faster.
            half = 0.5 * self.track.width_m * yaw_rate_b
            sides = [slip_ratio(v_body + half, wheel.rim_speed_left_mps),
                     slip_ratio(v_body - half, wheel.rim_speed_right_mps)]
        self.counters['slip_estimates'] += 1
        return SlipEstimate(wheel.stamp_ns, s, s_std, slip_class(s, moving), v_body,
                            math.sqrt(max(var_v, 0.0)), w, sides[0], sides[1])

    def _unknown(self, stamp_ns: int, wheel_speed: float = 0.0) -> SlipEstimate:
        self.counters['slip_unknown'] += 1
        return SlipEstimate(stamp_ns, float('nan'), float('nan'), -1, float('nan'),
                            float('nan'), wheel_speed)

    def _slip_before_alignment(self) -> list[SlipEstimate]:
        """Before alignment only "not moving" is known (wheels and IMU at rest)."""
        out = []
        while self._pending:
            wheel = self._pending.popleft()
            if (abs(wheel.rim_speed_mps) < self.params.moving_speed_threshold
                    and self.stationary.imu_steady()):
                self.counters['slip_estimates'] += 1
                out.append(SlipEstimate(wheel.stamp_ns, 0.0, 0.0, 0, 0.0, 0.0,
                                        wheel.rim_speed_mps))
            else:
                out.append(self._unknown(wheel.stamp_ns, wheel.rim_speed_mps))
        return out

    def _stale_check(self) -> list[SlipEstimate]:
        """Wheel dropout, or no wheel data at all: report "unknown" once per timeout instead of
        guessing (with no wheels the filter runs as an INS with ZUPT/ZARU only)."""
        last = self._last_stale_ns if self._last_stale_ns is not None else self._last_wheel_ns
        if last is None:
            last = self._aligned_ns
        if last is None or self.stamp_ns - last <= self._wheel_timeout_ns:
            return []
        self._last_stale_ns = self.stamp_ns
        if self._last_wheel_ns is None:
            self._event('no wheel data: slip unknown, INS with ZUPT/ZARU only')
        else:
            self._event(f'wheel data missing for '
                        f'{(self.stamp_ns - self._last_wheel_ns) * 1e-9:.1f} s: slip unknown')
        return [self._unknown(self.stamp_ns)]

    # ------------------------------------------------------------------ outputs
    def _base_llh(self) -> np.ndarray:
        r_bw_n = self.state.C_b_n @ self.l_bw_b
        return self.state.llh + curvilinear_to_ned(self.planet, self.state.llh[0],
                                                   self.state.llh[2]) @ r_bw_n

    def odometry(self) -> OdometryEstimate | None:
        """Current fused solution of base_link in odom, or None before alignment.

        Output only (nothing here feeds back into the filter), on floats where numpy would
        cost more than the arithmetic; a test checks it against the matrix formulas."""
        if self.state is None:
            # An IMU refused as non-REP-145: the wheels alone give a pose (degraded mode).
            return (self._wheel_odo.estimate(self.stamp_ns)
                    if self.imu_problem is not None and self.stamp_ns is not None else None)
        st = self.state
        L, lam, h = st.llh.tolist()
        c11, c12, c13, c21, c22, c23, c31, c32, c33 = C = st.C_b_n.ravel().tolist()
        vN, vE, vD = st.v_eb_n.tolist()
        lx, ly, lz = self._l_bw_b
        R_N, R_E = radii_of_curvature(self.planet, L)
        T_L, T_lam = 1.0 / (R_N + h), 1.0 / ((R_E + h) * math.cos(L))  # T_r(n)^p, T_h = -1
        # base_link position: llh + T C_b_n l_bw_b, in odom.
        p_o = self._odom_frame.enu(L + T_L * (c11 * lx + c12 * ly + c13 * lz),
                                   lam + T_lam * (c21 * lx + c22 * ly + c23 * lz),
                                   h - (c31 * lx + c32 * ly + c33 * lz))
        # C_base_odom = C_ENU_NED C_b_n C_FLU_FRD: rows N, E swapped, D negated; y, z negated.
        q = frames.dcm_to_quat_wxyz_floats(c21, -c22, -c23, c11, -c12, -c13, -c31, c32, c33)
        # omega_eb_b = omega_ib_b - b_g - C_n_b omega_ie_n; v = C_n_b v_eb_n + omega_eb_b x l.
        w_ie = self.planet.omega_ie_rps
        w_ie_N, w_ie_D = w_ie * math.cos(L), -w_ie * math.sin(L)
        o1, o2, o3 = self._omega_ib_b.tolist()
        b1, b2, b3 = st.b_g.tolist()
        wx = o1 - b1 - (c11 * w_ie_N + c31 * w_ie_D)
        wy = o2 - b2 - (c12 * w_ie_N + c32 * w_ie_D)
        wz = o3 - b3 - (c13 * w_ie_N + c33 * w_ie_D)
        vx = c11 * vN + c21 * vE + c31 * vD + (wy * lz - wz * ly)
        vy = c12 * vN + c22 * vE + c32 * vD + (wz * lx - wx * lz)
        vz = c13 * vN + c23 * vE + c33 * vD + (wx * ly - wy * lx)
        # Covariances from P of the last propagation epoch (at most covariance_decimation
        # samples old). Pose: position (curvilinear -> NED m -> ENU) and attitude psi (NED ->
        # ENU), i.e. M P M^T with M = diag(C_ENU_NED T^-1, C_ENU_NED), a scaled signed
        # permutation: indexing and scaling. Twist: velocity (NED -> base_link) and gyro bias
        # (b -> base_link), M = diag(C_FLU_FRD C_n_b, C_FLU_FRD), plus the gyro noise.
        s = np.array((1.0 / T_lam, 1.0 / T_L, 1.0, 1.0, 1.0, -1.0))
        pose_cov = (s[:, None] * s) * self.P[_POSE_IX]  # symmetric as P is: s_a s_b = s_b s_a
        M = np.zeros((6, 6))
        M[:3, :3] = (C[0:9:3], [-c for c in C[1:9:3]], [-c for c in C[2:9:3]])
        M[[3, 4, 5], [3, 4, 5]] = _FLU_FRD_SIGN
        twist_cov = M @ self.P[_TWIST_IX] @ M.T
        twist_cov[[3, 4, 5], [3, 4, 5]] += self.params.gyro_noise_density ** 2 / self._nominal_dt
        return OdometryEstimate(self.stamp_ns, np.array(p_o), np.array(q),
                                np.array((vx, -vy, -vz)), np.array((wx, -wy, -wz)),
                                pose_cov, kalman.symmetrize(twist_cov))

    def health(self) -> Health:
        """Current self-diagnosis: state, counters, NIS statistics, bias estimates."""
        values: dict = dict(self.counters)
        if self.state is None and self.imu_problem is not None:
            return Health(2, f'IMU not usable, not aligning (odometry from the wheels only, slip '
                          f'unknown): {self.imu_problem}', values)
        if self.state is None:
            recent = '; '.join(dict.fromkeys(text for _, text in self._events))
            return Health(1, 'aligning: waiting for a stationary window or '
                          f'{self.params.motion_alignment_after_s:.1f} s of IMU and wheel data'
                          + (f' (after: {recent})' if recent else ''), values)
        st = self.state
        sig = np.sqrt(np.maximum(np.diag(self.P), 0.0))
        values.update({
            'stationary': self.is_stationary, 'turning': self.is_turning,
            'velocity_std_mps': float(np.linalg.norm(sig[VEL])),
            'heading_std_rad': float(sig[2]),
            'accel_bias_mps2': [float(x) for x in st.b_a],
            'gyro_bias_rps': [float(x) for x in st.b_g],
        })
        for k, v in self.nis_mean.items():
            values[f'nis_mean_{k}'] = v
        values.update(self.monitor.values())
        notes = [f'suspected: {text}' for text in self.monitor.suspects()]
        lag, corr = self.timing.lag_s, self.timing.correlation
        values['wheel_lag_s'], values['wheel_lag_correlation'] = lag, corr
        values['effective_track_width_m'] = self.track.width_m
        values['effective_track_ratio'] = self.track.width_m / self.params.track_width
        if corr >= 0.8 and abs(lag - self.params.wheel_latency_s) > 0.05:
            # The turns say when the wheels moved: a lag the parameters do not declare shifts
            # every slip step against the body motion.
            notes.append(f'suspected: wheel stamps {lag * 1e3:+.0f} ms behind the IMU (yaw rate '
                         f'vs wheel differential in turns, r = {corr:.2f}) against a declared '
                         f'wheel_latency_s of {self.params.wheel_latency_s:.3f} s: clock offset '
                         'or undeclared latency')
        level = 1 if notes else 0
        if np.any(np.abs(st.b_g) > 5.0 * self.params.initial_gyro_bias_std):
            level = 1
            notes.append('gyro bias estimate beyond 5 sigma of its prior')
        if np.any(np.abs(st.b_a) > 5.0 * self.params.initial_accel_bias_std):
            level = 1
            notes.append('accelerometer bias estimate beyond 5 sigma of its prior')
        recent = [text for t, text in self._events
                  if t is not None and self.stamp_ns - t <= 10 * _NS]
        if recent:
            level = max(level, 1)
            notes = list(dict.fromkeys(recent)) + notes
        if self._recovering_until_ns is not None:
            level = max(level, 1)
        state = 'recovering' if self._recovering_until_ns is not None else 'running'
        return Health(level, state + (': ' + '; '.join(notes) if notes else ''), values)
