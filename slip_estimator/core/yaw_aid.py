"""Wheel yaw-rate aid: the gyro z bias observed from the wheel differential while driving.

Why. A robot that starts in motion and does not stop has nothing that observes its gyro z
bias: ZARU needs rest, and the non-holonomic constraints and the forward-speed aid leave the
heading (and so the z bias) unobservable. A consumer gyro's turn-on bias (0.5 deg/s) then
turns the heading by half a degree per second. The wheels measure the yaw rate too:
``rim_R - rim_L = B_eff * omega`` (:mod:`slip_estimator.core.track_width`), so
:class:`~slip_estimator.core.measurements.WheelYawRate` compares ``-(rim_R - rim_L) / B_eff``
(FRD) with the gyro z rate less its bias at each wheel sample while the robot moves, the
gyro averaged over the interval the sample's rim speeds describe
(:meth:`WheelYawAid.rate_window_ns`): a vibration line that the IMU rate folds onto a
multiple of the wheel rate (a 70-Hz chassis resonance sampled at 30 Hz is 10 Hz) holds one
phase at every wheel instant, so a single gyro sample reads it as a bias, and the aid taught
it to the filter (0.005 rad/s, 100 deg over the simulated vibrating 395-s drive); over the
interval it averages out.

How much it may be trusted, ``R`` (rad^2/s^2, per wheel sample), is the sum of

* the encoders: ``2 sigma_w^2 / B_eff^2`` (each side's rim speed ``wheel_speed_std_mps``);
* the gyro rate it is compared with: the variance of one sample in the IMU window (white
  noise and vibration), at least ``N_g^2 / dt``, over the samples the wheel interval averages;
* the effective track: ``z^2 * relative_var`` (a turn scrubs, and how much depends on the
  ground and the slip; :attr:`TrackWidthEstimator.relative_var`). It grows with the
  differential, so straight driving (differential ~0 whatever ``B_eff`` is) constrains the
  bias tightly and turns only loosely;
* **differential slip**: one side on softer ground or a side slope makes a robot whose wheels
  say straight yaw slowly (the softer side slips more, the downhill side slides), at
  ``wheel_yaw_rate_std_rps`` (sigma) 1-sigma.

The last two are properties of the ground and persist while it lasts,
``wheel_yaw_rate_correlation_s`` (tau): as a first-order Gauss-Markov error such a term of
variance ``v`` carries the information of a white noise of PSD ``2 v tau``, so each sample at
interval ``dt`` gets ``2 v tau / dt``: ``R = 2 sigma_w^2 / B_eff^2 + var_gyro + (z^2
relative_var + sigma^2) 2 tau / dt``. The bias is never believed better than the ground's
errors average out, whatever the wheel rate.

A ground that yaws the robot more than ``sigma`` (one track in sand for tens of seconds) shows
as a persistent innovation: its running mean over ``_RESIDUAL_MEMORY_S``
(:attr:`WheelYawAid.unexplained_rps`) replaces ``sigma`` when larger (covariance matching), so
the aid lets go of the bias while the wheels and the gyro disagree and takes hold again when
they agree; a single wild sample meets the filter's soft chi-square gate (R inflated onto the
gate). Both show in the residual monitor's ``wheel_yaw`` channel. Measured in
``test/integration/test_yaw_aid.py``. With ``wheel_aid: off`` (the paper's method) the aid is
not applied (the track width is still fitted). Only numpy and the standard library are used.
"""
from __future__ import annotations

from slip_estimator.core.measurements import Constraint, WheelYawRate
from slip_estimator.core.params import Params
from slip_estimator.core.planet import Planet
from slip_estimator.core.state import NavState
from slip_estimator.core.track_width import TrackWidthEstimator
from slip_estimator.core.types import WheelSample

_NS = 1_000_000_000
_RESIDUAL_MEMORY_S = 3.0
"""The yaw rate the ground adds now is measured as the innovation's running mean over this
long (the white gyro and encoder noise of 30 samples at 10 Hz averages to ~0.005 rad/s)."""
_MAX_INTERVAL_S = 1.0
"""A longer wheel interval (a dropout) counts as this long: the differential-slip share of R
never falls below what one second of it leaves."""


class WheelYawAid:
    """The wheel yaw-rate pseudo-measurement and the effective track width it needs (see the
    module docstring). :attr:`track` is the robot's :class:`TrackWidthEstimator`."""

    def __init__(self, p: Params, planet: Planet) -> None:
        self.model = WheelYawRate(planet)
        self.track = TrackWidthEstimator(p.track_width)
        self._encoder_var_mps2 = 2.0 * p.wheel_speed_std_mps ** 2
        self._slip_var_rps2 = p.wheel_yaw_rate_std_rps ** 2
        self._correlation_s = p.wheel_yaw_rate_correlation_s
        self._last_ns: int | None = None
        self.enabled = p.wheel_aid != 'off'
        self.unexplained_rps = 0.0  # running mean of the innovation (see variance_rps2)

    def variance_rps2(self, z_rps: float, width_m: float, gyro_var_rps2: float,
                      interval_s: float) -> float:
        """``R`` of one wheel sample (see the module docstring), rad^2/s^2."""
        ground_s = self._correlation_s / interval_s  # samples per correlation time
        slip_var = max(self._slip_var_rps2, self.unexplained_rps ** 2)
        return (self._encoder_var_mps2 / width_m ** 2 + gyro_var_rps2
                + (z_rps ** 2 * self.track.relative_var + slip_var) * 2.0 * ground_s)

    def rate_window_ns(self, wheel: WheelSample, latency_ns: int) -> tuple[int, int]:
        """The IMU interval (start, end ns) whose mean gyro rate a wheel sample's
        differential is compared with: its wheel interval (since the previous sample, at most
        ``_MAX_INTERVAL_S``; empty for the first), centred on its mean age ``latency_ns``
        before its stamp. The rim speeds are count differences over that interval, so a
        single gyro sample in it would mismatch them by whatever vibration the interval
        averages out (:meth:`.ForwardSpeedHistory.mean_yaw_rate_b_rps`)."""
        last_ns = self._last_ns
        span_ns = 0 if last_ns is None or wheel.stamp_ns <= last_ns else \
            min(wheel.stamp_ns - last_ns, int(_MAX_INTERVAL_S * _NS))
        start_ns = wheel.stamp_ns - latency_ns - span_ns // 2
        return start_ns, start_ns + span_ns

    def applies(self, wheel: WheelSample, moving: bool) -> bool:
        """Whether a wheel sample can give the constraint at all: the aid is on, the sides
        are known, and the robot is ``moving`` (at rest ZARU does it)."""
        return self.enabled and moving and wheel.rim_difference_mps is not None

    def constraint(self, wheel: WheelSample, yaw_rate_b_rps: float, state: NavState,
                   gyro_var_rps2: float, moving: bool,
                   imu_dt_s: float | None = None) -> Constraint | None:
        """Feed the track-width fit with one wheel sample and the gyro z rate less its bias
        over its interval (``yaw_rate_b_rps``, FRD); the yaw-rate constraint to apply (None:
        the aid is off, the sides are unknown, the robot is not ``moving`` (ZARU's case), or no
        interval yet).
        ``gyro_var_rps2``: the variance of one gyro sample now; with the IMU interval
        ``imu_dt_s`` that of ``yaw_rate_b_rps``, a mean over the wheel interval, is taken as
        the white-noise share of it (never more than one sample's)."""
        diff_mps = wheel.rim_difference_mps
        self.track.add(-yaw_rate_b_rps, diff_mps)
        last_ns, self._last_ns = self._last_ns, wheel.stamp_ns
        if not self.applies(wheel, moving) or last_ns is None or wheel.stamp_ns <= last_ns:
            return None
        interval_s = min((wheel.stamp_ns - last_ns) / _NS, _MAX_INTERVAL_S)
        width_m = self.track.width_m
        z_rps = -diff_mps / width_m
        # The gyro rate with its bias: the model's h(x) takes the bias from the state.
        innovation = self.model.innovation(state, yaw_rate_b_rps + float(state.b_g[2]), z_rps)
        w = min(1.0, interval_s / _RESIDUAL_MEMORY_S)
        self.unexplained_rps += w * (float(innovation[0]) - self.unexplained_rps)
        if imu_dt_s is not None:  # the gyro rate is a mean over the wheel interval
            gyro_var_rps2 *= min(1.0, imu_dt_s / interval_s)
        R = self.model.covariance(self.variance_rps2(z_rps, width_m, gyro_var_rps2, interval_s))
        return Constraint(self.model.name, innovation, self.model.jacobian(state), R)
