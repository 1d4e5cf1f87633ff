"""The ``/diagnostics`` report of the adapter: the core's health with the node's counters, the
input rates over the last period of data time, what was rejected or dropped since the last
report (at least WARN then) and why the estimator was reset since (at least WARN)."""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterable

from diagnostic_msgs.msg import DiagnosticArray

from slip_estimator.core.types import Health
from slip_estimator.ros import publish
from slip_estimator.ros.counters import NodeCounters


class HealthReport:
    """Builds each report; remembers what the last one said (since the estimator's start) and
    the resets not yet reported."""

    __slots__ = ('_notes', '_last_ns', '_received', '_rejected', '_dropped')

    def __init__(self) -> None:
        self._notes: list[str] = []
        self.restart()

    def restart(self, note: str | None = None) -> None:
        """The estimator (re)started: rates and counts 'since the last report' start again;
        ``note`` (why) goes into the next report."""
        self._last_ns: int | None = None
        self._received: Counter[str] = Counter()
        self._rejected = 0
        self._dropped = 0
        if note is not None:
            self._notes.append(note)

    def message(self, stamp_ns: int, health: Health, counters: NodeCounters,
                input_topics: Iterable[str], frame_id: str,
                parameter_change_pending: bool) -> DiagnosticArray:
        """The report at ``stamp_ns`` (data time)."""
        input_topics = list(input_topics)
        values = counters.values(input_topics, parameter_change_pending)
        if self._last_ns is not None and stamp_ns > self._last_ns:
            window_s = (stamp_ns - self._last_ns) * 1e-9
            for topic in input_topics:
                n = counters.received[topic] - self._received[topic]
                values[f'{topic} rate_hz'] = n / window_s
        level, message = health.level, health.message
        rejected = sum(counters.rejected.values())
        dropped = sum(counters.dropped_non_finite.values())
        new_rejects, new_drops = rejected - self._rejected, dropped - self._dropped
        if new_rejects or new_drops:
            level = max(level, 1)
            message = (f'{message}; {new_rejects} input message(s) rejected, {new_drops} '
                       f'non-finite output(s) dropped since the last report')
        if self._notes:
            level = max(level, 1)
            message = '; '.join([message, *self._notes])
            self._notes = []
        self._last_ns = stamp_ns
        self._received = Counter(counters.received)
        self._rejected, self._dropped = rejected, dropped
        return publish.health_to_diagnostic_array(
            Health(level=level, message=message, values=health.values), stamp_ns, frame_id,
            values)
