"""What the slip model keeps of the stretch it is aiding: the recent aided wheel samples, whose
window means anchor a change's continuity, and the wheel/INS consistency noise.

Only the standard library is used.
"""
from __future__ import annotations

from collections import deque
from typing import NamedTuple

_NS = 1_000_000_000
ANCHOR_S = 0.5
"""Aided samples before a change whose mean anchors its continuity measurement."""
_NOISE_MEMORY_S = 5.0
"""Memory of the measured wheel/INS consistency noise, s."""
_NOISE_STEP_MAX_S = 0.5
"""Longest interval since the last tracked wheel sample that the noise memory counts in full
(2-Hz wheels); a longer one (a gap, a stop, a measurement) counts as this: the first sample
after it weighs 0.5 s."""


class AidedMean(NamedTuple):
    """Means over the aided samples of a window."""

    t_ns: float
    """mean sample time (where the mean free speed belongs), ns"""
    z_mps: float
    """the held model's speed"""
    v_mps: float
    """the filter's speed"""
    v_free_mps: float
    """the free speed (without the wheel aid's corrections)"""
    aid_accel_mps2: float
    """the along-track acceleration the aid's corrections caused"""
    last_ns: int
    """time of the window's last sample, ns"""


class Anchor(NamedTuple):
    """What a change's measurement continues from: the held model's speed before it and the
    INS speed then, the filter's or, with ``aid_accel_mps2``, the free one (whose change is
    taken with that acceleration, as the step test takes it)."""

    z_mps: float
    v_mps: float
    body: bool
    """a body-side alarm (the velocity was re-anchored at once)"""
    aid_accel_mps2: float | None = None
    t_ns: float = 0.0
    """when ``v_mps`` was, ns"""


class AidedRecord:
    """The aided samples ``(t, z, v, v_free, aid_accel)`` of the last ``horizon_s`` while a
    slip is held; cleared by a change, a stop or an IMU gap."""

    def __init__(self, horizon_s: float) -> None:
        self._horizon_ns = int(horizon_s * _NS)
        self._rows: deque = deque()

    def __len__(self) -> int:
        return len(self._rows)

    def clear(self) -> None:
        self._rows.clear()

    def add(self, t_ns: int, z_mps: float, v_mps: float, v_free_mps: float,
            aid_accel_mps2: float) -> None:
        rows = self._rows
        rows.append((t_ns, z_mps, v_mps, v_free_mps, aid_accel_mps2))
        while rows[0][0] < t_ns - self._horizon_ns:
            rows.popleft()

    def mean(self, start_ns: int, end_ns: int | None = None) -> AidedMean | None:
        """Means over the samples in [``start_ns``, ``end_ns``] (no end: up to the newest);
        None when there is none."""
        rows = [x for x in self._rows if start_ns <= x[0] and (end_ns is None or x[0] <= end_ns)]
        return _mean(rows)

    def before(self, onset_ns: int) -> AidedMean | None:
        """What a change with onset ``onset_ns`` continues from: the mean over the
        ``ANCHOR_S`` before it, or the oldest sample where none is that old (None when there
        is no sample)."""
        return self.mean(onset_ns - int(ANCHOR_S * _NS), onset_ns) or self.first()

    def first(self) -> AidedMean | None:
        """The oldest sample (None when there is none)."""
        return _mean(list(self._rows)[:1])


def _mean(rows: list) -> AidedMean | None:
    if not rows:
        return None
    n = len(rows)
    return AidedMean(sum(x[0] for x in rows) / n, sum(x[1] for x in rows) / n,
                     sum(x[2] for x in rows) / n, sum(x[3] for x in rows) / n,
                     sum(x[4] for x in rows) / n, rows[-1][0])


class ConsistencyNoise:
    """Variance of the aid's innovation (wheel/INS consistency: vibration, encoder
    quantisation, pitching): a running mean over ``_NOISE_MEMORY_S`` of wheel time, not of
    samples, so the memory is the same at any wheel rate."""

    def __init__(self) -> None:
        self.var_mps2 = 0.0
        self._t_ns: int | None = None

    def add(self, t_ns: int, innovation_mps: float) -> None:
        dt_s = (t_ns - self._t_ns) * 1e-9 if self._t_ns is not None else 0.0
        self._t_ns = t_ns
        if not 0.0 < dt_s <= _NOISE_STEP_MAX_S:
            dt_s = _NOISE_STEP_MAX_S
        self.var_mps2 += (dt_s / _NOISE_MEMORY_S if self.var_mps2 else 1.0) * (
            innovation_mps ** 2 - self.var_mps2)
