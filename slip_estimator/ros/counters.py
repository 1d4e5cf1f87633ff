"""What the node counts (messages received, rejected per reason, published, dropped as
non-finite, callback exceptions, resets, clock jumps, IMU stamp gaps) and the last check before
publishing: no message with NaN/Inf goes out (:func:`slip_estimator.ros.finite.message_is_finite`).
The counts are kept across estimator resets; ``/diagnostics`` carries them
(:meth:`NodeCounters.values`)."""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from slip_estimator.ros import finite
from slip_estimator.ros.topics import OUTPUT_TYPES, Output


@dataclass(slots=True)
class NodeCounters:
    """The node's counters (see the module docstring)."""

    received: Counter[str] = field(default_factory=Counter)
    """Input messages by input topic."""
    rejected: Counter[tuple[str, str]] = field(default_factory=Counter)
    """Input messages rejected, by (input topic, reason)."""
    published: Counter[str] = field(default_factory=Counter)
    """Output messages by output topic."""
    dropped_non_finite: Counter[str] = field(default_factory=Counter)
    """Output messages dropped for a NaN/Inf, by output topic."""
    callback_exceptions: Counter[str] = field(default_factory=Counter)
    """Exceptions a caller caught while handling a message, by topic."""
    resets: int = 0
    """Estimator resets by the adapter (clock jumps back, requests)."""
    clock_jumps_back: int = 0
    imu_stamp_gaps: int = 0

    def pass_finite(self, out: list[Output]) -> list[Output]:
        """Drop (and count) messages with NaN/Inf; count the rest as published."""
        kept = []
        for topic, msg in out:
            if finite.message_is_finite(msg):
                self.published[topic] += 1
                kept.append((topic, msg))
            else:
                self.dropped_non_finite[topic] += 1
        return kept

    def count_published(self, out: list[Output]) -> list[Output]:
        """Count ``out`` as published without the check (messages finite by construction)."""
        for topic, _ in out:
            self.published[topic] += 1
        return out

    def values(self, input_topics: Iterable[str], parameter_change_pending: bool
               ) -> dict[str, Any]:
        """The counters as flat diagnostic values."""
        values: dict[str, Any] = {}
        for topic in input_topics:
            values[f'{topic} received'] = self.received[topic]
        for (topic, reason), n in sorted(self.rejected.items()):
            values[f'{topic} rejected {reason}'] = n
        values['/imu/data stamp_gaps'] = self.imu_stamp_gaps
        for topic in OUTPUT_TYPES:
            values[f'{topic} published'] = self.published[topic]
        for topic, n in sorted(self.dropped_non_finite.items()):
            values[f'{topic} dropped_non_finite'] = n
        for topic, n in sorted(self.callback_exceptions.items()):
            values[f'{topic} callback_exceptions'] = n
        values['node_resets'] = self.resets  # 'resets' is the core's own counter
        values['clock_jumps_back'] = self.clock_jumps_back
        values['parameter_change_pending'] = parameter_change_pending
        return values
