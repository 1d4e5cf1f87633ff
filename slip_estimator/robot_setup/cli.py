"""``slip-estimator setup BAG [--declared FILE] [--out my_robot.yaml]``."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog='slip-estimator setup',
        description='Measure a robot on one of its bags (rosbag2 MCAP/sqlite3 or ROS 1 .bag: '
                    'topics, IMU gravity/units/mounting, noise at rest, wheel lag, effective '
                    'track, wheel radius ratio, GNSS start) and write a commented params file '
                    'that replay and the node read as it is.',
        epilog='example: slip-estimator setup my_robot.bag --declared geometry.yaml '
               '--out my_robot.yaml')
    ap.add_argument('bag', type=Path, help='rosbag2 folder, .mcap, .db3 or ROS 1 .bag; best '
                    'with 10 s at rest, turns both ways and straight runs')
    ap.add_argument('--declared', type=Path, help='params file with what you know (wheel '
                    'radius, track, joint names, mounting); measured values replace only '
                    'what it does not set (and the mounting, when measured)')
    ap.add_argument('--out', type=Path, default=Path('my_robot.yaml'),
                    help='params file to write (default: %(default)s)')
    return ap


def setup_main(argv: list[str] | None = None) -> int:
    """Run ``slip-estimator setup``; 0, or 2 with one line on stderr for bad input."""
    args = _parser().parse_args(argv)
    from slip_estimator.bagio import BagError
    from slip_estimator.core.params import ParameterError, Params
    from slip_estimator.paramfile import load_params, read_param_values
    from slip_estimator.robot_setup.decide import propose
    from slip_estimator.robot_setup.measure import measure
    from slip_estimator.robot_setup.render import params_text, report_text
    from slip_estimator.robot_setup.scan import SetupError, scan_bag

    try:
        declared, keys = Params(), set()
        if args.declared:
            declared = load_params(args.declared)
            keys = set(read_param_values(args.declared))
        scan = scan_bag(args.bag, declared, keys)
        measured = measure(scan.imu, scan.wheels, scan.gnss, declared.track_width)
        proposal = propose(declared, keys, scan, measured)
        args.out.write_text(params_text(proposal, str(args.bag)))
    except (ParameterError, BagError, SetupError, OSError) as exc:
        print(f'slip-estimator setup: {exc}', file=sys.stderr)
        return 2
    print(report_text(str(args.bag), scan, measured, proposal, str(args.out), declared))
    return 0
