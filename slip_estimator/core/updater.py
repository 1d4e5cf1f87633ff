"""The measurement updates: when the pseudo-measurements are due, which ones apply, and the
bookkeeping of every update (counters, residual monitor).

At ``update_rate_hz`` (at a covariance-propagation epoch) the detectors decide (stationary:
IMU window still and wheels stopped; turning: yaw rate above its threshold), then ZUPT + ZARU
(at rest) or the non-holonomic constraint (moving; vertical only while turning) are applied one
after the other through the filter's gated update. Each applied update returns the filter's
:class:`~slip_estimator.core.history.Correction` to the caller, who keeps the history. With the
wheel aid on, a stop after driving first reopens the horizontal acceleration error (tilt and
accelerometer bias, :meth:`~slip_estimator.core.filter.ErrorStateFilter.reopen_levels`), so
that its zero velocity levels the INS again before the next start measures the ground.

At each wheel sample while moving, the wheel yaw-rate aid (:mod:`slip_estimator.core.yaw_aid`)
is applied through the same gated update (:meth:`Updater.wheel_yaw_rate`).

The IMU's noise model: the noise densities of :attr:`Updater.params` (process noise, ZARU)
come from the IMU itself when the parameters leave them at their defaults
(:meth:`Updater.use_imu_noise`): from the covariances its messages declare, else from the
spread it shows at rest (only ever raising the defaults), once per filter.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.detectors import ImuRate, StationaryDetector, TurnDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.history import Correction
from slip_estimator.core.measurements import (NonHolonomic, PseudoMeasurements,
                                              ZeroAngularRate, ZeroVelocity)
from slip_estimator.core.params import Params, with_message_noise
from slip_estimator.core.planet import Planet
from slip_estimator.core.types import WheelSample
from slip_estimator.core.yaw_aid import WheelYawAid

_NS = 1_000_000_000


class Updater:
    """Schedules and applies the measurement updates (see the module docstring).

    ``counters`` (update and gate counts) and ``monitor`` (normalised residuals) are the
    estimator's records, written here for every update. :attr:`params` are the parameters
    in force (the IMU noise densities adopted from the IMU, :meth:`use_imu_noise`).
    """

    def __init__(self, p: Params, planet: Planet, l_bw_b: np.ndarray, counters: dict[str, int],
                 monitor: ResidualMonitor) -> None:
        self.params = p
        self.constraints = PseudoMeasurements(
            ZeroVelocity(p.zupt_velocity_std_mps),
            ZeroAngularRate(planet, p.zaru_rate_std_rps, p.gyro_noise_density_rps_rthz),
            NonHolonomic(planet, l_bw_b, p.nhc_lateral_std_mps, p.nhc_vertical_std_mps))
        self.turn = TurnDetector(p.turn_rate_threshold_rps)
        self.yaw_aid = WheelYawAid(p, planet)  # survives filter resets, as the track fit
        self._period_ns = int(_NS / p.update_rate_hz)
        # What a stop re-levels is what the wheel aid taught under held slips; without the aid
        # (the paper's method, whose covariance ignores the vibration) the stops are left as
        # the paper has them: its accelerometer biases then run out of bounds (s5t1).
        self._relevel = p.wheel_aid == 'hold'
        self._counters, self._monitor = counters, monitor
        self.reset()

    def reset(self) -> None:
        self.next_update_ns: int | None = None
        self.is_stationary = self.is_turning = False
        self._moved = False  # driven since the filter started (its first rest is the alignment's)
        self._drive_scatter = (0, 0.0)  # gyro window variances summed while driving, and n
        self._noise_adopted = False  # the IMU's noise model taken (once the rate was known)

    def schedule(self, stamp_ns: int) -> None:
        """The next pseudo-measurements at the first propagation epoch from ``stamp_ns``."""
        self.next_update_ns = stamp_ns

    def due(self, stamp_ns: int) -> bool:
        return stamp_ns >= self.next_update_ns

    def pseudo_measurements(self, flt: ErrorStateFilter, stationary: StationaryDetector,
                            stamp_ns: int, imu_rate: ImuRate,
                            track_width_m: float) -> list[Correction]:
        """The detectors decide (a turn scrubs when the yaw rate x the effective
        ``track_width_m`` is large against the latest rim speed, while wheels are recent), then
        ZUPT + ZARU (at rest) or the NHC, one after the other; the corrections made, in order.
        Then the IMU spread measured at rest, once there is one, becomes the noise model for
        the following steps (:meth:`use_imu_noise`, raising the defaults only)."""
        flt.last_records = []
        self.next_update_ns = stamp_ns + self._period_ns
        w_mean, n = flt.take_mean_rate()
        was_stationary = self.is_stationary
        self.is_stationary = stationary.is_stationary(stamp_ns)
        if self.is_stationary and not was_stationary and self._moved and self._relevel:
            # A stop after driving levels the INS again; the accelerometer's turn-on bias
            # uncertainty is the scale of what a drive leaves unknown.
            flt.reopen_levels(self.params.initial_accel_bias_std)
        if self._relevel:
            self._drive_vibration(flt, stationary, imu_rate, was_stationary)
        self._moved = self._moved or not self.is_stationary
        self.is_turning = self.turn.is_turning(w_mean - flt.state.b_g, flt.state.C_b_n,
                                               stationary.recent_rim_speed_mps(stamp_ns),
                                               track_width_m)
        out = []
        window = stationary.window
        gyro_var = window.variance()[3:] if self.is_stationary and window.n >= 2 else None
        for c in self.constraints.select(flt.state, w_mean, max(1, n) * imu_rate.dt_s,
                                         self.is_stationary, self.is_turning, gyro_var,
                                         imu_rate.dt_s):
            correction = self.update(flt, c.name, c.innovation, c.H, c.R, c.channels)
            if correction is not None:
                out.append(correction)
        rest = stationary.rest_std
        if rest is not None:  # measured at rest: the IMU's noise
            self.use_imu_noise((rest[0] ** 2, rest[1] ** 2), flt, stationary, imu_rate,
                               raise_only=True)
        return out

    def _drive_vibration(self, flt: ErrorStateFilter, stationary: StationaryDetector,
                         imu_rate: ImuRate, was_stationary: bool) -> None:
        """While driving, the mean gyro scatter (largest axis) in the IMU window; at the
        start of a stop, the variance by which the rest's gyro bias may differ from the
        drive's (the filter's :attr:`~ErrorStateFilter.rest_bias_jump_var_rps2`): the
        drive's scatter beyond the rest's (vibration), a fraction ``vibration_noise_fraction``
        of it as white noise (as the process noise takes it) averaged over the wheel yaw-rate
        aid's correlation time, the span over which the aid taught the drive's bias."""
        window = stationary.window
        if window.n < 2:
            return
        var = float(max(window.variance()[3:]))
        if not self.is_stationary:
            n, total = self._drive_scatter
            self._drive_scatter = (n + 1, total + var)
        elif not was_stationary and self._drive_scatter[0]:
            n, total = self._drive_scatter
            k = self.params.vibration_noise_fraction
            flt.rest_bias_jump_var_rps2 = k * k * max(0.0, total / n - var) * imu_rate.dt_s \
                / self.params.wheel_yaw_rate_correlation_s
            self._drive_scatter = (0, 0.0)

    def wheel_yaw_rate(self, flt: ErrorStateFilter, wheel: WheelSample, yaw_rate_b_rps: float,
                       stationary: StationaryDetector, imu_rate: ImuRate) -> list[Correction]:
        """The wheel yaw-rate aid at one wheel sample (``yaw_rate_b_rps``: the gyro z rate
        less its bias over its interval, FRD), while moving (at rest ZARU does it); one gyro
        sample's variance is the IMU window's (noise and vibration), at least the white noise's.
        The correction made (none when not applied)."""
        moving = not self.is_stationary
        gyro_var_rps2 = self.params.gyro_noise_density_rps_rthz ** 2 / imu_rate.dt_s
        if stationary.window.n >= 2 and self.yaw_aid.applies(wheel, moving):
            gyro_var_rps2 = max(gyro_var_rps2, float(stationary.window.variance()[5]))
        c = self.yaw_aid.constraint(wheel, yaw_rate_b_rps, flt.state, gyro_var_rps2, moving,
                                    imu_rate.dt_s)
        if c is not None:
            self._monitor.add_yaw_disagreement(self.yaw_aid.unexplained_rps,
                                               self.params.wheel_yaw_rate_std_rps)
        correction = None if c is None else self.update(flt, c.name, c.innovation, c.H, c.R)
        return [] if correction is None else [correction]

    def use_imu_noise(self, noise_var: tuple[float, float] | None, flt: ErrorStateFilter,
                      stationary: StationaryDetector, imu_rate: ImuRate,
                      raise_only: bool = False) -> None:
        """The IMU declares its noise variances per sample (accel, gyro; None: it does not), or
        its spread at rest was measured: the stationarity limits never sit below it and, once
        the IMU rate is known, the filter's noise densities (process noise, ZARU) come from it
        when the parameters leave them at their defaults (:func:`params.with_message_noise`;
        ``raise_only``: never below the defaults). Done once per filter."""
        if noise_var is None or self._noise_adopted:
            return
        stationary.sensor_std = [math.sqrt(v) for v in noise_var]
        if not imu_rate.known:
            return
        self._noise_adopted = True
        params = with_message_noise(self.params, *noise_var, imu_rate.dt_s, raise_only)
        if params is not None:
            self.params = params
            flt.use_noise(params)
            self.constraints.zaru.gyro_noise_density_rps_rthz = \
                params.gyro_noise_density_rps_rthz

    def update(self, flt: ErrorStateFilter, name: str, innovation: np.ndarray, H: np.ndarray,
               R: np.ndarray, channels: tuple[str, ...] | None = None) -> Correction | None:
        """One gated update of ``flt``, counted and fed to the residual monitor; the
        correction it made (None: not applied)."""
        outcome = flt.update(name, innovation, H, R)
        rec = outcome.record
        self._counters['gated'] += outcome.gated
        if math.isfinite(rec.nis):
            self._monitor.add_update(name, innovation, rec.S, channels)
        if outcome.correction is not None:
            self._counters[name] += 1
        return outcome.correction
