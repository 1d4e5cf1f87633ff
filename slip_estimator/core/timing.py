"""Time offset between the wheel stamps and the IMU, measured from the data.

A skid-steer rover turns by driving its sides at different speeds, so the wheel differential
``v_right - v_left`` follows the gyro yaw rate. Cross-correlating the two over a range of lags
gives the lag of the wheel stamps behind the IMU: a wheel sample stamped ``t`` describes the
motion at IMU time ``t - lag``. The same routine serves the offline study of a log
(``pathfinder.wheel_imu_lag``) and the online monitor that names an undeclared offset in the
node's diagnostics.
"""
from __future__ import annotations

from collections import deque

import numpy as np


def correlation_vs_lag(t_fast_s: np.ndarray, x_fast: np.ndarray, t_slow_s: np.ndarray,
                       y_slow: np.ndarray, lags_s: np.ndarray, window_s: float = 0.1
                       ) -> np.ndarray:
    """Correlation of ``y_slow`` with the mean of ``x_fast`` over ``window_s`` around each
    ``t_slow - lag``, for every lag (NaN where undefined). Times in s, ascending."""
    t_fast = np.asarray(t_fast_s, dtype=float)
    t_slow = np.asarray(t_slow_s, dtype=float)
    y = np.asarray(y_slow, dtype=float)
    c = np.concatenate([[0.0], np.cumsum(np.asarray(x_fast, dtype=float))])
    lags = np.asarray(lags_s, dtype=float)
    out = np.full(len(lags), np.nan)
    # The window edges of every lag at once (element for element the per-lag arithmetic);
    # the online monitor runs this for 81 lags every 10 s.
    tq = t_slow[None, :] - lags[:, None]
    i0_all = np.searchsorted(t_fast, tq - 0.5 * window_s)
    i1_all = np.searchsorted(t_fast, tq + 0.5 * window_s)
    ok_all = i1_all > i0_all
    n_ok = ok_all.sum(axis=1).tolist()
    y_spread = _spread(y)  # that of y[ok] where every sample is ok (the same values)
    for k, n in enumerate(n_ok):
        if n < 3:
            continue
        i0, i1, y_k, y_k_spread = i0_all[k], i1_all[k], y, y_spread
        if n < len(y):
            ok = ok_all[k]
            i0, i1, y_k = i0[ok], i1[ok], y[ok]
            y_k_spread = _spread(y_k)
        mean = (c[i1] - c[i0]) / (i1 - i0)
        if _spread(mean) and y_k_spread:
            out[k] = _correlation(mean, y_k)
    return out


def _spread(x: np.ndarray) -> bool:
    """``x.std() > 0`` for a 1-D float array: the sum of the squared deviations from the mean
    as np.var computes them is positive (NaN is not)."""
    d = x - np.add.reduce(x) / len(x)
    return bool(np.add.reduce(d * d) > 0.0)


def _correlation(x: np.ndarray, y: np.ndarray) -> float:
    """``np.corrcoef(x, y)[0, 1]`` for two 1-D float arrays of one length >= 2: the
    operations of np.cov and np.corrcoef (numpy 1.x and 2.x), without their argument
    handling, which took most of the time for the monitor's short series."""
    X = np.concatenate((x[None, :], y[None, :]), axis=0)
    X -= X.mean(axis=1)[:, None]
    cov = np.dot(X, X.T.conj())
    cov *= np.true_divide(1, X.shape[1] - 1)
    stddev = np.sqrt(np.diag(cov))
    cov /= stddev[:, None]
    cov /= stddev[None, :]
    return float(np.clip(cov[0, 1], -1, 1))


def best_lag(t_fast_s: np.ndarray, x_fast: np.ndarray, t_slow_s: np.ndarray,
             y_slow: np.ndarray, max_lag_s: float = 0.4, step_s: float = 0.005,
             window_s: float = 0.1) -> tuple[float, float]:
    """(lag s, correlation) at the correlation peak over ``[-max_lag_s, max_lag_s]``; (NaN,
    NaN) when no lag gives a correlation."""
    lags = np.arange(-max_lag_s, max_lag_s + 1e-9, step_s)
    corr = correlation_vs_lag(t_fast_s, x_fast, t_slow_s, y_slow, lags, window_s)
    if not np.isfinite(corr).any():
        return float('nan'), float('nan')
    k = int(np.nanargmax(corr))
    return float(lags[k]), float(corr[k])


class WheelTimingMonitor:
    """Online lag of the wheel stamps behind the IMU from turns (yaw rate vs differential).

    Parameters
    ----------
    horizon_s : data kept for one estimate, s.
    period_s : time between estimates, s (each costs a few milliseconds).
    min_turn_rps : the yaw-rate spread (std, rad/s) the horizon needs for an estimate; a
        straight drive says nothing about timing.
    """

    def __init__(self, horizon_s: float = 30.0, period_s: float = 10.0,
                 min_turn_rps: float = 0.05, bin_s: float = 0.02) -> None:
        self.horizon_ns = int(horizon_s * 1e9)
        self.period_ns = int(period_s * 1e9)
        self.bin_ns = int(bin_s * 1e9)
        self.min_turn_rps = min_turn_rps
        # The yaw rate is kept as means over bin_s (the correlation averages over 0.1 s
        # anyway): a running sum per IMU sample, one entry per bin.
        self._sum, self._tsum, self._n, self._bin_start_ns = 0.0, 0, 0, None
        self._imu: deque = deque()     # (bin centre ns, mean yaw rate about z-down, rad/s)
        self._wheel: deque = deque()   # (stamp ns, v_right - v_left, m/s)
        self._next_ns: int | None = None
        self.lag_s = float('nan')
        self.correlation = float('nan')

    def add_imu(self, stamp_ns: int, yaw_rate_frd_rps: float) -> None:
        if self._bin_start_ns is None:
            self._bin_start_ns, self._next_ns = stamp_ns, stamp_ns + self.period_ns
        self._sum += yaw_rate_frd_rps
        self._tsum += stamp_ns
        self._n += 1
        if stamp_ns - self._bin_start_ns < self.bin_ns:
            return
        self._imu.append((self._tsum // self._n, self._sum / self._n))
        self._sum, self._tsum, self._n, self._bin_start_ns = 0.0, 0, 0, stamp_ns
        horizon = stamp_ns - self.horizon_ns
        while self._imu and self._imu[0][0] < horizon:
            self._imu.popleft()
        if stamp_ns >= self._next_ns:
            self._next_ns = stamp_ns + self.period_ns
            self._estimate()

    def add_wheel(self, stamp_ns: int, differential_mps: float | None) -> None:
        """One wheel sample's right minus left rim speed (None: not known, ignored)."""
        if differential_mps is None:
            return
        self._wheel.append((stamp_ns, differential_mps))
        horizon = stamp_ns - self.horizon_ns
        while self._wheel[0][0] < horizon:
            self._wheel.popleft()

    def _estimate(self) -> None:
        if len(self._wheel) < 20 or len(self._imu) < 20:
            return
        imu = np.array(self._imu, dtype=float)
        wheel = np.array(self._wheel, dtype=float)
        if imu[:, 1].std() < self.min_turn_rps:
            return
        t0 = imu[0, 0]
        # z down: a left turn is a negative yaw rate and a positive right - left.
        self.lag_s, self.correlation = best_lag((imu[:, 0] - t0) * 1e-9, -imu[:, 1],
                                                (wheel[:, 0] - t0) * 1e-9, wheel[:, 1],
                                                step_s=0.01)

    def suspicion(self, declared_latency_s: float) -> str | None:
        """What the measured lag says against ``declared_latency_s`` (None: nothing).

        The turns say when the wheels moved: a lag the parameters do not declare shifts every
        slip step against the body motion."""
        lag, corr = self.lag_s, self.correlation
        if not (corr >= 0.8 and abs(lag - declared_latency_s) > 0.05):
            return None
        return (f'wheel stamps {lag * 1e3:+.0f} ms behind the IMU (yaw rate vs wheel '
                f'differential in turns, r = {corr:.2f}) against a declared wheel_latency_s of '
                f'{declared_latency_s:.3f} s: clock offset or undeclared latency')
