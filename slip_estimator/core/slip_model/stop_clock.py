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
REST_SETTLE_S = 0.5
"""The rest's last stretch whose mean INS speed tells whether the zero-velocity updates have
levelled the INS (:meth:`StopClock.rest_offset_mps`)."""


class StopClock:
    """The current stop of the wheels (see the module docstring)."""

    def __init__(self, moving_threshold_mps: float) -> None:
        self._threshold_mps = moving_threshold_mps
        self.clear()

    def clear(self) -> None:
        """No stop under way (the next still sample starts one)."""
        self._since_ns: int | None = None
        self.rest_aided = False  # the zero-speed aid of the current stop was given
        self._rest_v: list[tuple[int, float]] = []  # (t, INS speed) at its aided samples

    def rest(self, t_ns: int, v: float) -> None:
        """A sample of the stop's zero-speed aid, the INS's forward speed ``v`` there."""
        self.rest_aided = True
        rest_v = self._rest_v
        rest_v.append((t_ns, v))
        while rest_v[0][0] < t_ns - int(REST_SETTLE_S * _NS):
            rest_v.pop(0)

    def rest_offset_mps(self, zupt_std_mps: float) -> float:
        """The INS forward speed the rest's zero-velocity updates left: its mean over the last
        ``REST_SETTLE_S`` where beyond ``zupt_std_mps`` (the updates' own 1-sigma; the samples
        are correlated, so the mean's noise is not smaller), else 0, m/s. The updates pull the
        speed to zero at each step, so an offset they leave for half a second is an
        acceleration error (tilt, accelerometer bias) they have not removed, and the free INS
        of the next start integrates it, with the offset's sign (:class:`~.chain.SlipChain`)."""
        n = len(self._rest_v)
        mean = sum(v for _t, v in self._rest_v) / n if n >= 3 else 0.0
        return mean if abs(mean) > zupt_std_mps else 0.0

    def still_ns(self, t_ns: int, w: float) -> int | None:
        """How long the rim speed ``w`` has been below the moving threshold at ``t_ns``, ns
        (None while it is above: a new stop starts with no zero-speed aid given)."""
        if abs(w) >= self._threshold_mps:
            self.clear()
            return None
        if self._since_ns is None:
            self._since_ns = t_ns
        return t_ns - self._since_ns

    def zero_speed_aid(self, t_ns: int, still_ns: int, v: float,
                       zupt_std_mps: float) -> float | None:
        """Whether wheels still for ``still_ns`` (:meth:`still_ns`) bring the stop's
        zero-speed aid at ``t_ns``: None while the body is taken to be stopping (less than
        ``STOP_S``); else the sample is the rest's (the INS's forward speed ``v`` there,
        :meth:`rest`) and the INS speed its updates have left, m/s (:meth:`rest_offset_mps`
        beyond ``zupt_std_mps``, else 0)."""
        if still_ns < int(STOP_S * _NS):
            return None
        # Wheels held still: the body is at rest unless it slides, which the gate catches.
        # This anchors the next start even where a vibrating IMU keeps the ZUPT off.
        self.rest(t_ns, v)
        return self.rest_offset_mps(zupt_std_mps)

    def stopping(self, t_ns: int, w: float, awaits_aid: bool = True) -> bool:
        """The rim speed ``w`` fell below the moving threshold less than ``STOP_S`` ago, or,
        with ``awaits_aid``, the stop's zero-speed aid has not been given yet: the sample it
        comes with still shows the speed the INS had before it, not a slide (a slide shows
        from the next sample on, where the gate refuses the aid). Repeated calls for one
        sample are harmless."""
        still = self.still_ns(t_ns, w)
        return still is not None and (still < int(STOP_S * _NS)
                                      or (awaits_aid and not self.rest_aided))
