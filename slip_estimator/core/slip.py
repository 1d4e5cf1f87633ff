"""Slip ratio, its uncertainty, its class (paper eq. 1 and sec. 5.3) and the probability that
it is medium or worse."""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.types import SLIP_CLASS_UPPER_BOUNDS


def slip_ratio(v_body_mps: float, v_rim_mps: float) -> float:
    """Longitudinal slip ratio s in [-1, 1] (paper eq. 1).

    ``s = 1 - v/(r w)`` when ``v < r w`` (driving slip, s > 0), ``s = r w / v - 1`` when
    ``v > r w`` (skid, s < 0), 0 when equal. Reversing is handled by mirroring both speeds
    (the rover's "forward" is the direction of the wheels); a body moving against its wheels
    is extreme slip, clamped to +-1.
    """
    if v_rim_mps < 0.0 or (v_rim_mps == 0.0 and v_body_mps < 0.0):
        v_body_mps, v_rim_mps = -v_body_mps, -v_rim_mps
    if v_body_mps < v_rim_mps:
        return min(1.0, 1.0 - v_body_mps / v_rim_mps)
    if v_body_mps > v_rim_mps:
        return max(-1.0, v_rim_mps / v_body_mps - 1.0)
    return 0.0


def speed_ratio(s: float) -> float:
    """``g(s) = v / (r w)`` of a slip ratio (eq. 1 solved for the body speed)."""
    return 1.0 - s if s >= 0.0 else 1.0 / (1.0 + s)


def slip_ratio_std(v_body_mps: float, v_rim_mps: float, var_body: float, var_rim: float) -> float:
    """1-sigma of s by first-order propagation of the body-speed and rim-speed variances."""
    v, w = abs(v_body_mps), abs(v_rim_mps)
    if v < w:
        d_v, d_w = -1.0 / w, v / (w * w)
    elif v > 0.0:
        d_v, d_w = -w / (v * v), 1.0 / v
    else:
        return 1.0
    return min(1.0, math.sqrt(d_v * d_v * var_body + d_w * d_w * var_rim))


MEDIUM_LOWER_BOUND = SLIP_CLASS_UPPER_BOUNDS[0]
"""``|s|`` above which the slip is medium or worse."""


def p_medium_or_worse(s: float, s_std: float) -> float:
    """Probability that the slip is medium or worse, ``P(|S| > 0.2)`` for ``S ~ N(s, s_std^2)``
    (the published slip and its 1-sigma); NaN when either is not finite."""
    if not (math.isfinite(s) and math.isfinite(s_std)):
        return float('nan')
    if s_std <= 0.0:
        return 1.0 if abs(s) > MEDIUM_LOWER_BOUND else 0.0
    k = 1.0 / (s_std * math.sqrt(2.0))  # P(S > b) = Phi((s - b) / s_std) = erfc(...) / 2
    b = MEDIUM_LOWER_BOUND
    return 0.5 * (math.erfc((b - s) * k) + math.erfc((b + s) * k))


def p_beyond_medium_bound(s: float, s_std: float) -> float:
    """Probability that the slip lies beyond 0.2 on the side of ``s``, ``P(sign(s) S > 0.2)``
    for ``S ~ N(s, s_std^2)``: 1/2 at the bound and for a 1-sigma too wide to tell (where
    :func:`p_medium_or_worse` counts the far tail too and tends to 1)."""
    if s_std <= 0.0:
        return 1.0 if abs(s) > MEDIUM_LOWER_BOUND else 0.0
    return 0.5 * math.erfc((MEDIUM_LOWER_BOUND - abs(s)) / (s_std * math.sqrt(2.0)))


def slip_class(s: float, moving: bool) -> int:
    """0 none (not moving), 1 low (|s| <= 0.2), 2 medium (<= 0.4), 3 high (<= 0.7), 4 extreme."""
    if not moving:
        return 0
    a = abs(s)
    for k, upper in enumerate(SLIP_CLASS_UPPER_BOUNDS):
        if a <= upper:
            return k + 1
    return 4


def slip_ratio_array(v_body_mps, v_rim_mps) -> np.ndarray:
    """:func:`slip_ratio` vectorised (evaluation, simulator truth); NaN inputs give NaN."""
    v, w = np.broadcast_arrays(np.asarray(v_body_mps, dtype=float),
                               np.asarray(v_rim_mps, dtype=float))
    flip = (w < 0) | ((w == 0) & (v < 0))
    v = np.where(flip, -v, v)
    w = np.where(flip, -w, w)
    with np.errstate(divide='ignore', invalid='ignore'):
        s = np.where(v < w, 1.0 - v / w, np.where(v > w, w / v - 1.0, 0.0))
    s = np.clip(s, -1.0, 1.0)
    return np.where(np.isnan(v) | np.isnan(w), np.nan, s)


def slip_class_array(s, moving) -> np.ndarray:
    """:func:`slip_class` vectorised; -1 where s is NaN while moving."""
    s = np.asarray(s, dtype=float)
    moving = np.broadcast_to(np.asarray(moving, dtype=bool), s.shape)
    cls = 1 + np.searchsorted(np.asarray(SLIP_CLASS_UPPER_BOUNDS), np.abs(s), side='left')
    cls = np.where(moving, cls, 0)
    return np.where(np.isnan(s) & moving, -1, cls).astype(int)
