"""``slip-estimator bench``: parse arguments, run the chosen sections, print their tables and
write the JSON; ``--worker`` runs the subprocess side of the live and memory sections."""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from slip_estimator.bench import tables
from slip_estimator.bench.machine import machine_info

SECTIONS = ('core', 'replay', 'live', 'memory', 'scaling')
PATHFINDER_S5T1 = Path(__file__).resolve().parents[2] / '..' / 'shared' / 'data' / 'pathfinder' \
    / 's5t1.mat'


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(',') if x.strip()]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog='slip-estimator bench',
        description='Measure core throughput, replay speed, the live node over DDS, memory '
                    'and scaling on this machine.',
        epilog='example: slip-estimator bench --only core --json bench.json')
    ap.add_argument('--only', default=','.join(SECTIONS),
                    help='comma-separated sections to run (default: %(default)s)')
    ap.add_argument('--json', type=Path, help='also write every figure to this JSON file')
    ap.add_argument('--seed', type=int, default=0, help='simulator truth seed')
    ap.add_argument('--repeats', type=int, default=3, help='core: best of N runs')
    ap.add_argument('--core-scenario', choices=('short', 'default'), default='short')
    ap.add_argument('--core-duration-s', type=float, default=0.0,
                    help='core: cut the scenario (0 = whole scenario)')
    ap.add_argument('--replay-duration-s', type=float, default=1e9,
                    help='replay: simulated bag length, s (default: the whole default scenario)')
    ap.add_argument('--replay-repeats', type=int, default=3,
                    help='replay: best of N replays by estimation time')
    ap.add_argument('--pathfinder', default=str(PATHFINDER_S5T1),
                    help='replay: s5t1.mat (skipped when missing; "" to skip)')
    ap.add_argument('--live-duration-s', type=float, default=60.0,
                    help='live: publishing time, s')
    ap.add_argument('--live-discovery-timeout-s', type=float, default=30.0)
    ap.add_argument('--live-imu-rates', type=_floats, default=[250.0, 1000.0],
                    help='live: IMU rates to publish at, Hz (comma-separated; wheels 10 Hz)')
    ap.add_argument('--baseline', type=Path, default=None, metavar='DIR',
                    help='a source tree of the previous version (e.g. git worktree add DIR '
                         'REV, or git archive REV | tar -x -C DIR): its node (live) and its '
                         'whole replay process (replay) are measured right after this '
                         "tree's, side by side")
    ap.add_argument('--domain-id', type=int, default=None,
                    help='live: ROS_DOMAIN_ID (default: 100 + pid %% 100)')
    ap.add_argument('--memory-duration-s', type=float, default=3600.0,
                    help='memory: data length, s')
    ap.add_argument('--memory-sample-s', type=float, default=300.0,
                    help='memory: RSS sample interval in data time, s')
    ap.add_argument('--scaling-rates', type=_floats, default=[50, 100, 250, 500, 1000],
                    help='scaling: IMU rates, Hz (comma-separated)')
    ap.add_argument('--scaling-rate-duration-s', type=float, default=0.0,
                    help='scaling: cut the rate runs (0 = whole short scenario)')
    ap.add_argument('--scaling-lengths', type=_floats, default=[60, 180, 600],
                    help='scaling: log lengths, s (comma-separated)')
    ap.add_argument('--worker', choices=('live', 'memory'), help=argparse.SUPPRESS)
    ap.add_argument('--worker-out', help=argparse.SUPPRESS)
    return ap


def _runners() -> dict[str, tuple[Callable[[argparse.Namespace], dict[str, Any]],
                                   Callable[[dict[str, Any]], None]]]:
    """Section -> (run, print); the section modules are imported only when the bench runs."""
    from slip_estimator.bench.live import bench_live
    from slip_estimator.bench.memory import bench_memory
    from slip_estimator.bench.throughput import bench_core, bench_replay, bench_scaling

    return {'core': (bench_core, tables.print_core), 'replay': (bench_replay, tables.print_replay),
            'live': (bench_live, tables.print_live), 'memory': (bench_memory, tables.print_memory),
            'scaling': (bench_scaling, tables.print_scaling)}


def bench_main(argv: list[str] | None = None) -> int:
    """``slip-estimator bench`` (argv without the subcommand). Returns the exit status."""
    args = build_parser().parse_args(argv)
    if args.worker == 'live':
        from slip_estimator.bench.live import live_worker
        return live_worker(args)
    if args.worker == 'memory':
        from slip_estimator.bench.memory import memory_worker
        return memory_worker(args)
    only = [s.strip() for s in args.only.split(',') if s.strip()]
    unknown = [s for s in only if s not in SECTIONS]
    if unknown:
        print(f'slip-estimator bench: unknown section(s) {unknown}; choose from {SECTIONS}',
              file=sys.stderr)
        return 2
    report: dict[str, Any] = {'machine': machine_info(), 'argv': list(argv or sys.argv[1:])}
    tables.print_machine(report['machine'])
    status = 0
    runners = _runners()
    for name in SECTIONS:
        if name not in only:
            continue
        run, show = runners[name]
        t0 = time.perf_counter()
        try:
            res = run(args)
        except Exception as exc:  # noqa: BLE001 -- report and go on with the other sections
            print(f'\n== {name}: FAILED: {exc}', flush=True)
            report[name] = {'error': str(exc)}
            status = 1
            continue
        if name == 'memory':
            from slip_estimator.bench.memory import memory_verdict
            res['growth_mb'], res['verdict'] = memory_verdict(res)
        res['section_wall_s'] = time.perf_counter() - t0
        report[name] = res
        show(res)
        sys.stdout.flush()
    report['machine']['loadavg_1min_end'] = os.getloadavg()[0]
    print(f'\n1-min load average at the end: {report["machine"]["loadavg_1min_end"]:.2f}')
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, default=float))
        print(f'\nfigures written to {args.json}')
    return status
