"""The sensor series ``setup`` measures on, and the windows it measures them in (pure: numpy).

Times are seconds from the first IMU stamp (float, ascending), IMU vectors are resolved in the
IMU's own frame (``imu_link``, as published: nothing is assumed about the mounting), rim speeds
in m/s with the declared wheel radius, the wheel differential right minus left (m/s), GNSS
positions in ENU metres from the first fix.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ImuSeries:
    """IMU samples as published: ``f_imu_mps2`` specific force and ``omega_imu_rps`` rate,
    both (n, 3) in imu_link; ``t_s`` (n,)."""

    t_s: np.ndarray
    f_imu_mps2: np.ndarray
    omega_imu_rps: np.ndarray

    @property
    def dt_s(self) -> float:
        """Median sample interval, s."""
        return float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else float('nan')


@dataclass(frozen=True)
class WheelSeries:
    """Wheel samples: mean rim speed ``v_mps`` and ``diff_mps`` right minus left (NaN where
    the sides are not known), at ``t_s``."""

    t_s: np.ndarray
    v_mps: np.ndarray
    diff_mps: np.ndarray


@dataclass(frozen=True)
class GnssSeries:
    """GNSS fixes: ``t_s``, ``llh0`` (rad, rad, m) of the first fix, ``enu_m`` (n, 3)."""

    t_s: np.ndarray
    llh0: tuple[float, float, float]
    enu_m: np.ndarray


@dataclass(frozen=True)
class Figure:
    """A measured value with its spread (1-sigma over independent parts) and the samples it
    rests on (``n``); ``value`` NaN when it could not be measured (``why`` says why)."""

    value: float
    spread: float = float('nan')
    n: int = 0
    why: str = ''

    @property
    def ok(self) -> bool:
        return math.isfinite(self.value)


def missing(why: str) -> Figure:
    """A figure that could not be measured, and why."""
    return Figure(float('nan'), why=why)


STOPPED_SPEED_MPS = 0.01
"""Rim speeds below this count as stopped (encoder quantisation on slow wheels)."""
REST_MIN_S = 1.0
"""A stop must last this long to count as rest (the body settles after braking)."""
REST_MARGIN_S = 0.3
"""Cut from both ends of a stop: the braking and the start."""


def window_mean(t_s: np.ndarray, x: np.ndarray, tq_s: np.ndarray, width_s: float) -> np.ndarray:
    """Mean of ``x`` (n,) or (n, k) over ``width_s`` around each query time (NaN: none)."""
    x = np.asarray(x, dtype=float)
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    i0 = np.searchsorted(t_s, tq_s - 0.5 * width_s)
    i1 = np.searchsorted(t_s, tq_s + 0.5 * width_s)
    n = (i1 - i0).astype(float)
    with np.errstate(invalid='ignore', divide='ignore'):
        n = np.where(n > 0, n, np.nan)
        return (c[i1] - c[i0]) / (n if x.ndim == 1 else n[:, None])


def rest_intervals(wheels: WheelSeries, imu: ImuSeries) -> list[tuple[float, float]]:
    """Intervals (s) where every wheel stood still for at least ``REST_MIN_S``, trimmed by
    ``REST_MARGIN_S``; before the first wheel sample, the IMU alone (the robot was not yet
    driven: the log starts at rest when the first wheel samples are stopped)."""
    still = np.abs(wheels.v_mps) < STOPPED_SPEED_MPS
    still &= ~(np.abs(np.nan_to_num(wheels.diff_mps)) > 2 * STOPPED_SPEED_MPS)
    out = []
    start = imu.t_s[0] if len(still) and still[0] else None
    for k in range(len(still)):
        if still[k] and start is None:
            start = wheels.t_s[k]
        elif not still[k] and start is not None:
            out.append((start, wheels.t_s[k]))
            start = None
    if start is not None:
        out.append((start, imu.t_s[-1]))
    return [(a + REST_MARGIN_S, b - REST_MARGIN_S) for a, b in out
            if b - a >= REST_MIN_S + 2 * REST_MARGIN_S]


def inside(t_s: np.ndarray, intervals: list[tuple[float, float]]) -> np.ndarray:
    """Mask of the times inside any of the intervals."""
    mask = np.zeros(len(t_s), dtype=bool)
    for a, b in intervals:
        mask |= (t_s >= a) & (t_s <= b)
    return mask


def blocks(n: int, parts: int = 8) -> list[np.ndarray]:
    """Index blocks splitting ``range(n)`` into ``parts`` contiguous parts (for spreads)."""
    return [b for b in np.array_split(np.arange(n), parts) if len(b)]


def spread_of(values: list[float]) -> float:
    """Standard error of the mean of independent part estimates (NaN for fewer than 2)."""
    v = np.array([x for x in values if math.isfinite(x)])
    return float(v.std(ddof=1) / math.sqrt(len(v))) if len(v) >= 2 else float('nan')
