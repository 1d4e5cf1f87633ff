"""Multi-scale step test: a slip change is a step of the free residual, INS error a walk.

The slip model (:mod:`slip_estimator.core.slip_model.model`) feeds it, per wheel sample, the free
residual ``rho`` (the filter's forward speed less the held model's, without the wheel aid's own
corrections) and the along-track acceleration those corrections cause. It smooths ``rho`` over
``SMOOTH_S`` and compares the smoothed value with its value ``T`` ago for each scale ``T`` of
``SCALES_S``, against a threshold of ``k`` times the spread of that change, which it learns
online (robustly) from the samples that do not alarm. Only the standard library is used.
"""
from __future__ import annotations

import math
from collections import deque

SMOOTH_S = 0.5
"""Averaging time of the free residual: white wheel noise (10 Hz quantisation, pitching) falls
by sqrt(n), a slip transition (>= 0.5 s) is barely blurred."""
SCALES_S = (1.0, 2.5)
"""Time scales of the step test: a slip transition of 0.5-3 s shows fully in one of them,
while the INS random walk grows only like sqrt(T)."""
_SCALES_NS = tuple(int(x * 1e9) for x in SCALES_S)
_SMOOTH_NS = int(SMOOTH_S * 1e9)
_SPREAD_PRIOR_N = 10
_SPREAD_MEMORY_N = 500
"""The spread is learned as a running mean (from a prior worth 10 samples) that becomes an
EMA over 500 samples (50 s at 10 Hz): a step that stays under the threshold cannot inflate it
within its own transition."""


class StepTest:
    """The test of the module docstring; ``prior_var_per_s``: the prior spread of the
    residual's change, a random walk's variance per second (m^2/s^3)."""

    def __init__(self, prior_var_per_s: float) -> None:
        self.spread_var = [prior_var_per_s * t for t in SCALES_S]
        self._spread_n = [_SPREAD_PRIOR_N] * len(SCALES_S)
        self.clear()

    def clear(self) -> None:
        """Start afresh (a change was detected, or the INS went through a gap); the learned
        spread is kept."""
        self._free: deque = deque()  # (t, rho) over the smoothing time
        self._free_sum = 0.0
        self._smooth: deque = deque()  # (t, smoothed rho, aid acceleration)

    def add(self, t_ns: int, rho: float, aid_accel_mps2: float, min_step_mps: float,
            k: float, floor_var: tuple[float, ...] | list[float] = ()) -> int | None:
        """Add one sample; return the onset time on an alarm (a change larger than
        ``min_step_mps`` and ``k`` times its spread at some scale: the learned one, or
        ``floor_var`` at that scale if larger), else None."""
        free = self._free
        free.append((t_ns, rho))
        self._free_sum += rho
        while free[0][0] < t_ns - _SMOOTH_NS:
            self._free_sum -= free.popleft()[1]
        rho_s = self._free_sum / len(free)
        smooth = self._smooth
        smooth.append((t_ns, rho_s, aid_accel_mps2))
        while len(smooth) > 2 and smooth[1][0] <= t_ns - _SCALES_NS[-1]:
            smooth.popleft()  # keep one entry at or before the longest scale
        alarm = None
        for i, scale_ns in enumerate(_SCALES_NS):
            t_then = t_ns - scale_ns
            then = None
            for t, r, acc in smooth:  # the newest value at or before t_then (oldest first)
                if t > t_then:
                    break
                then = (t, r, acc)
            if then is None:
                continue
            # The change since then without the aid corrections made since then.
            d = rho_s - then[1] + then[2] * (t_ns - then[0]) * 1e-9
            var = max(self.spread_var[i], floor_var[i]) if floor_var else self.spread_var[i]
            h = max(min_step_mps, k * math.sqrt(var))
            if abs(d) > h:
                alarm = t_then if alarm is None else min(alarm, t_then)
            else:  # learn the spread at this scale, robustly (clipped at 3 sigma)
                d2 = min(d * d, 9.0 * var)
                n = self._spread_n[i] = min(self._spread_n[i] + 1, _SPREAD_MEMORY_N)
                self.spread_var[i] += (d2 - self.spread_var[i]) / n
        return alarm
