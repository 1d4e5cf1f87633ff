"""Verifying a take-back (:mod:`slip_estimator.core.history`: what the wheel aid taught since a
body-side change began is taken back at its alarm). On an IMU whose tilt wanders (the simulated
Pathfinder's vibration), what the aid taught over the seconds before a false body-side alarm
was its levelling of the INS's own excursion; taken back, the INS runs away at the rate removed
(0.26-0.54 m/s in the next second after 0.30-0.46 m/s^2 removed on ground that never slips, the
rim steady) and a false slip is held. A true change mostly leaves the INS level after the
take-back, but where the body keeps slowing through the check (a slip ramp the alarm fired in
the middle of) the INS follows it at a rate like the one removed: only a take-back well beyond
what this IMU resolves over the check (:class:`RunawayScale`, measured: its free residual's 1-s
spread, its tilt 1-sigma, the aid's innovation scatter) is checked. :class:`TakeBackCheck`
keeps the last take-back and returns the correction that restores it (its tilt and bias, and
the speed lost meanwhile). numpy and the standard library only.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from slip_estimator.core.slip_model.step_test import SCALES_S
from slip_estimator.core.state import ATT, BA, N_ERR, VEL

_NS = 1_000_000_000
TAKE_BACK_CHECK_S = SCALES_S[0]
"""How long after a take-back the INS is watched (:meth:`TakeBackCheck.refuted`): the step
test's shortest scale, over which its spread is measured (:class:`RunawayScale`)."""
RUNAWAY_SIGMA = 4.0
"""A take-back is checked when the along-track acceleration it removed exceeds this many times
the acceleration the INS resolves over the check (:class:`RunawayScale`). On the simulated
Pathfinder IMU (1-s spread 0.045-0.068 m/s, g times the tilt 1-sigma 0.050-0.062 m/s^2) that
is 0.20-0.27 m/s^2 (the constant it replaces: 0.2), where the false take-backs on ground that
never slips removed 4.1-9.5 times the scale; on the consumer 30-Hz IMU (g tilt 0.066-0.089)
0.26-0.36. Below 3.7 a tactical IMU's right take-back at a patch the body kept slowing
through (0.074 m/s^2 removed, g tilt 0.020) would be restored."""
_RUNAWAY_RATIO = (0.7, 1.3)
"""The INS's speed change over the check, relative to the acceleration removed times the
check's span, that marks it as running away at that rate (the false take-backs: 0.82-1.17)."""


class RunawayScale(NamedTuple):
    """What a take-back's check is measured against, from this IMU and these wheels at the
    take-back (:func:`runaway_scale`)."""

    accel_mps2: float
    """along-track acceleration the free INS resolves over ``TAKE_BACK_CHECK_S``, m/s^2"""
    rim_mps: float
    """rim-speed change that still counts as steady over the check, m/s"""


def runaway_scale(spread_var_mps2: float, tilt_std_rad: float, g_mps2: float,
                  aid_noise_var_mps2: float) -> RunawayScale:
    """The check's scale from measured quantities: the acceleration is the coarser of the free
    residual's measured spread over the check span (``spread_var_mps2``, the step test's at its
    shortest scale) per that span and the filter's tilt resolution (``tilt_std_rad``, its
    1-sigma, grown by the vibration the IMU shows) times ``g_mps2`` (a take-back within either
    could be the aid's routine levelling of a real tilt or a body that keeps slowing); the rim
    tolerance is the wheel aid's measured innovation scatter (``aid_noise_var_mps2``: encoder
    quantisation, pitching; where the rim moves beyond it, the INS may have followed the
    body)."""
    return RunawayScale(max(math.sqrt(spread_var_mps2) / TAKE_BACK_CHECK_S,
                            tilt_std_rad * g_mps2), math.sqrt(aid_noise_var_mps2))


@dataclass
class _TakeBack:
    """A take-back waiting for its check: when, its tilt and bias error state, the along-track
    acceleration it removed, the forward speed then, the scale it is checked against, and the
    rim speed at the first wheel sample after it."""

    t_ns: int
    dx: np.ndarray
    da_fwd_mps2: float
    v_fwd_mps: float
    scale: RunawayScale
    rim_mps: float | None = None


class TakeBackCheck:
    """The last take-back, until its check (module doc)."""

    def __init__(self) -> None:
        self._pending: _TakeBack | None = None

    @property
    def pending(self) -> bool:
        """A take-back waits for its check."""
        return self._pending is not None

    def clear(self) -> None:
        """Forget the take-back waiting (after a recovery)."""
        self._pending = None

    def taken_back(self, t_ns: int, v_fwd_mps: float, scale: RunawayScale,
                   corrections: Iterable) -> None:
        """Remember a take-back made at ``t_ns`` (INS time; ``v_fwd_mps``: the forward speed
        after it) from its ``corrections`` (``history.Correction``: the take-back and the
        anchor after it; their tilt and bias parts), checked against ``scale``."""
        dx = np.zeros(N_ERR)
        da_mps2 = 0.0
        for c in corrections:
            dx[ATT] += c.dx[ATT]
            dx[BA] += c.dx[BA]
            da_mps2 += c.da_fwd_mps2
        self._pending = _TakeBack(t_ns, dx, da_mps2, v_fwd_mps, scale)

    def refuted(self, t_ns: int, v_fwd_mps: float, rim_mps: float,
                forward_n: np.ndarray) -> np.ndarray | None:
        """``TAKE_BACK_CHECK_S`` after the take-back (``t_ns``, ``v_fwd_mps``: the INS time and
        forward speed now; ``rim_mps``: the rim speed now; ``forward_n``: the body's forward
        axis in navigation axes): the error state that restores it (the tilt and bias taken
        back, and the forward speed the INS lost since) if the INS ran away at the rate
        removed while the rim stayed steady (module doc), else None."""
        tb = self._pending
        if tb is None:
            return None
        if tb.rim_mps is None:
            tb.rim_mps = rim_mps
        if t_ns - tb.t_ns < int(TAKE_BACK_CHECK_S * _NS):
            return None
        self._pending = None
        removed_mps = tb.da_fwd_mps2 * TAKE_BACK_CHECK_S
        dv_mps = v_fwd_mps - tb.v_fwd_mps
        lo, hi = _RUNAWAY_RATIO
        if abs(tb.da_fwd_mps2) < RUNAWAY_SIGMA * tb.scale.accel_mps2 \
                or abs(rim_mps - tb.rim_mps) >= tb.scale.rim_mps \
                or not lo * abs(removed_mps) <= dv_mps * math.copysign(1.0, removed_mps) \
                <= hi * abs(removed_mps):
            return None
        dx = -tb.dx
        dx[VEL] = dv_mps * forward_n
        return dx
