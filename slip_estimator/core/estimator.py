"""The estimator facade: IMU and wheel samples in, odometry, slip and health out.

It owns its parts (the filter, measurement models, alignment, detectors and monitors, the
supervisor, the forward-speed history, the wheel aid, the wheel-sample update, the pure
outputs) and moves data between them by calls and return values; no part calls back into it.
A wheel sample describes the body ``wheel_latency_s`` before its stamp, which the INS may not
have reached yet: ``add_wheel`` queues it, and the call that brings the INS past its stamp
hands it to the :class:`~slip_estimator.core.wheel_update.WheelUpdate` (its slip, then the
wheel aid).
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core import frames, outputs
from slip_estimator.core.alignment import AlignmentCollector, AlignmentStart
from slip_estimator.core.detectors import ImuRate, StationaryDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.filter_start import filter_start, recovery_covariance, relevel
from slip_estimator.core.history import ForwardSpeedHistory, WheelQueue
from slip_estimator.core.measurements import ForwardSpeed
from slip_estimator.core.odometry_guard import OdometryGuard
from slip_estimator.core.params import Params
from slip_estimator.core.planet import PLANETS, LocalEnu
from slip_estimator.core.slip_model.model import CHANGE_LOOKBACK_S
from slip_estimator.core.slip_model.wheel_aid import WheelAid
from slip_estimator.core.state import NavState
from slip_estimator.core.supervisor import GapAction, Supervisor
from slip_estimator.core.timing import WheelTimingMonitor
from slip_estimator.core.types import (Health, ImuSample, OdometryEstimate, SlipEstimate,
                                       WheelSample, wheel_speeds)
from slip_estimator.core.updater import Updater
from slip_estimator.core.wheel_odometry import WheelDeadReckoning
from slip_estimator.core.wheel_update import WheelUpdate

_NS = 1_000_000_000


class SlipEstimator:
    """Strapdown INS + 15-state error-state EKF + detectors + slip computation. Samples may
    be added in any interleaving; each call returns the slip estimates that became computable."""

    def __init__(self, p: Params) -> None:
        self.planet = PLANETS[p.planet]
        # Lever arm IMU -> base_link origin (the wheel-contact centre), body frame b.
        self.l_bw_b = -(frames.C_FLU_FRD @ np.asarray(p.imu_to_base_xyz, dtype=float))
        self._l_bw_b = tuple(self.l_bw_b.tolist())
        self._wheel_latency_ns = int(p.wheel_latency_s * _NS)
        self.forward = ForwardSpeed(self.planet, self.l_bw_b)
        # These survive filter resets: they are the node's record of what happened.
        self.supervisor = Supervisor(p)
        self.counters = self.supervisor.counters
        self.monitor = ResidualMonitor()
        self.updater = Updater(p, self.planet, self.l_bw_b, self.counters, self.monitor)
        self.timing = WheelTimingMonitor()
        self.track = self.updater.yaw_aid.track
        self._reset_filter()

    def _reset_filter(self) -> None:
        """Everything the filter's history made: new (at start and after a full reset)."""
        p = self.params
        self.filter = ErrorStateFilter(p, self.planet)
        self.stamp_ns: int | None = None
        self.imu_rate = ImuRate()
        self.stationary = StationaryDetector.for_params(p)
        self.alignment = AlignmentCollector(p, self.planet)
        self._aligned_ns: int | None = None
        self.odom_frame: LocalEnu | None = None  # origin: base_link at alignment
        self._wheel_odo = WheelDeadReckoning(math.radians(90.0 - p.initial_heading_deg))  # ENU
        self.omega_ib_b = np.zeros(3)  # the last gyro sample, rad/s
        self.history = ForwardSpeedHistory(self._l_bw_b, aid_horizon_s=CHANGE_LOOKBACK_S)
        self._waiting_wheels = WheelQueue()
        self.updater.reset()
        self.supervisor.reset()
        self.wheel_aid = WheelAid(p)
        self.slip_model = self.wheel_aid.slip_model
        self.odometry_guard = OdometryGuard()
        self.wheel_update = WheelUpdate(
            self.filter, self.history, self.stationary, self.imu_rate, self.wheel_aid,
            self.odometry_guard, updater=self.updater, supervisor=self.supervisor,
            monitor=self.monitor, forward=self.forward, wheel_latency_ns=self._wheel_latency_ns)

    @property
    def params(self) -> Params:
        """The parameters in force (IMU noise densities from the IMU when not configured)."""
        return self.updater.params

    @property
    def aligned(self) -> bool:
        """True once the initial alignment is done and the filter runs."""
        return self.filter.state is not None

    @property
    def state(self) -> NavState | None:
        """The navigation state (None before alignment)."""
        return self.filter.state

    # ------------------------------------------------------------------ inputs
    def add_imu(self, sample: ImuSample) -> list[SlipEstimate]:
        """Process one IMU sample; return slip estimates that became due."""
        # 1. check the sample
        # (runs at the IMU rate: the stamp and the filter are held in locals)
        stamp_ns = sample.stamp_ns
        f_l, w_l = sample.f_ib_b.tolist(), sample.omega_ib_b.tolist()
        if not self.supervisor.accept_imu(stamp_ns, self.stamp_ns, f_l, w_l):
            return []
        prev_ns, self.stamp_ns = self.stamp_ns, stamp_ns
        self.omega_ib_b = sample.omega_ib_b
        # 2. the detectors see every sample
        self.stationary.add_imu(f_l, w_l)
        self.timing.add_imu(stamp_ns, w_l[2])
        if prev_ns is None:
            return self._slip_before_alignment()
        # 3. the time step: clipping, gaps (a long one is not integrated across), the IMU rate
        dt_s = (stamp_ns - prev_ns) * 1e-9
        flt = self.filter
        gap = self.supervisor.imu_step(stamp_ns, dt_s, f_l, w_l, flt.state is not None)
        if gap is not GapAction.NONE:
            self.slip_model.interrupt()  # no step test across a hole in the INS
            if gap is GapAction.RECOVER:
                self._recover(stamp_ns, dt_s, 'IMU gap')
                self.alignment.start_relevel()  # the tilt kept across it may be far off
                return self._evaluate_reached_wheels()
        elif self.imu_rate.add(dt_s):
            self.stationary.fit_window(self.params.stationary_window_s, self.imu_rate.dt_s)
        if sample.noise_var is not None:
            self.updater.use_imu_noise(sample.noise_var, self.filter, self.stationary,
                                       self.imu_rate)
        # 4. alignment
        if flt.state is None:
            start = self.alignment.add_imu(sample.f_ib_b, sample.omega_ib_b, stamp_ns,
                                           self.stationary.is_stationary(stamp_ns),
                                           self.imu_rate.dt_s, sample.tilt_rp_rad)
            if start is not None:
                self._align(start, stamp_ns)
            return self._slip_before_alignment()
        if self.alignment.releveling:  # after a recovery
            start = self.alignment.relevel(sample.f_ib_b, sample.omega_ib_b, stamp_ns)
            if start is not None:
                self._relevel(start, stamp_ns)
        # 5. strapdown, covariance every few samples; 6. when due: pseudo-measurements, health
        if flt.mechanize(f_l, w_l, dt_s):
            flt.predict_covariance(self.stationary.window, self.imu_rate.dt_s)
            if self.updater.due(stamp_ns):
                for correction in self.updater.pseudo_measurements(
                        flt, self.stationary, stamp_ns, self.imu_rate, self.track.width_m):
                    self.history.apply(correction, aid=False)
                self._check_filter_health(stamp_ns)
                flt = self.filter  # a new one after a full reset
                if flt.state is None:
                    return []
        # 7. the forward-speed history, and 8. the wheel samples the INS has now reached
        self.history.record(stamp_ns, flt.state, w_l, dt_s)
        return self._evaluate_reached_wheels()

    def add_wheel(self, sample: WheelSample) -> list[SlipEstimate]:
        """Process one wheel sample; return slip estimates that became due."""
        # 1. check the sample (the supervisor notes its arrival)
        if not self.supervisor.accept_wheel(sample, self.stamp_ns):
            return []
        # 2. the detectors see every sample (when it arrived: wheels may lag the IMU)
        self.stationary.add_wheel(self.supervisor.wheel_arrival_ns,
                                  max(abs(v) for v in wheel_speeds(sample)), sample.rim_speed_mps)
        self.timing.add_wheel(sample.stamp_ns, sample.rim_difference_mps)
        # 3. wait for the INS to reach its time
        if self._waiting_wheels.push(sample):
            self.counters['wheel_future'] += 1
        if not self.aligned or self.alignment.releveling:
            self.alignment.add_wheel(sample.stamp_ns, sample.rim_speed_mps)
        if not self.aligned:
            self._wheel_odo.add(sample, self.track.width_m)
            return self._slip_before_alignment()
        # 4. evaluate what the INS has reached
        return self._evaluate_reached_wheels()

    # ------------------------------------------------------------------ alignment, health
    def _align(self, start: AlignmentStart, stamp_ns: int) -> None:
        """Start the filter (in motion: slip unknown while the wheels re-anchor the speed)."""
        st, P = filter_start(start, self.params, self.planet, self.l_bw_b)
        self.filter.start(st, P, float(np.linalg.norm(start.f_b)))
        self.odom_frame = LocalEnu(self.planet, outputs.base_llh(st, self.l_bw_b, self.planet))
        self.updater.schedule(stamp_ns)
        self._aligned_ns = stamp_ns
        if start.speed_mps is not None:
            self.slip_model.reset(from_rest=False)
            self.supervisor.aligned_in_motion(stamp_ns)

    def _recover(self, stamp_ns: int, gap_s: float, reason: str) -> None:
        """After an IMU gap or a divergence: velocity from the last rim speed, P widened, slip
        unknown (after a gap, the attitude is re-levelled a window later: :meth:`_relevel`)."""
        self.supervisor.start_recovery(stamp_ns, reason)
        self.filter.restart_velocity(self._waiting_wheels.newest_rim_speed_mps(), lambda st:
                                     recovery_covariance(self.params, self.planet, st, gap_s))
        self.history.clear()
        self.slip_model.reset(from_rest=False)  # the velocity now comes from the rim
        self.updater.schedule(stamp_ns)

    def _relevel(self, start: AlignmentStart, stamp_ns: int) -> None:
        """Attitude re-levelled, velocity from the rim; slip unknown for ``recovery_s``."""
        flt = self.filter
        flt.P = relevel(flt.state, flt.P, start, self.params, self.planet)
        flt.clear_accumulators()
        self.history.clear()
        self.slip_model.reset(from_rest=False)
        self.supervisor.start_recovery(stamp_ns)

    def _check_filter_health(self, stamp_ns: int) -> None:
        """Carry out the supervisor's verdict on the filter (reset, repair, recover)."""
        verdict = self.supervisor.check_filter(stamp_ns, self.filter.state, self.filter.P)
        if verdict.reset:
            self._reset_filter()
            return
        if verdict.repaired_P is not None:
            self.filter.P = verdict.repaired_P
        if verdict.recover_reason is not None:
            if verdict.b_a is not None:
                self.filter.state.b_a, self.filter.state.b_g = verdict.b_a, verdict.b_g
            self._recover(stamp_ns, 0.0, verdict.recover_reason)

    # ------------------------------------------------------------------ wheel samples
    def _evaluate_reached_wheels(self) -> list[SlipEstimate]:
        """The slip of every waiting wheel sample the INS has reached; "unknown" per timeout."""
        # Most IMU samples reach no wheel sample: no generator, no list made for them.
        out = ([est for est in map(self.wheel_update.evaluate,
                                   self._waiting_wheels.reached(self.stamp_ns))
                if est is not None] if self._waiting_wheels.any_reached(self.stamp_ns) else [])
        stale_ns = self.supervisor.wheels_stale(self.stamp_ns, self._aligned_ns)
        if stale_ns is not None:
            out.append(self.wheel_update.unknown(stale_ns))
        return out

    def _slip_before_alignment(self) -> list[SlipEstimate]:
        out = [outputs.slip_before_alignment(wheel, self.params, self.stationary.imu_steady())
               for wheel in self._waiting_wheels.drain()]
        for est in out:
            self.counters['slip_unknown' if est.slip_class < 0 else 'slip_estimates'] += 1
        return out

    # ------------------------------------------------------------------ outputs
    def covariance(self) -> np.ndarray:
        """Error-state covariance at the last IMU sample (flushes the decimated prediction)."""
        if self.aligned:
            self.filter.predict_covariance(self.stationary.window, self.imu_rate.dt_s)
        return self.filter.P

    def odometry(self) -> OdometryEstimate | None:
        """Published base_link in odom: the fused solution, advanced as wheels + gyro where the
        IMU cannot resolve slip (:mod:`~slip_estimator.core.odometry_guard`; each call advances
        the published track to the last IMU stamp); before alignment None (no usable IMU:
        wheels only)."""
        if not self.aligned:
            refused = self.alignment.imu_problem is not None and self.stamp_ns is not None
            return self._wheel_odo.estimate(self.stamp_ns) if refused else None
        return self.odometry_guard.publish(self.fused_odometry())

    def fused_odometry(self) -> OdometryEstimate:
        """The filter's own solution of base_link in odom (aligned only)."""
        return outputs.odometry(self.stamp_ns, self.filter.state, self.filter.P,
                                self.omega_ib_b, self._l_bw_b, self.planet, self.odom_frame,
                                self.params.gyro_noise_density_rps_rthz ** 2 / self.imu_rate.dt_s)

    def health(self) -> Health:
        """Current self-diagnosis: state, counters, NIS statistics, bias estimates."""
        motion = (self.updater.is_stationary, self.updater.is_turning)
        return self.supervisor.health(self.stamp_ns, self.filter, motion, self.monitor,
                                      self.timing, self.track.width_m, self.alignment.imu_problem,
                                      self.slip_model, self.odometry_guard.figures())
