"""The adapter's clock is the IMU's stamps (data time, never the wall clock), so a replay equals
what the node would have done: :class:`ImuStamps` judges each IMU stamp (in order, a small step
back, a jump back that restarts the estimator, a gap of lost samples) and
:class:`OutputSchedule` says when odometry and ``/diagnostics`` are due."""
from __future__ import annotations

from enum import Enum

from slip_estimator.core.params import Params

RESET_JUMP_BACK_S = 1.0
"""An IMU stamp this far behind the previous one restarts the estimator (bag loop, sim reset);
smaller steps back are rejected as ``non_monotonic``."""

IMU_GAP_FACTOR = 1.5
"""An IMU stamp step longer than this many nominal periods counts as a gap (lost samples)."""


class StampStep(Enum):
    """What an IMU stamp is, after the previous one."""

    NEXT = 'next'
    """The first stamp, or later than the previous one by about the nominal period."""
    GAP = 'gap'
    """Later than the previous one by more than ``IMU_GAP_FACTOR`` nominal periods."""
    BEHIND = 'behind'
    """Not later than the previous one, by at most ``RESET_JUMP_BACK_S``: rejected."""
    JUMPED_BACK = 'jumped_back'
    """More than ``RESET_JUMP_BACK_S`` behind the previous one: a clock reset."""


class ImuStamps:
    """The IMU stamp sequence: the last accepted stamp and the nominal period (an EMA of the
    steps)."""

    __slots__ = ('last_ns', '_dt_ns')

    def __init__(self) -> None:
        self.last_ns: int | None = None
        """The last accepted stamp, ns."""
        self._dt_ns: float | None = None

    def step(self, stamp_ns: int) -> StampStep:
        """Judge ``stamp_ns``; a stamp taken (NEXT or GAP) becomes the last one, a stamp behind
        (BEHIND or JUMPED_BACK) changes nothing."""
        last = self.last_ns
        if last is not None and stamp_ns <= last:
            return (StampStep.JUMPED_BACK if last - stamp_ns > RESET_JUMP_BACK_S * 1e9
                    else StampStep.BEHIND)
        self.last_ns = stamp_ns
        if last is None:
            return StampStep.NEXT
        dt = float(stamp_ns - last)
        if self._dt_ns is None:
            self._dt_ns = dt
        elif dt > IMU_GAP_FACTOR * self._dt_ns:
            return StampStep.GAP
        else:
            self._dt_ns += 0.01 * (dt - self._dt_ns)
        return StampStep.NEXT


class OutputSchedule:
    """When odometry (``odometry_rate_hz`` of IMU stamps, 0 = every IMU sample) and
    ``/diagnostics`` (the first IMU sample, then every ``diagnostics_period_s``) are due."""

    __slots__ = ('_odom_period_ns', '_diag_period_ns', '_next_odom_ns', '_next_diag_ns')

    def __init__(self, params: Params) -> None:
        self._odom_period_ns = (0 if params.odometry_rate_hz == 0.0
                                else round(1e9 / params.odometry_rate_hz))
        self._diag_period_ns = round(params.diagnostics_period_s * 1e9)
        self._next_odom_ns: int | None = None
        self._next_diag_ns: int | None = None

    def odometry_due(self, stamp_ns: int) -> bool:
        """Whether odometry is due at ``stamp_ns`` (:meth:`odometry_sent` once it went out)."""
        return self._next_odom_ns is None or stamp_ns >= self._next_odom_ns

    def odometry_sent(self, stamp_ns: int) -> None:
        """Odometry went out at ``stamp_ns``: the next is due one period later on a fixed grid
        (no drift), re-anchored after a gap in the data (:func:`_next_due`)."""
        self._next_odom_ns = _next_due(self._next_odom_ns, stamp_ns, self._odom_period_ns)

    def diagnostics_due(self, stamp_ns: int) -> bool:
        """Whether ``/diagnostics`` is due at ``stamp_ns``; if so, the next is scheduled as
        odometry's is."""
        if self._next_diag_ns is not None and stamp_ns < self._next_diag_ns:
            return False
        self._next_diag_ns = _next_due(self._next_diag_ns, stamp_ns, self._diag_period_ns)
        return True


def _next_due(due_ns: int | None, stamp_ns: int, period_ns: int) -> int:
    """One period after ``due_ns`` (a fixed grid, no drift), or after ``stamp_ns`` when that
    is not later than ``stamp_ns`` (a gap in the data) or there is no grid yet."""
    nxt = (due_ns or stamp_ns) + period_ns
    return nxt if nxt > stamp_ns else stamp_ns + period_ns
