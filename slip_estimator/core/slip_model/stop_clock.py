"""When still wheels are a stop: how long the rim speed has been below the moving threshold,
and whether the stop's zero-speed aid has been given.

A rover's wheels stop a little before its body (encoder lag, the last roll-out), so for
``STOP_S`` after the rim speed falls below the threshold the body is still taken to be
stopping; from then on still wheels are a stop and bring a zero-speed aid. The sample that
brings that aid still shows the speed the INS had before it (the held slip's error, not a
slide). Only the standard library is used.
"""
from __future__ import annotations

_NS = 1_000_000_000
STOP_S = 0.5
"""Wheels still for this long: the body is taken to be at rest (a zero-speed aid)."""


class StopClock:
    """The current stop of the wheels (see the module docstring)."""

    def __init__(self, moving_threshold_mps: float) -> None:
        self._threshold_mps = moving_threshold_mps
        self.clear()

    def clear(self) -> None:
        """No stop under way (the next still sample starts one)."""
        self._since_ns: int | None = None
        self.rest_aided = False  # the zero-speed aid of the current stop was given

    def still_ns(self, t_ns: int, w: float) -> int | None:
        """How long the rim speed ``w`` has been below the moving threshold at ``t_ns``, ns
        (None while it is above: a new stop starts with no zero-speed aid given)."""
        if abs(w) >= self._threshold_mps:
            self.clear()
            return None
        if self._since_ns is None:
            self._since_ns = t_ns
        return t_ns - self._since_ns

    def stopping(self, t_ns: int, w: float, awaits_aid: bool = True) -> bool:
        """The rim speed ``w`` fell below the moving threshold less than ``STOP_S`` ago, or,
        with ``awaits_aid``, the stop's zero-speed aid has not been given yet: the sample it
        comes with still shows the speed the INS had before it, not a slide (a slide shows
        from the next sample on, where the gate refuses the aid). Repeated calls for one
        sample are harmless."""
        still = self.still_ns(t_ns, w)
        return still is not None and (still < int(STOP_S * _NS)
                                      or (awaits_aid and not self.rest_aided))
