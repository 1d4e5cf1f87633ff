"""The replay's inputs: which bag topics feed which input (``-r FROM:=TO`` and the topic
parameters), what a bag lacks, and the order the messages reach the adapter.

The messages go in ARRIVAL order (the bag's log time) through a reorder window of
``reorder_window_s`` of header stamps (:class:`ReorderWindow`): within the window the messages
go out in header-stamp order, the IMU before the wheels at equal stamps (the INS has then
reached a wheel sample's time when the wheel sample comes, as the live node once both arrived);
a message later than the window is passed on late, as the node would receive it. A sensor clock
that jumps back by more than ``RESET_JUMP_BACK_S`` (a reset or a loop) flushes the window, so
the adapter sees the jump as the live node does. The IMU is decoded ``CHUNK_MESSAGES`` at a time
into :class:`~slip_estimator.core.types.ImuSample` records (:mod:`slip_estimator.ros.cdr`, no
message objects); the wheel messages stay serialized for the adapter.
"""
from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator
from itertools import islice
from typing import Any

from slip_estimator.ros import cdr
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.data_time import RESET_JUMP_BACK_S
from slip_estimator.ros.topics import TOPIC_IMU

CHUNK_MESSAGES = 2000
"""Input messages decoded at once and handled per estimation phase (their outputs are held
until the chunk is written)."""
REORDER_WINDOW_S = 0.5
"""Default reorder window of header stamps, s."""


def _rank(topic: str) -> int:
    return 0 if topic == TOPIC_IMU else 1


Item = tuple[int, str, Any]
"""(header stamp ns, input topic, payload): an IMU payload is an ImuSample or the reason it was
rejected, a wheel payload the serialized message."""


class ReorderWindow:
    """Arrival order, put right by header stamp within ``window_s``.

    A message is held until the newest stamp seen is ``window_s`` past its own; held messages
    leave in (stamp, IMU first, arrival) order. A stamp more than ``jump_back_s`` behind the
    newest flushes everything held first (a clock reset: what came before it goes first).
    Zero stamps (invalid, rejected by the adapter) pass at once.
    """

    def __init__(self, window_s: float = REORDER_WINDOW_S,
                 jump_back_s: float = RESET_JUMP_BACK_S) -> None:
        self._window_ns = round(window_s * 1e9)
        self._jump_ns = round(jump_back_s * 1e9)
        self._heap: list[tuple[int, int, int, Item]] = []
        self._newest_ns: int | None = None
        self._arrivals = 0

    def order(self, items: Iterable[Item]) -> Iterator[Item]:
        """The items (in arrival order) in replay order."""
        heap = self._heap
        for item in items:
            stamp_ns = item[0]
            self._arrivals += 1
            if stamp_ns <= 0:
                yield item
                continue
            newest = self._newest_ns
            if newest is not None and newest - stamp_ns > self._jump_ns:
                yield from self._flush()
                newest = None
            if newest is None or stamp_ns > newest:
                self._newest_ns = newest = stamp_ns
            heapq.heappush(heap, (stamp_ns, _rank(item[1]), self._arrivals, item))
            limit = newest - self._window_ns
            while heap and heap[0][0] <= limit:
                yield heapq.heappop(heap)[3]
        yield from self._flush()

    def _flush(self) -> Iterator[Item]:
        while self._heap:
            yield heapq.heappop(self._heap)[3]
        self._newest_ns = None


def decoded_inputs(adapter: SlipEstimatorAdapter, raw: Iterable[tuple[str, bytes]]
                   ) -> Iterator[Item]:
    """(topic, serialized message) in arrival order -> :data:`Item` in the same order: the IMU
    decoded into samples ``CHUNK_MESSAGES`` at a time (:meth:`SlipEstimatorAdapter.imu_samples`),
    the wheel messages' stamps read (0 for one that does not decode: the adapter rejects it)."""
    raw = iter(raw)
    while chunk := list(islice(raw, CHUNK_MESSAGES)):
        imu = iter(adapter.imu_samples([r for topic, r in chunk if topic == TOPIC_IMU]))
        for topic, r in chunk:
            if topic == TOPIC_IMU:
                stamp_ns, sample = next(imu)
                yield stamp_ns, topic, sample
            else:
                try:
                    yield cdr.stamp_ns(r), topic, r
                except cdr.CdrError:
                    yield 0, topic, r


def parse_remap(text: str) -> tuple[str, str]:
    """``FROM:=TO`` (ROS remapping syntax) -> (``/FROM``, ``/TO``)."""
    src, sep, dst = text.partition(':=')
    if not sep or not src.strip() or not dst.strip():
        raise ValueError(f'remapping {text!r} is not FROM:=TO')
    return '/' + src.strip().lstrip('/'), '/' + dst.strip().lstrip('/')


def input_sources(expected: Iterable[str], remap: dict[str, str]) -> dict[str, str]:
    """Bag topic to read for each expected input topic (``remap`` maps bag topic -> input)."""
    source = {topic: topic for topic in expected}
    for src, dst in remap.items():
        if dst in source:
            source[dst] = src
    return source


def with_params_remap(adapter: SlipEstimatorAdapter, remap: dict[str, str]) -> dict[str, str]:
    """``remap`` (bag topic -> input topic) completed by the topic parameters
    (``imu_topic``, ...) for the inputs it does not map (a ``-r`` remap wins)."""
    given = set(remap.values())
    return {**{src: dst for dst, src in adapter.input_sources.items()
               if src != dst and dst not in given}, **remap}


def missing_inputs(adapter: SlipEstimatorAdapter, topics: dict[str, str],
                   remap: dict[str, str]) -> list[str]:
    """Descriptions of the expected inputs the bag (``topics``: name -> type) does not have."""
    from slip_estimator.bagio import message_type_name

    missing = []
    for expected, src in input_sources(adapter.input_types, remap).items():
        want = message_type_name(adapter.input_types[expected])
        named = expected if src == expected else f'{expected} (from {src})'
        if src not in topics:
            missing.append(f'{named} [{want}]')
        elif topics[src] != want:
            missing.append(f'{named} [{want}; the bag has {topics[src]}]')
    return missing


def describe_inputs(adapter: SlipEstimatorAdapter, topics: dict[str, str],
                    missing: list[str]) -> str:
    """One line: what is missing, what the parameters expect, what the bag has."""
    have = ', '.join(f'{t} [{ty}]' for t, ty in sorted(topics.items())) or 'no topics'
    return (f'missing input {"; ".join(missing)} (wheel_input: {adapter.params.wheel_input}); '
            f'the bag has: {have}; map a topic with -r FROM:=TO or set wheel_input')
