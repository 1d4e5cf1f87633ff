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
"""
from __future__ import annotations

import argparse
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

    @property
    def realtime_ratio(self) -> float:
        """Data duration over wall time (> 1: faster than real time)."""
        return self.data_duration_s / self.wall_time_s if self.wall_time_s > 0 else float('inf')

    def line(self) -> str:
        """One-line human summary."""
        rejected = sum(self.rejected.values())
        return (f'replay: {self.messages_in} messages in ({rejected} rejected), '
                f'{self.messages_out} out, {self.data_duration_s:.1f} s of data in '
                f'{self.wall_time_s:.2f} s wall ({self.realtime_ratio:.1f}x real time)')


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
    t0 = time.perf_counter()
    adapter = (SlipEstimatorAdapter(params) if estimator_factory is None
               else SlipEstimatorAdapter(params, estimator_factory))
    topics = set(adapter.input_types)
    items = []
    for index, m in enumerate(read_messages(input_bag, topics)):
        items.append(((header_stamp_ns(m.msg), m.log_time_ns, _rank(m.topic), index), m))
    items.sort(key=lambda item: item[0])

    inputs: Counter[str] = Counter()
    outputs: Counter[str] = Counter()
    stamps = [key[0] for key, _ in items if key[0] != 0]
    next_progress = t0 + PROGRESS_EVERY_S
    with BagWriter(output_bag) as writer:
        for n, ((stamp_ns, _, _, _), m) in enumerate(items):
            inputs[m.topic] += 1
            for topic, msg in adapter.on_message(m.topic, m.msg):
                writer.write(topic, msg, stamp_ns)
                outputs[topic] += 1
            if progress and time.perf_counter() > next_progress:
                next_progress += PROGRESS_EVERY_S
                print(f'replay: {n + 1}/{len(items)} messages', file=sys.stderr, flush=True)
    return ReplaySummary(
        messages_in=len(items), messages_out=sum(outputs.values()), inputs=dict(inputs),
        outputs=dict(outputs),
        rejected={f'{t} {r}': c for (t, r), c in sorted(adapter.rejected.items())},
        dropped_non_finite=dict(adapter.dropped_non_finite),
        data_duration_s=(max(stamps) - min(stamps)) * 1e-9 if stamps else 0.0,
        wall_time_s=time.perf_counter() - t0)


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
