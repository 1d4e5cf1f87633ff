"""Bag replay: run the node's logic over a recorded rosbag2 bag, write the outputs to MCAP.

``slip-estimator replay INPUT_BAG [--params-file FILE.yaml] --output OUTPUT_BAG``

The input messages (IMU and the wheel topic selected by ``wheel_input``) are fed to the same
:class:`~slip_estimator.ros.adapter.SlipEstimatorAdapter` as the live node uses, in header-stamp
order: a stable sort on (header stamp, log time, topic rank, position in the bag), where the
IMU ranks before the wheels so that at equal stamps the INS has reached a wheel sample's time
when the wheel sample comes (its slip is then evaluated at once, as the live node would once
both arrived). Every published message is written with log time = the header stamp of the
input message that produced it. Nothing depends on wall time, so two replays give identical
message streams.

The whole input is held in memory for the sort (a few hundred MB per hour of 250 Hz IMU).
The sorted messages are then processed in chunks of ``CHUNK_MESSAGES``: estimation (the
adapter: conversion, core, output messages, NaN guard) over a chunk, then writing its outputs,
so that three timers around the phases split the wall time into bag read (read, deserialize,
sort), estimation and bag write (serialize, write, close) at no per-message cost.
"""
from __future__ import annotations

import argparse
import gc
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from slip_estimator.bagio import BagWriter, read_messages
from slip_estimator.core.params import ParameterError, Params
from slip_estimator.paramfile import load_params
from slip_estimator.ros.adapter import (
    TOPIC_IMU,
    EstimatorFactory,
    SlipEstimatorAdapter,
)
from slip_estimator.ros.convert import header_stamp_ns

PROGRESS_EVERY_S = 2.0
"""Wall-time interval of the progress line on stderr."""
CHUNK_MESSAGES = 2000
"""Input messages per estimation phase (their outputs are held until the chunk is written)."""


@dataclass
class ReplaySummary:
    """Result of :func:`replay_bag`."""

    messages_in: int
    messages_out: int
    inputs: dict[str, int] = field(default_factory=dict)
    outputs: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    dropped_non_finite: dict[str, int] = field(default_factory=dict)
    data_duration_s: float = 0.0
    wall_time_s: float = 0.0
    read_s: float = 0.0
    """Bag read: read + deserialize + header-stamp sort, s."""
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
        return (f'replay: {self.messages_in} messages in ({rejected} rejected), '
                f'{self.messages_out} out, {self.data_duration_s:.1f} s of data in '
                f'{self.wall_time_s:.2f} s wall ({self.realtime_ratio:.1f}x real time): '
                f'bag read {self.read_s:.2f} s, estimation {self.estimation_s:.2f} s '
                f'({self.estimation_realtime_ratio:.1f}x real time), bag write '
                f'{self.write_s:.2f} s')


def _ratio(data_s: float, wall_s: float) -> float:
    return data_s / wall_s if wall_s > 0 else float('inf')


def _rank(topic: str) -> int:
    return 0 if topic == TOPIC_IMU else 1


def replay_bag(input_bag: str | Path, params: Params, output_bag: str | Path, *,
               progress: bool = False,
               estimator_factory: EstimatorFactory | None = None) -> ReplaySummary:
    """Replay ``input_bag`` through the adapter and write the outputs to ``output_bag`` (MCAP).

    Parameters
    ----------
    input_bag : rosbag2 bag (directory, .mcap or .db3).
    params : estimator and node parameters.
    output_bag : new bag directory (must not exist).
    progress : print a progress line on stderr every ``PROGRESS_EVERY_S`` of wall time.
    estimator_factory : substitute core (tests); the real SlipEstimator by default.
    """
    clock = time.perf_counter
    t0 = clock()
    adapter = (SlipEstimatorAdapter(params) if estimator_factory is None
               else SlipEstimatorAdapter(params, estimator_factory))
    topics = set(adapter.input_types)
    items = []
    # The input (hundreds of thousands of objects, no reference cycles) lives until the end:
    # the cyclic garbage collector is kept from scanning it while it grows and afterwards.
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        for index, m in enumerate(read_messages(input_bag, topics)):
            items.append(((header_stamp_ns(m.msg), m.log_time_ns, _rank(m.topic), index), m))
        items.sort(key=lambda item: item[0])
        gc.freeze()
    finally:
        if gc_was_enabled:
            gc.enable()
    try:
        inputs: Counter[str] = Counter(m.topic for _, m in items)
        stamps = [key[0] for key, _ in items if key[0] != 0]
        read_s = clock() - t0
        outputs, estimation_s, t_write = _estimate_and_write(items, adapter, output_bag,
                                                             progress, t0 + PROGRESS_EVERY_S)
    finally:
        gc.unfreeze()
    t1 = clock()
    return ReplaySummary(
        messages_in=len(items), messages_out=sum(outputs.values()), inputs=dict(inputs),
        outputs=dict(outputs),
        rejected={f'{t} {r}': c for (t, r), c in sorted(adapter.rejected.items())},
        dropped_non_finite=dict(adapter.dropped_non_finite),
        data_duration_s=(max(stamps) - min(stamps)) * 1e-9 if stamps else 0.0,
        wall_time_s=t1 - t0, read_s=read_s, estimation_s=estimation_s,
        write_s=(t1 - t_write) - estimation_s)


def _estimate_and_write(items: list, adapter: SlipEstimatorAdapter, output_bag: str | Path,
                        progress: bool, next_progress: float
                        ) -> tuple[Counter[str], float, float]:
    """The estimation and write phases of :func:`replay_bag`, chunk by chunk: the output
    counts, the estimation time and the clock at the start of the phases."""
    clock = time.perf_counter
    outputs: Counter[str] = Counter()
    estimation_s = 0.0
    on_message = adapter.on_message
    t_write = clock()
    with BagWriter(output_bag) as writer:
        for start in range(0, len(items), CHUNK_MESSAGES):
            t_est = clock()
            produced = []
            for (stamp_ns, _, _, _), m in items[start:start + CHUNK_MESSAGES]:
                out = on_message(m.topic, m.msg)
                if out:
                    produced.append((stamp_ns, out))
            estimation_s += clock() - t_est
            for stamp_ns, out in produced:
                for topic, msg in out:
                    writer.write(topic, msg, stamp_ns)
                    outputs[topic] += 1
            if progress and clock() > next_progress:
                next_progress += PROGRESS_EVERY_S
                done = min(start + CHUNK_MESSAGES, len(items))
                print(f'replay: {done}/{len(items)} messages', file=sys.stderr, flush=True)
    return outputs, estimation_s, t_write


def replay_main(argv: list[str] | None = None) -> int:
    """``slip-estimator replay`` (argv without the subcommand). Returns the exit status."""
    parser = argparse.ArgumentParser(
        prog='slip-estimator replay',
        description='Run the slip estimator over a rosbag2 bag and write its outputs to MCAP.')
    parser.add_argument('input_bag', type=Path, help='input rosbag2 bag (MCAP or sqlite3)')
    parser.add_argument('--params-file', type=Path,
                        help='ROS 2 parameter file (default: built-in defaults)')
    parser.add_argument('--output', '-o', type=Path, required=True,
                        help='output bag directory (MCAP; must not exist)')
    args = parser.parse_args(argv)
    try:
        params = load_params(args.params_file) if args.params_file else Params()
    except (ParameterError, OSError) as exc:
        print(f'slip-estimator replay: {exc}', file=sys.stderr)
        return 2
    if args.output.exists():
        print(f'slip-estimator replay: output {args.output} exists', file=sys.stderr)
        return 2
    summary = replay_bag(args.input_bag, params, args.output, progress=True)
    print(summary.line())
    return 0


if __name__ == '__main__':
    sys.exit(replay_main())
