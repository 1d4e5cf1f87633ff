"""Bag replay: run the node's logic over a recorded bag, write the outputs to MCAP.

``slip-estimator replay INPUT_BAG [--params-file FILE.yaml] [-r FROM:=TO ...] --output OUT``

The input messages (IMU and the wheel topic selected by ``wheel_input``; other topic names
mapped onto them with ``-r FROM:=TO`` as the live node's ``--ros-args -r``) are fed to the same
:class:`~slip_estimator.ros.adapter.SlipEstimatorAdapter` as the live node uses, in ARRIVAL
order (the bag's log time) through a reorder window of ``reorder_window_s`` of header stamps
(:class:`ReorderWindow`): within the window the messages go out in header-stamp order, the IMU
before the wheels at equal stamps (the INS has then reached a wheel sample's time when the wheel
sample comes, as the live node once both arrived); a message later than the window is passed on
late, as the node would receive it. A sensor clock that jumps back by more than
``RESET_JUMP_BACK_S`` (a reset or a loop) flushes the window, so the adapter sees the jump as
the live node does: named in ``/diagnostics``, the estimator reset, output resuming. Every
published message is written with log time = the header stamp of the input that produced it.
Nothing depends on wall time, so two replays give identical message streams.

The input streams through in chunks of ``CHUNK_MESSAGES``: read (read the serialized messages,
decode the IMU's in one batch per chunk with :mod:`slip_estimator.ros.cdr`, reorder), estimation
(the adapter: wheel decoding, core, output messages, NaN guard), write (serialize, write,
close); three timers split the wall time into these phases at no per-message cost. No Python
message object is built for an input: the IMU bytes become :class:`ImuSample` records in
numpy, as :func:`slip_estimator.ros.convert.imu_from_msg` would make them from messages.
"""
from __future__ import annotations

import argparse
import gc
import heapq
import sys
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from itertools import islice
from pathlib import Path
from typing import Any

from slip_estimator.bagio import BagError, BagWriter, bag_topics, read_raw
from slip_estimator.core.params import ParameterError, Params
from slip_estimator.paramfile import load_params
from slip_estimator.ros import cdr
from slip_estimator.ros.adapter import EstimatorFactory, SlipEstimatorAdapter
from slip_estimator.ros.data_time import RESET_JUMP_BACK_S
from slip_estimator.ros.topics import TOPIC_IMU, TOPIC_SLIP_RATIO

PROGRESS_EVERY_S = 2.0
"""Wall-time interval of the progress line on stderr."""
CHUNK_MESSAGES = 2000
"""Input messages per estimation phase (their outputs are held until the chunk is written)."""
REORDER_WINDOW_S = 0.5
"""Default reorder window of header stamps, s."""


@dataclass
class ReplaySummary:
    """Result of :func:`replay_bag`."""

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


def replay_bag(input_bag: str | Path, params: Params, output_bag: str | Path, *,
               progress: bool = False,
               estimator_factory: EstimatorFactory | None = None,
               remap: dict[str, str] | None = None,
               reorder_window_s: float = REORDER_WINDOW_S) -> ReplaySummary:
    """Replay ``input_bag`` through the adapter and write the outputs to ``output_bag`` (MCAP).

    Parameters
    ----------
    input_bag : rosbag2 bag (directory, .mcap or .db3) or ROS 1 .bag.
    params : estimator and node parameters.
    output_bag : new bag directory (must not exist).
    progress : print a progress line on stderr every ``PROGRESS_EVERY_S`` of wall time.
    estimator_factory : substitute core (tests); the real SlipEstimator by default.
    remap : bag topic -> input topic (``-r FROM:=TO``).
    reorder_window_s : header-stamp reorder window (see :class:`ReorderWindow`).
    """
    clock = time.perf_counter
    t0 = clock()
    adapter = (SlipEstimatorAdapter(params) if estimator_factory is None
               else SlipEstimatorAdapter(params, estimator_factory))
    remap = with_params_remap(adapter, remap or {})
    rename = {src: dst for dst, src in input_sources(adapter.input_types, remap).items()}
    raw = ((rename[topic], r) for topic, _, _, r in read_raw(input_bag, set(rename)))
    ordered = ReorderWindow(reorder_window_s).order(decoded_inputs(adapter, raw))
    # The records have no reference cycles: the cyclic garbage collector is kept off.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        run = _Run(adapter, progress)
        with BagWriter(output_bag) as writer:
            run.stream(ordered, writer, clock() - t0)
            t_close = clock()
        run.write_s += clock() - t_close
    finally:
        if gc_was_enabled:
            gc.enable()
    return ReplaySummary(
        messages_in=run.n_in, messages_out=sum(run.outputs.values()), inputs=dict(run.inputs),
        outputs=dict(run.outputs),
        rejected={f'{t} {r}': c for (t, r), c in sorted(adapter.counters.rejected.items())},
        dropped_non_finite=dict(adapter.counters.dropped_non_finite), resets=adapter.counters.resets,
        data_duration_s=run.data_duration_s(), wall_time_s=clock() - t0, read_s=run.read_s,
        estimation_s=run.estimation_s, write_s=run.write_s)


class _Run:
    """The chunked read / estimate / write loop of :func:`replay_bag` and its counters."""

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

    def data_duration_s(self) -> float:
        if self._stamp_min is None or self._stamp_max is None:
            return self._closed_s
        return self._closed_s + (self._stamp_max - self._stamp_min) * 1e-9


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='slip-estimator replay',
        description='Run the slip estimator over a bag (rosbag2 MCAP/sqlite3 or ROS 1 .bag) '
                    'and write its outputs to MCAP.',
        epilog='example: slip-estimator replay my_robot.bag --params-file my_robot.yaml '
               '-o estimate')
    parser.add_argument('input_bag', type=Path,
                        help='input bag: rosbag2 folder, .mcap, .db3 or ROS 1 .bag')
    parser.add_argument('--params-file', type=Path,
                        help='ROS 2 parameter file (default: built-in defaults)')
    parser.add_argument('--output', '-o', type=Path, required=True,
                        help='output bag directory (MCAP; must not exist)')
    parser.add_argument('-r', '--remap', action='append', default=[], metavar='FROM:=TO',
                        help='read bag topic FROM as input topic TO, e.g. -r '
                             '/imu/data_raw:=/imu/data (repeatable; as --ros-args -r)')
    parser.add_argument('--reorder-window', type=float, default=REORDER_WINDOW_S,
                        metavar='S', help='header-stamp reorder window over the arrival order, '
                                          's (default: %(default)s)')
    return parser


def replay_main(argv: list[str] | None = None) -> int:
    """``slip-estimator replay`` (argv without the subcommand). Returns the exit status:
    0, 1 when no slip could be estimated, 2 for bad input (one line on stderr)."""
    args = _parser().parse_args(argv)
    try:
        params = load_params(args.params_file) if args.params_file else Params()
        remap = dict(parse_remap(r) for r in args.remap)
        if args.reorder_window < 0.0:
            raise ValueError('--reorder-window must be >= 0')
        if args.output.exists():
            raise ValueError(f'output {args.output} exists')
        topics = bag_topics(args.input_bag)
        adapter = SlipEstimatorAdapter(params)
        remap = with_params_remap(adapter, remap)
        missing = missing_inputs(adapter, topics, remap)
        if len(missing) == len(adapter.input_types):
            raise ValueError(f'{args.input_bag}: ' + describe_inputs(adapter, topics, missing))
        if missing:
            print(f'slip-estimator replay: warning: {args.input_bag}: '
                  + describe_inputs(adapter, topics, missing), file=sys.stderr)
        summary = replay_bag(args.input_bag, params, args.output, progress=True, remap=remap,
                             reorder_window_s=args.reorder_window)
    except (ParameterError, BagError, ValueError) as exc:
        print(f'slip-estimator replay: {exc}', file=sys.stderr)
        return 2
    print(summary.line())
    if not summary.outputs.get(TOPIC_SLIP_RATIO):
        why = describe_inputs(adapter, topics, missing) if missing else (
            'see /diagnostics in the output bag')
        print(f'slip-estimator replay: no slip could be estimated from {args.input_bag}: {why}',
              file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(replay_main())
