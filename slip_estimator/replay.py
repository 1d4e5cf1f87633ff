"""Bag replay: run the node's logic over a recorded bag, write the outputs to MCAP.

``slip-estimator replay INPUT_BAG [--params-file FILE.yaml] [-r FROM:=TO ...] --output OUT``

The input messages (IMU and the wheel topic selected by ``wheel_input``; other topic names
mapped onto them with ``-r FROM:=TO`` as the live node's ``--ros-args -r``) are fed to the same
:class:`~slip_estimator.ros.adapter.SlipEstimatorAdapter` as the live node uses, in ARRIVAL
order (the bag's log time) put right by header stamp within a reorder window; a sensor clock
that jumps back is seen by the adapter as the live node sees it: named in ``/diagnostics``, the
estimator reset, output resuming. Every published message is written with log time = the
header stamp of the input that produced it. Nothing depends on wall time, so two replays give
identical message streams. No Python message object is built for an input: the IMU bytes
become :class:`~slip_estimator.core.types.ImuSample` records in numpy, as
:func:`slip_estimator.ros.convert.imu_from_msg` would make them from messages.

The parts: :mod:`slip_estimator.replay_inputs` (topic remapping, missing inputs, decoding,
the reorder window), :mod:`slip_estimator.replay_stream` (the chunked read / estimate / write
run, its timers and the :class:`~slip_estimator.replay_stream.ReplaySummary`); this module
joins them (:func:`replay_bag`) and is the CLI.
"""
from __future__ import annotations

import argparse
import gc
import sys
import time
from pathlib import Path

from slip_estimator.bagio import BagError, BagWriter, bag_topics, read_raw
from slip_estimator.core.params import ParameterError, Params
from slip_estimator.paramfile import load_params
from slip_estimator.replay_inputs import (
    REORDER_WINDOW_S,
    ReorderWindow,
    decoded_inputs,
    describe_inputs,
    input_sources,
    missing_inputs,
    parse_remap,
    with_params_remap,
)
from slip_estimator.replay_stream import ReplayRun, ReplaySummary
from slip_estimator.ros.adapter import EstimatorFactory, SlipEstimatorAdapter
from slip_estimator.ros.topics import TOPIC_SLIP_RATIO


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
    progress : print a progress line on stderr every
        :data:`~slip_estimator.replay_stream.PROGRESS_EVERY_S` of wall time.
    estimator_factory : substitute core (tests); the real SlipEstimator by default.
    remap : bag topic -> input topic (``-r FROM:=TO``).
    reorder_window_s : header-stamp reorder window (see
        :class:`~slip_estimator.replay_inputs.ReorderWindow`).
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
        run = ReplayRun(adapter, progress)
        with BagWriter(output_bag) as writer:
            run.stream(ordered, writer, clock() - t0)
            t_close = clock()
        run.write_s += clock() - t_close
    finally:
        if gc_was_enabled:
            gc.enable()
    return run.summary(clock() - t0)


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
