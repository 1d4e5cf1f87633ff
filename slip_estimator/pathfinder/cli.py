"""Command-line shell of ``slip-estimator import-pathfinder``: a Pathfinder .mat log to an MCAP
bag and a params file, printing what was verified."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from slip_estimator.report import first_line


def import_main(argv: list[str] | None = None) -> int:
    """Run ``slip-estimator import-pathfinder FILE.mat --output BAG [--params-out FILE]``."""
    ap = argparse.ArgumentParser(prog='slip-estimator import-pathfinder',
                                 description='Convert a WVU Pathfinder .mat log to an MCAP bag '
                                             'and a params file; prints what was verified.',
                                 epilog='example: slip-estimator import-pathfinder '
                                        '../shared/data/pathfinder/s5t1.mat --output s5t1 '
                                        '--params-out s5t1.yaml')
    ap.add_argument('mat', help='Pathfinder .mat file (MATLAB v7.3)')
    ap.add_argument('--output', required=True, help='output bag directory (must not exist)')
    ap.add_argument('--params-out', help='write a ROS 2 params file for this log')
    ap.add_argument('--heading', type=float, help='initial heading override, deg cw from north '
                                                  '(default: estimated from GNSS)')
    ap.add_argument('--measured-noise', action='store_true',
                    help='IMU noise densities measured at rest instead of the datasheet')
    ap.add_argument('--measured-lag', action='store_true',
                    help='wheel_latency_s = the wheel-stamp lag measured on the log (default 0)')
    args = ap.parse_args(argv)

    from slip_estimator import pathfinder as pf

    if Path(args.output).exists():
        print(f'slip-estimator import-pathfinder: {args.output} exists', file=sys.stderr)
        return 2
    if not Path(args.mat).is_file():
        print(f'slip-estimator import-pathfinder: {args.mat}: no such file', file=sys.stderr)
        return 2
    try:
        log, facts, params = pf.import_pathfinder(
            args.mat, args.output, args.params_out, measured_noise=args.measured_noise,
            measured_lag=args.measured_lag, heading_deg=args.heading, progress=True)
    except ImportError:
        print('slip-estimator import-pathfinder: needs h5py (pip install '
              '"slip_estimator[pathfinder]" or pip install h5py)', file=sys.stderr)
        return 2
    except (OSError, KeyError, ValueError) as exc:
        print(f'slip-estimator import-pathfinder: {args.mat}: not a Pathfinder .mat log '
              f'(MATLAB v7.3 / HDF5 with tTimu, Ax.., llhGPS): {first_line(exc)}',
              file=sys.stderr)
        return 2
    print(pf.format_facts(log, facts))
    print(f'wrote {args.output}')
    if args.params_out:
        print(f'params -> {args.params_out} (initial heading {params.initial_heading_deg:.2f} '
              'deg)')
        notes = pf.params_notes(facts, args.measured_noise, args.measured_lag)
        print('\n'.join('  ' + n for n in notes))
    return 0
