"""Detectors that decide which pseudo-measurements the rover's physics allow right now.

Kept apart from the measurement models (a detector answers "is the rover stationary?", a model
says what that implies); thresholds are parameters.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from slip_estimator.core.params import Params


_add_reduce = np.add.reduce


class ImuWindow:
    """The most recent IMU samples (body frame), oldest first, for window statistics.

    ``add`` runs at the IMU rate and only queues the sample; the queue is moved into the
    buffer (older rows shifted out) in two array operations when statistics are asked for
    (at most every few samples), and the window variance is kept until the next sample.
    """

    def __init__(self, n_samples: int) -> None:
        self._buf = np.zeros((max(2, n_samples), 6))  # the newest self._n rows are the window
        self._dev = np.empty_like(self._buf)  # deviations from the mean (variance)
        self._queue_max = 6 * len(self._buf)  # floats queued when a whole window waits
        self._n = 0
        self._queue: list[float] = []  # queued samples, six floats each
        self._var: np.ndarray | None = None

    def add(self, f_ib_b: Sequence[float], omega_ib_b: Sequence[float]) -> None:
        """Append one sample, dropping the oldest when full (lists of floats are the cheapest
        input; arrays work too)."""
        queue = self._queue
        queue.extend(f_ib_b)
        queue.extend(omega_ib_b)
        self._var = None
        if len(queue) >= self._queue_max:
            self._flush()

    def _flush(self) -> None:
        queue = self._queue
        if not queue:
            return
        buf, size, k = self._buf, len(self._buf), len(queue) // 6
        if k >= size:
            buf[:] = np.array(queue[-6 * size:], dtype=float).reshape(size, 6)
        else:
            buf[:-k] = buf[k:]
            buf[-k:] = np.array(queue, dtype=float).reshape(k, 6)
        self._n = min(self._n + k, size)
        queue.clear()

    def clear(self) -> None:
        """Forget all samples."""
        self._n = 0
        self._queue.clear()
        self._var = None

    @property
    def n(self) -> int:
        """Number of samples held."""
        return min(self._n + len(self._queue) // 6, len(self._buf))

    @property
    def size(self) -> int:
        """Nominal number of samples (the window is full at this many)."""
        return len(self._buf)

    @property
    def full(self) -> bool:
        """True once the window holds its nominal number of samples."""
        return self.n == len(self._buf)

    def samples(self, last: int | None = None) -> np.ndarray:
        """The newest ``last`` samples (all by default) as rows (f_x, f_y, f_z, w_x, w_y, w_z),
        oldest first (a copy)."""
        self._flush()
        n = self._n if last is None else min(last, self._n)
        return self._buf[len(self._buf) - n:].copy()

    def variance(self) -> np.ndarray:
        """Per-column (population) variance of the samples held, as ``samples().var(axis=0)``
        computes it (the same operations, rows in the same order), cached until the next
        sample."""
        if self._var is None:
            self._flush()
            n = self._n
            a = self._buf[len(self._buf) - n:]
            # np.add.reduce is what ndarray.sum calls (without its Python wrapper); the
            # deviations go to a buffer kept for it: the same operations, fewer allocations.
            mean = _add_reduce(a, 0, None, None, True)
            mean /= n
            x = np.subtract(a, mean, out=self._dev[:n])
            x *= x
            var = _add_reduce(x, 0)
            var /= n
            self._var = var
        return self._var


_REST_MARGIN = 1.5
"""A window counts as steady up to this many times the IMU's spread at rest."""
_REST_SETTLE_NS = 1_000_000_000
"""The wheels stopped this long ago: the body has stopped rocking after braking."""
_REST_ACCEL_LIMIT_MPS2 = 0.5
_REST_GYRO_LIMIT_RPS = 0.1
"""Beyond these a window with the wheels stopped is motion (pushed, sliding), not noise."""


class StationaryDetector:
    """Stationary when, over a window, the specific force and the gyro rates are steady
    and every wheel is (nearly) stopped.

    The wheel test makes the detector robust to smooth constant-velocity driving, which an
    IMU-only test cannot tell from rest; the IMU test keeps a rover whose wheels are blocked
    but which slides (or is carried) from being declared at rest. Without recent wheel data
    the IMU test alone decides.
    """

    def __init__(self, window_samples: int, accel_std_max_mps2: float, gyro_std_max_rps: float,
                 wheel_speed_max_mps: float, wheel_timeout_ns: int) -> None:
        self.window = ImuWindow(window_samples)
        self.accel_std_max_mps2 = accel_std_max_mps2
        self.gyro_std_max_rps = gyro_std_max_rps
        self.wheel_speed_max_mps = wheel_speed_max_mps
        self.wheel_timeout_ns = wheel_timeout_ns
        self._wheel_stamp_ns: int | None = None
        self._rim_speed_mps = 0.0  # the latest wheel sample's mean rim speed
        self._wheels_stopped = False
        self._stopped_since_ns: int | None = None
        # The IMU's own spread at rest (accel m/s^2, gyro rad/s), learned while the wheels
        # have been stopped for a window: the thresholds never sit below its noise.
        self.rest_std: list[float] | None = None
        # The IMU's noise std (accel m/s^2, gyro rad/s) its messages declare, if they do.
        self.sensor_std: list[float] | None = None

    @classmethod
    def for_params(cls, params: Params) -> StationaryDetector:
        """The detector of the parameters (window sized for 250 Hz until the rate is known)."""
        p = params.detectors
        return cls(max(2, int(round(p.stationary_window_s * 250.0))), p.stationary_accel_std_mps2,
                   p.stationary_gyro_std_rps, p.stationary_wheel_speed_mps,
                   int(p.wheel_timeout_s * 1_000_000_000))

    @property
    def window_samples(self) -> int:
        """Nominal number of samples in the IMU window."""
        return self.window.size

    def resize(self, window_samples: int) -> None:
        """A new (empty) IMU window of ``window_samples`` (the IMU rate became known)."""
        self.window = ImuWindow(window_samples)

    def fit_window(self, window_s: float, dt_s: float) -> None:
        """Resize the IMU window (when it changes) to hold ``window_s`` at the IMU interval
        ``dt_s`` (the IMU rate became known)."""
        n = max(2, int(round(window_s / dt_s)))
        if n != self.window_samples:
            self.resize(n)

    def add_imu(self, f_ib_b: Sequence[float], omega_ib_b: Sequence[float]) -> None:
        """Feed one IMU sample."""
        self.window.add(f_ib_b, omega_ib_b)

    def add_wheel(self, stamp_ns: int, max_abs_rim_speed_mps: float,
                  rim_speed_mps: float = 0.0) -> None:
        """Feed the largest absolute rim speed of one wheel sample (and its mean rim speed,
        for :meth:`recent_rim_speed_mps`)."""
        self._wheel_stamp_ns = stamp_ns
        self._rim_speed_mps = rim_speed_mps
        self._wheels_stopped = max_abs_rim_speed_mps <= self.wheel_speed_max_mps
        if not self._wheels_stopped:
            self._stopped_since_ns = None
        elif self._stopped_since_ns is None:
            self._stopped_since_ns = stamp_ns

    def wheels_recent(self, now_ns: int) -> bool:
        """True when a wheel sample arrived within the wheel timeout."""
        return (self._wheel_stamp_ns is not None
                and now_ns - self._wheel_stamp_ns <= self.wheel_timeout_ns)

    def recent_rim_speed_mps(self, now_ns: int) -> float | None:
        """The latest mean rim speed while wheels are recent (:meth:`wheels_recent`), m/s;
        else None."""
        return self._rim_speed_mps if self.wheels_recent(now_ns) else None

    def imu_steady(self) -> bool:
        """IMU part of the test (window must be full)."""
        if not self.window.full:
            return False
        # Per-axis spread: the specific-force norm barely changes when the rover starts to
        # accelerate horizontally (sqrt(g^2 + a^2) ~ g), the axes do.
        v = self.window.variance().tolist()
        accel_max, gyro_max = self.thresholds()
        return (all(math.sqrt(x) <= accel_max for x in v[:3])
                and all(math.sqrt(x) <= gyro_max for x in v[3:]))

    def thresholds(self) -> tuple[float, float]:
        """Accelerometer and gyro std limits: the configured ones, or _REST_MARGIN times the
        spread this IMU shows at rest (or, before a rest was seen, the noise its messages
        declare) if that is larger (a consumer MEMS IMU is noisier at rest than the configured
        limits)."""
        noise = self.rest_std if self.rest_std is not None else self.sensor_std
        if noise is None:
            return self.accel_std_max_mps2, self.gyro_std_max_rps
        return (max(self.accel_std_max_mps2, _REST_MARGIN * noise[0]),
                max(self.gyro_std_max_rps, _REST_MARGIN * noise[1]))

    def _learn_rest(self, now_ns: int) -> None:
        """The wheels have been still for a window: the IMU window is its rest noise, unless
        it is far beyond any IMU's (the rover is being moved)."""
        if (self._stopped_since_ns is None or not self.window.full
                or now_ns - self._stopped_since_ns < _REST_SETTLE_NS):
            return
        v = self.window.variance().tolist()
        std = [math.sqrt(max(v[:3])), math.sqrt(max(v[3:]))]
        if std[0] > _REST_ACCEL_LIMIT_MPS2 or std[1] > _REST_GYRO_LIMIT_RPS:
            return
        if self.rest_std is None:
            self.rest_std = std
        else:
            self.rest_std = [r + 0.05 * (x - r) for r, x in zip(self.rest_std, std)]

    def is_stationary(self, now_ns: int) -> bool:
        """The decision at ``now_ns``."""
        if self.wheels_recent(now_ns) and not self._wheels_stopped:
            return False
        if self.wheels_recent(now_ns):
            self._learn_rest(now_ns)
        return self.imu_steady()


_SCRUB_FRACTION = 0.5
"""A turn scrubs when the side speed difference it needs exceeds this fraction of the forward
rim speed (the inner side then rolls at less than half the mean)."""


class TurnDetector:
    """A skid-steer turn: |yaw rate| above a threshold, and tight enough that the wheels
    scrub. The wheels then slide sideways and the lateral non-holonomic constraint does not
    hold (Kilic et al. 2022, sec. 3.2).

    How tight: the turn needs a side speed difference of yaw rate x the effective track
    (:mod:`slip_estimator.core.track_width`, 1.5-1.9x the wheel spacing on skid-steer
    robots); while that stays below ``_SCRUB_FRACTION`` of the rim speed, both sides roll
    forward and the robot follows an arc (a fast robot's 0.4 rad/s arc at 0.9 m/s is not an
    in-place turn).
    """

    def __init__(self, yaw_rate_threshold_rps: float) -> None:
        self.yaw_rate_threshold_rps = yaw_rate_threshold_rps

    def is_turning(self, omega_nb_b: np.ndarray, C_b_n: np.ndarray,
                   rim_speed_mps: float | None = None, track_width_m: float = 0.0) -> bool:
        """Yaw rate = body rate projected on the local vertical; ``rim_speed_mps`` (the
        latest mean rim speed, None without wheels) and the effective ``track_width_m`` tell
        an arc from a scrubbing turn."""
        yaw_rate = math.fabs(float(C_b_n[2] @ omega_nb_b))
        if yaw_rate <= self.yaw_rate_threshold_rps:
            return False
        return (rim_speed_mps is None
                or 0.5 * yaw_rate * track_width_m > _SCRUB_FRACTION * math.fabs(rim_speed_mps))


class ImuRate:
    """The IMU's nominal sample interval: the median of its first ``learn_samples`` intervals,
    then a slow running mean. Every window defined in seconds (stationarity, alignment) then
    holds that many of its samples, whatever the rate (20-1000 Hz)."""

    def __init__(self, learn_samples: int = 10, initial_dt_s: float = 1.0 / 250.0) -> None:
        self.dt_s = initial_dt_s
        self._learn_samples = learn_samples
        self._first_dts_s: list[float] | None = []  # until the rate is known

    @property
    def known(self) -> bool:
        """True once the rate has been learned (:attr:`dt_s` is the IMU's own)."""
        return self._first_dts_s is None

    def add(self, dt_s: float) -> bool:
        """One regular interval (not a gap); True when the rate has just become known."""
        if self._first_dts_s is None:
            self.dt_s = 0.99 * self.dt_s + 0.01 * dt_s
            return False
        self._first_dts_s.append(dt_s)
        if len(self._first_dts_s) < self._learn_samples:
            return False
        self.dt_s = float(np.median(self._first_dts_s))
        self._first_dts_s = None
        return True
