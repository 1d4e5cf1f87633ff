"""When a body can run ahead of wheels held at their commanded rate (negative slip).

Physics. A rover's motor controllers hold the wheel rate; the body runs ahead of the rims only
when something pulls it: gravity along a downhill slope beating the rolling resistance of soft
ground. On level or rising ground a measured run-ahead is the INS (it missed the start of a
slowdown whose end it then sees, or it drifted), and no slope a rover drives lets the body roll
at twice the rim speed (it would slide). Over a crest the front wheels are on the down-slope
before the body pitches, so the slope is judged a little ahead at the current nose-down pitch
rate. The pull lasts only as long as the grade: once the ground ahead is no longer nose-down
beyond ``PITCH_RAD`` a run-ahead held since it was read downhill is over, and the body is back
on the ground's slip (its return, as gradual as the grade easing, is too slow for the step
test to see: patches seed 0 held -0.29 for 44 s while the truth was back at 0.06). Only the
standard library is used.
"""
from __future__ import annotations

import math

MIN_SLIP = 0.15
"""A run-ahead this large needs the downhill pull (a few percent: slope, encoder scale, skid)."""
MAX_SLIP = 0.5
"""A body at twice the speed of wheels held at their rate slides rather than rolls: such a
reading is the INS (an unobserved bias after a start in motion)."""
PITCH_RAD = math.radians(2.0)
"""Nose-down pitch beyond which a body running ahead of its wheels is physically possible."""
CREST_LOOKAHEAD_S = 2.0
"""How far ahead the slope is judged while the body pitches nose down (passing a crest)."""
_RATE_TAU_S = 0.5
"""Smoothing time of the pitch rate."""


class RunAheadCheck:
    """Tracks the pitch (FRD, nose up positive) and judges measured run-aheads."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._pitch_rad = 0.0
        self._rate_rps = 0.0
        self._t_ns: int | None = None
        self.ground: float | None = None
        """While a run-ahead read downhill is held: the ground's slip it returns to."""
        self.left: float | None = None
        """After a run-ahead read nose down (held, or confirmed as the hold before it), while
        the ground ahead is still nose-down: the ground's slip the body left and returns to."""

    @property
    def pitch_rad(self) -> float:
        """The last pitch, rad (FRD, nose up positive)."""
        return self._pitch_rad

    def add(self, t_ns: int, pitch_rad: float) -> None:
        """One pitch sample (at the wheel rate)."""
        if self._t_ns is not None:
            dt_s = (t_ns - self._t_ns) * 1e-9
            if 0.0 < dt_s < 1.0:
                self._rate_rps += min(1.0, dt_s / _RATE_TAU_S) * (
                    (pitch_rad - self._pitch_rad) / dt_s - self._rate_rps)
        self._t_ns, self._pitch_rad = t_ns, pitch_rad

    @property
    def pitch_ahead_rad(self) -> float:
        """The pitch ``CREST_LOOKAHEAD_S`` ahead while pitching nose down, the pitch otherwise."""
        return self._pitch_rad + CREST_LOOKAHEAD_S * min(0.0, self._rate_rps)

    def held(self, slip: float, previous: float | None, ground: float | None,
             measured: float | None = None) -> None:
        """The slip model now holds ``slip``, settled as a change from ``previous`` (None: a
        start) that read ``measured`` (None: as held). A change down to a run-ahead (below
        the previous and below zero) read nose down beyond ``PITCH_RAD`` remembers the ground
        it returns to: ``ground`` (the ground's slip the last start measured), or the previous
        hold where no start measured one. A hold at or above zero forgets it. A run-ahead
        reading (below zero and below the previous hold) read nose down leaves that ground
        (:attr:`left`) even where the previous hold was kept; any other reading forgets it."""
        measured = slip if measured is None else measured
        nose_down = self._pitch_rad < -PITCH_RAD
        if slip >= 0.0 or previous is None:
            self.ground = None
        elif self.ground is None and slip < previous and nose_down:
            self.ground = ground if ground is not None else previous
        if previous is None or not (measured < min(previous, 0.0) and nose_down):
            self.left = None
        elif self.left is None:
            self.left = self.ground if self.ground is not None else previous

    def returned(self) -> float | None:
        """The ground's slip where a held run-ahead is over (the ground ahead no longer
        nose-down beyond ``PITCH_RAD``: no grade pulls the body ahead), then forgotten; None
        otherwise. The eased grade also forgets the ground a run-ahead :attr:`left`."""
        ground = self.ground
        if self.pitch_ahead_rad < -PITCH_RAD:
            return None
        self.left = None  # the grade has eased: what rises from here is not that return
        if ground is None:
            return None
        self.ground = None
        return ground

    def implausible(self, slip: float) -> bool:
        """True for a run-ahead no ground here explains: beyond ``MAX_SLIP``, or beyond
        ``MIN_SLIP`` where the ground ahead is not nose-down steeper than ``PITCH_RAD``."""
        return slip < -MAX_SLIP or (slip < -MIN_SLIP and self.pitch_ahead_rad > -PITCH_RAD)
