"""The measurement updates: when the pseudo-measurements are due, which ones apply, and the
bookkeeping of every update (counters, residual monitor).

At ``update_rate_hz`` (at a covariance-propagation epoch) the detectors decide (stationary:
IMU window still and wheels stopped; turning: yaw rate above its threshold), then ZUPT + ZARU
(at rest) or the non-holonomic constraint (moving; vertical only while turning) are applied one
after the other through the filter's gated update. Each applied update returns the filter's
:class:`~slip_estimator.core.history.Correction` to the caller, who keeps the history.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.detectors import StationaryDetector, TurnDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.history import Correction
from slip_estimator.core.measurements import (NonHolonomic, PseudoMeasurements,
                                              ZeroAngularRate, ZeroVelocity)
from slip_estimator.core.params import Params
from slip_estimator.core.planet import Planet

_NS = 1_000_000_000


class Updater:
    """Schedules and applies the measurement updates (see the module docstring).

    ``counters`` (update and gate counts) and ``monitor`` (normalised residuals) are the
    estimator's records, written here for every update.
    """

    def __init__(self, p: Params, planet: Planet, l_bw_b: np.ndarray, counters: dict[str, int],
                 monitor: ResidualMonitor) -> None:
        self.constraints = PseudoMeasurements(
            ZeroVelocity(p.zupt_velocity_std),
            ZeroAngularRate(planet, p.zaru_rate_std, p.gyro_noise_density),
            NonHolonomic(planet, l_bw_b, p.nhc_lateral_std, p.nhc_vertical_std))
        self.turn = TurnDetector(p.turn_rate_threshold)
        self._period_ns = int(_NS / p.update_rate_hz)
        self._counters, self._monitor = counters, monitor
        self.reset()

    def reset(self) -> None:
        self.next_update_ns: int | None = None
        self.is_stationary = self.is_turning = False

    def schedule(self, stamp_ns: int) -> None:
        """The next pseudo-measurements at the first propagation epoch from ``stamp_ns``."""
        self.next_update_ns = stamp_ns

    def due(self, stamp_ns: int) -> bool:
        return stamp_ns >= self.next_update_ns

    def pseudo_measurements(self, flt: ErrorStateFilter, stationary: StationaryDetector,
                            stamp_ns: int, imu_dt_s: float) -> list[Correction]:
        """The detectors decide, then ZUPT + ZARU (at rest) or the NHC, one after the other;
        the corrections made, in order."""
        flt.last_records = []
        self.next_update_ns = stamp_ns + self._period_ns
        w_mean, n = flt.take_mean_rate()
        self.is_stationary = stationary.is_stationary(stamp_ns)
        self.is_turning = self.turn.is_turning(w_mean - flt.state.b_g, flt.state.C_b_n)
        out = []
        for c in self.constraints.select(flt.state, w_mean, max(1, n) * imu_dt_s,
                                         self.is_stationary, self.is_turning):
            correction = self.update(flt, c.name, c.innovation, c.H, c.R, c.channels)
            if correction is not None:
                out.append(correction)
        return out

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
