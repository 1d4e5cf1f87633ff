"""The rim speed the slip model remembers: whether it is steady, how far it moved lately and
when it began to move (a wheel-side change is measured from there). Only the standard library
is used."""
from __future__ import annotations

from collections import deque

_NS = 1_000_000_000
STEADY_FRACTION = 0.05
"""Rim speed steady: it moved by less than this fraction (plus 1 cm/s) since the last sample."""
MEMORY_S = 2.0
"""A wheel-side change needs the rim speed to have moved within this long."""
_ONSET_FRACTION = 0.1
"""The rim began to move at the last sample within this fraction of the memory's largest
change from now."""


def rim_steady(previous_mps: float | None, w: float) -> bool:
    """The rim speed ``w`` (m/s) is steady: it moved by less than ``STEADY_FRACTION`` of itself
    plus 1 cm/s since the last sample's ``previous_mps`` (None: no last sample)."""
    return previous_mps is not None and abs(w - previous_mps) <= STEADY_FRACTION * abs(w) + 0.01


class RimMemory:
    """The moving rim speeds of the last ``MEMORY_S``."""

    def __init__(self) -> None:
        self.last_mps: float | None = None
        self._recent: deque = deque()

    def clear(self) -> None:
        self.last_mps = None
        self._recent.clear()

    def add(self, t_ns: int, w: float) -> bool:
        """Remember the rim speed ``w`` (m/s) at ``t_ns``; True when it is steady."""
        steady = rim_steady(self.last_mps, w)
        self.last_mps = w
        recent = self._recent
        recent.append((t_ns, w))
        while recent[0][0] < t_ns - int(MEMORY_S * _NS):
            recent.popleft()
        return steady

    def moved_mps(self, w: float) -> float:
        """The largest difference between ``w`` and a remembered rim speed, m/s."""
        return max(abs(w - wk) for _, wk in self._recent)

    def onset_ns(self, w: float) -> int:
        """When the rim began to move towards ``w``, ns."""
        dev = self.moved_mps(w)
        return max(tk for tk, wk in self._recent
                   if abs(w - wk) >= (1.0 - _ONSET_FRACTION) * dev)
