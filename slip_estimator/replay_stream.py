"""The replay's streaming run and its result.

The ordered input streams through in chunks of ``CHUNK_MESSAGES``: read (read the serialized
messages, decode the IMU's in one batch per chunk, reorder: :mod:`slip_estimator.replay_inputs`),
estimation (the adapter: wheel decoding, core, output messages, NaN guard), write (serialize,
write, close); three timers split the wall time into these phases at no per-message cost. Every
published message is written with log time = the header stamp of the input that produced it.
"""
from __future__ import annotations

import sys
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import islice

from slip_estimator.bagio import BagWriter
from slip_estimator.replay_inputs import CHUNK_MESSAGES, Item
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.data_time import RESET_JUMP_BACK_S
from slip_estimator.ros.topics import TOPIC_IMU

PROGRESS_EVERY_S = 2.0
"""Wall-time interval of the progress line on stderr."""


@dataclass
class ReplaySummary:
    """Result of :func:`slip_estimator.replay.replay_bag`."""

    messages_in: int
    messages_out: int
    inputs: dict[str, int] = field(default_factory=dict)
    outputs: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    dropped_non_finite: dict[str, int] = field(default_factory=dict)
    resets: int = 0
    """Estimator resets by the adapter (sensor clock jumps back)."""
    data_duration_s: float = 0.0
    wall_time_s: float = 0.0
    read_s: float = 0.0
    """Bag read: read + decode the IMU + reorder, s."""
    estimation_s: float = 0.0
    """Estimation: the adapter (conversion, core, output messages, NaN guard), s."""
    write_s: float = 0.0
    """Bag write: serialize + write + close, s."""

    @property
    def realtime_ratio(self) -> float:
        """Data duration over wall time (> 1: faster than real time)."""
        return _ratio(self.data_duration_s, self.wall_time_s)

    @property
    def estimation_realtime_ratio(self) -> float:
        """Data duration over the estimation time."""
        return _ratio(self.data_duration_s, self.estimation_s)

    def line(self) -> str:
        """One-line human summary."""
        rejected = sum(self.rejected.values())
        resets = f', {self.resets} estimator reset(s) on clock jumps' if self.resets else ''
        return (f'replay: {self.messages_in} messages in ({rejected} rejected{resets}), '
                f'{self.messages_out} out, {self.data_duration_s:.1f} s of data in '
                f'{self.wall_time_s:.2f} s wall ({self.realtime_ratio:.1f}x real time): '
                f'bag read {self.read_s:.2f} s, estimation {self.estimation_s:.2f} s '
                f'({self.estimation_realtime_ratio:.1f}x real time), bag write '
                f'{self.write_s:.2f} s')


def _ratio(data_s: float, wall_s: float) -> float:
    return data_s / wall_s if wall_s > 0 else float('inf')


class ReplayRun:
    """The chunked read / estimate / write loop of a replay and its counters."""

    def __init__(self, adapter: SlipEstimatorAdapter, progress: bool) -> None:
        self.adapter, self.progress = adapter, progress
        self.inputs: Counter[str] = Counter()
        self.outputs: Counter[str] = Counter()
        self.n_in = 0
        self.read_s = self.estimation_s = self.write_s = 0.0
        self._stamp_min: int | None = None
        self._stamp_max: int | None = None
        self._closed_s = 0.0

    def stream(self, ordered: Iterator[Item], writer: BagWriter, setup_s: float) -> None:
        """Hand ``ordered`` to the adapter chunk by chunk and write what it publishes to
        ``writer``; ``setup_s`` (opening the bag) counts as reading."""
        clock = time.perf_counter
        on_imu, on_raw = self.adapter.on_imu_sample, self.adapter.on_raw
        self.read_s = setup_s
        next_progress = clock() + PROGRESS_EVERY_S
        while True:
            t_read = clock()
            chunk = list(islice(ordered, CHUNK_MESSAGES))
            t_est = clock()
            self.read_s += t_est - t_read
            if not chunk:
                return
            produced = []
            for stamp_ns, topic, payload in chunk:
                out = on_imu(payload) if topic == TOPIC_IMU else on_raw(topic, payload)
                if out:
                    produced.append((stamp_ns, out))
            t_write = clock()
            self.estimation_s += t_write - t_est
            for stamp_ns, out in produced:
                for topic, msg in out:
                    writer.write(topic, msg, stamp_ns)
                    self.outputs[topic] += 1
            self.write_s += clock() - t_write
            self._count(chunk)
            if self.progress and clock() > next_progress:
                next_progress += PROGRESS_EVERY_S
                print(f'replay: {self.n_in} messages', file=sys.stderr, flush=True)

    def _count(self, chunk: list[Item]) -> None:
        """Count the chunk; the data duration adds up the stamp spans between clock jumps."""
        self.n_in += len(chunk)
        self.inputs.update(topic for _, topic, _ in chunk)
        jump_ns = RESET_JUMP_BACK_S * 1e9
        lo, hi = self._stamp_min, self._stamp_max
        for stamp_ns, _, _ in chunk:
            if stamp_ns <= 0:
                continue
            if lo is None or hi is None:
                lo = hi = stamp_ns
            elif stamp_ns < hi - jump_ns:
                self._closed_s += (hi - lo) * 1e-9
                lo = hi = stamp_ns
            else:
                lo, hi = min(lo, stamp_ns), max(hi, stamp_ns)
        self._stamp_min, self._stamp_max = lo, hi

    def summary(self, wall_time_s: float) -> ReplaySummary:
        """What the run did (the adapter's rejections, drops and resets included)."""
        counters = self.adapter.counters
        return ReplaySummary(
            messages_in=self.n_in, messages_out=sum(self.outputs.values()),
            inputs=dict(self.inputs), outputs=dict(self.outputs),
            rejected={f'{t} {r}': c for (t, r), c in sorted(counters.rejected.items())},
            dropped_non_finite=dict(counters.dropped_non_finite), resets=counters.resets,
            data_duration_s=self.data_duration_s(), wall_time_s=wall_time_s,
            read_s=self.read_s, estimation_s=self.estimation_s, write_s=self.write_s)

    def data_duration_s(self) -> float:
        if self._stamp_min is None or self._stamp_max is None:
            return self._closed_s
        return self._closed_s + (self._stamp_max - self._stamp_min) * 1e-9
