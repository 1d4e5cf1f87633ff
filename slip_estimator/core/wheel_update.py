"""One wheel sample the INS has reached, against the forward-speed history: its slip out, its
aid in.

In order (:meth:`WheelUpdate.evaluate`): an aid take-back the INS has since refuted is restored,
the body motion ``wheel_latency_s`` before the stamp is read from the history, the wheel
yaw-rate aid corrects the gyro z bias, the slip estimate is computed (unknown while the
estimator recovers: the rim re-anchors the speed), and the wheel aid's decision
(:class:`~slip_estimator.core.slip_model.aid_decision.AidDecision`) is carried out on the filter
as a gated forward-speed update or an anchor; where the odometry guard's verdict ends a
fallback of a measuring span, the fused position's cross-track correlations are forgotten
(:meth:`~slip_estimator.core.odometry_guard.OdometryGuard.wheel`). Every correction is
recorded in the history. The estimator (:mod:`slip_estimator.core.estimator`) makes one per
filter run and hands it the wheel samples the INS has reached; it does not call back.
"""
from __future__ import annotations

from slip_estimator.core import outputs
from slip_estimator.core.detectors import ImuRate, StationaryDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.history import ForwardSpeedHistory, HistoryPoint
from slip_estimator.core.measurements import ForwardSpeed
from slip_estimator.core.odometry_guard import OdometryGuard
from slip_estimator.core.params import Params
from slip_estimator.core.planet import llh_to_local_enu
from slip_estimator.core.slip_model.aid_decision import AidDecision
from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.slip_model.wheel_aid import WheelAid
from slip_estimator.core.supervisor import Supervisor
from slip_estimator.core.take_back import runaway_scale
from slip_estimator.core.types import SlipEstimate, WheelSample
from slip_estimator.core.updater import Updater


class WheelUpdate:
    """The wheel-sample update of one filter run (a full reset makes a new one): the run's
    filter, history, detectors, wheel aid and odometry guard, and the estimator's lasting
    parts (updater, supervisor, residual monitor, forward-speed model)."""

    def __init__(self, flt: ErrorStateFilter, history: ForwardSpeedHistory,
                 stationary: StationaryDetector, imu_rate: ImuRate, wheel_aid: WheelAid,
                 odometry_guard: OdometryGuard, *, updater: Updater, supervisor: Supervisor,
                 monitor: ResidualMonitor, forward: ForwardSpeed, wheel_latency_ns: int) -> None:
        self.filter = flt
        self.history = history
        self.stationary = stationary
        self.imu_rate = imu_rate
        self.wheel_aid = wheel_aid
        self.odometry_guard = odometry_guard
        self.updater = updater
        self.supervisor = supervisor
        self.counters = supervisor.counters
        self.monitor = monitor
        self.forward = forward
        self.track = updater.yaw_aid.track
        self._wheel_latency_ns = wheel_latency_ns

    @property
    def params(self) -> Params:
        """The parameters in force (the updater's: IMU noise from the IMU when not configured)."""
        return self.updater.params

    def evaluate(self, wheel: WheelSample) -> SlipEstimate | None:
        """1. the body motion ``wheel_latency_s`` before its stamp, 2. the track width and yaw-rate
        aid, 3. the slip (unknown while recovering: the rim re-anchors), 4. the wheel aid."""
        restore = self.history.take_back_refuted(wheel.rim_speed_mps,
                                                 self.filter.state.C_b_n[:, 0])
        if restore is not None:  # the INS ran away from a take-back: the aid had it right
            self.history.apply(self.filter.correct(restore), aid=False)
        at = self.history.at(wheel.stamp_ns - self._wheel_latency_ns)
        if at is None:
            self.counters['wheel_late'] += 1
            return None
        # The yaw-rate aid compares the differential with the gyro over the wheel interval.
        yaw_rate_rps = self.history.mean_yaw_rate_b_rps(
            *self.updater.yaw_aid.rate_window_ns(wheel, self._wheel_latency_ns))
        for correction in self.updater.wheel_yaw_rate(
                self.filter, wheel, at.yaw_rate_b_rps if yaw_rate_rps is None else yaw_rate_rps,
                self.stationary, self.imu_rate):
            self.history.apply(correction, aid=False)
        turning = self.updater.is_turning
        if self.supervisor.recovering(wheel.stamp_ns):
            self._apply_aid(self.wheel_aid.reanchor(wheel.rim_speed_mps, turning), at)
            return self.unknown(wheel.stamp_ns, wheel.rim_speed_mps)
        self.counters['slip_estimates'] += 1
        st = self.filter.state
        var_ins = self.filter.variance(self.forward.jacobian(st))
        var_v = var_ins + self.wheel_aid.held_speed_var_mps2(wheel.rim_speed_mps)
        rim_var = self.wheel_aid.rim_timing_var_mps2(wheel)
        still = self.wheel_aid.stopping(wheel) or self.updater.is_stationary
        est = outputs.slip_estimate(wheel, at.v_fwd_mps, at.yaw_rate_b_rps, var_v,
                                    self.params, still, self.track.width_m, rim_var,
                                    self.wheel_aid.held_slip,
                                    self.wheel_aid.confidence(wheel.rim_speed_mps, turning))
        self._apply_aid(self.wheel_aid.decide(
            wheel, at, est, st.C_b_n, turning, self.filter.tilt_std_rad(),
            self.filter.forward_reading_var_mps2(SCALES_S), var_ins), at)
        if self.odometry_guard.wheel(self.wheel_aid.odometry_decision(est)):
            self.filter.decorrelate_cross_track()  # a fallback of a measuring span ended
        return est

    def _apply_aid(self, d: AidDecision | None, at: HistoryPoint) -> None:
        """Carry out a wheel-aid decision (``at``: the history at the wheel sample's time)."""
        if d is None:
            return
        if d.held_slip is not None:
            self.monitor.add_held_slip(d.held_slip)
        taken_back = None
        if d.take_back_since_ns is not None:
            # A change began there: what the aid taught since was the old slip's.
            undo = -self.history.aid_taught_since(d.take_back_since_ns)
            taken_back = self.filter.correct(undo)
            self.history.apply(taken_back, aid=True)
        if not d.update:
            return
        if not d.anchor:
            self._aid_update(d.z_mps, at.v_fwd_mps, d.var_mps2, excluded=not d.repair)
            return
        # A known jump of the INS error (a change, or a settled measurement): not gated.
        llh_before = self.filter.state.llh.copy()
        correction = self.filter.anchor(self.forward.innovation(d.z_mps, at.v_fwd_mps),
                                        self.forward.jacobian(self.filter.state),
                                        self.forward.covariance(d.var_mps2))
        self.history.apply(correction, aid=not d.repair)
        if d.held_slip is None and not d.repair:  # a change's onset, not a settled slip
            self.odometry_guard.change_anchored(
                llh_to_local_enu(self.filter.planet, self.filter.state.llh, llh_before))
        if taken_back is not None:  # checked against the INS TAKE_BACK_CHECK_S on
            m = self.wheel_aid.slip_model
            self.history.taken_back(runaway_scale(m.spread_var[0], self.filter.tilt_std_rad(),
                                                  self.filter.g_mps2, m.aid_noise_var),
                                    taken_back, correction)

    def _aid_update(self, z_mps: float, v_hist_mps: float, var_mps2: float,
                    excluded: bool = True) -> None:
        """Gated forward-speed update towards the aid value ``z_mps`` (``v_hist_mps``: the INS
        value at the wheel sample's instant). The validation study replaces it."""
        correction = self.updater.update(
            self.filter, 'wheel', self.forward.innovation(z_mps, v_hist_mps),
            self.forward.jacobian(self.filter.state), self.forward.covariance(var_mps2))
        if correction is not None:
            self.history.apply(correction, aid=excluded, taught=excluded)

    def unknown(self, stamp_ns: int, wheel_speed_mps: float = 0.0) -> SlipEstimate:
        """An unknown slip (recovering, or no wheel sample in time), counted."""
        self.counters['slip_unknown'] += 1
        return outputs.unknown_slip(stamp_ns, wheel_speed_mps)
