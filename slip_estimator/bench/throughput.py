"""Core throughput, replay speed and scaling: the compute-bound sections of the bench.

Simulated drives become the core's records through :mod:`slip_estimator.streams` (built
before timing) and are fed by :func:`slip_estimator.streams.feed`, the same loop the tests
and the validation study use.
"""
from __future__ import annotations

import argparse
import gc
import os
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slip_estimator.streams import SensorData, concatenate, feed, from_simulation, records

IMU_RATE_HZ = 250.0


@dataclass(frozen=True)
class Drive:
    """A simulated drive as the core sees it (:class:`~slip_estimator.streams.SensorData`)
    and the parameters matching the simulated rover."""

    params: Any
    data: SensorData


def drive_from_sim(result: Any) -> Drive:
    """A :class:`SimResult` with its matching parameters."""
    from slip_estimator.sim.bag import sim_params

    params = sim_params(result)
    return Drive(params, from_simulation(result, params))


def chained_drive(duration_s: float, rate_imu_hz: float = IMU_RATE_HZ) -> Drive:
    """A drive of ``duration_s`` chained from default scenarios (seed 0, 1, ...), each
    simulated separately (so the simulator never holds more than ~6 min at once) and shifted
    in time. At each junction the rover restarts at rest from the start pose (a small tilt and
    bias step the filter absorbs at the stop)."""
    from slip_estimator.sim import default_scenario, simulate

    parts: list[Drive] = []
    left = duration_s
    offset_ns = 0
    seed = 0
    while left > 1e-9:
        cfg = default_scenario(seed).replace(rate_imu_hz=rate_imu_hz)
        cfg = cfg.replace(duration_s=max(min(left, cfg.total_duration_s), 10.0))
        d = drive_from_sim(simulate(cfg))
        gc.collect()
        parts.append(Drive(d.params, d.data.shifted(offset_ns)))
        offset_ns = int(parts[-1].data.imu_ns[-1] - parts[0].data.imu_ns[0]) \
            + round(1e9 / rate_imu_hz)
        left -= cfg.total_duration_s
        seed += 1
    return Drive(parts[0].params, concatenate([d.data for d in parts]))


def time_core(params: Any, recs: Sequence[Any], repeats: int = 1) -> tuple[float, Any, float]:
    """Best wall time (s) of feeding the records into a fresh SlipEstimator, that estimator,
    and the best CPU time (s) of the thread doing it (the steadier figure on a shared
    machine: waiting for a core is not counted)."""
    from slip_estimator.core.estimator import SlipEstimator

    best, best_cpu, est = float('inf'), float('inf'), None
    for _ in range(repeats):
        est = SlipEstimator(params)
        gc.collect()
        t0, c0 = time.perf_counter(), time.thread_time()
        feed(est, recs, keep_estimates=False)
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.thread_time() - c0)
    return best, est, best_cpu


def _core_row(label: str, n: int, data_s: float, wall_s: float, rate_hz: float = IMU_RATE_HZ
              ) -> dict[str, Any]:
    steps = n / wall_s
    return {'label': label, 'imu_steps': n, 'data_s': round(data_s, 3), 'wall_s': wall_s,
            'steps_per_s': steps, 'us_per_step': 1e6 / steps,
            'realtime_ratio': steps / rate_hz}


def bench_core(args: argparse.Namespace) -> dict[str, Any]:
    """Core throughput on the short (or default) scenario, default and reference covariance."""
    from slip_estimator.sim import default_scenario, short_scenario, simulate

    make = short_scenario if args.core_scenario == 'short' else default_scenario
    cfg = make(args.seed)
    if args.core_duration_s:
        cfg = cfg.replace(duration_s=max(10.0, min(args.core_duration_s, cfg.total_duration_s)))
    drive = drive_from_sim(simulate(cfg))
    recs = list(records(drive.data))
    rows = []
    for label, params in (
            (f'default (covariance_decimation={drive.params.covariance_decimation})',
             drive.params),
            ('reference (covariance_decimation=1)', drive.params.replace(covariance_decimation=1))):
        wall, est, cpu = time_core(params, recs, args.repeats)
        row = _core_row(label, drive.data.n_imu, drive.data.duration_s, wall)
        row['cpu_s'], row['cpu_us_per_step'] = cpu, 1e6 * cpu / drive.data.n_imu
        row['aligned'] = bool(est.aligned)
        row['counters'] = dict(est.counters)
        rows.append(row)
    return {'scenario': args.core_scenario, 'seed': args.seed, 'repeats': args.repeats,
            'rows': rows}


def _replay_one(label: str, bag: Path, params: Any, work: Path, repeats: int = 1
                ) -> dict[str, Any]:
    """Best (by estimation time) of ``repeats`` replays of ``bag``; its summary as figures."""
    from slip_estimator.replay import replay_bag

    best = None
    for k in range(max(1, repeats)):
        gc.collect()
        summary = replay_bag(bag, params, work / f'{label}_out_{k}')
        if best is None or summary.estimation_s < best.estimation_s:
            best = summary
    return {'label': label, 'messages_in': best.messages_in,
            'messages_out': best.messages_out, 'data_s': best.data_duration_s,
            'wall_s': best.wall_time_s, 'realtime_ratio': best.realtime_ratio,
            'read_s': best.read_s, 'estimation_s': best.estimation_s, 'write_s': best.write_s,
            'estimation_realtime_ratio': best.estimation_realtime_ratio, 'repeats': repeats}


def bench_replay(args: argparse.Namespace) -> dict[str, Any]:
    """replay_bag on a simulated 250 Hz bag and, when present, the real s5t1 log."""
    from slip_estimator.sim import default_scenario, simulate
    from slip_estimator.sim.bag import sim_params, write_sim_bag

    rows = []
    with tempfile.TemporaryDirectory(prefix='slip_bench_replay_') as tmp:
        work = Path(tmp)
        cfg = default_scenario(args.seed)
        cfg = cfg.replace(duration_s=max(10.0, min(args.replay_duration_s, cfg.total_duration_s)))
        result = simulate(cfg)
        t0 = time.perf_counter()
        write_sim_bag(result, work / 'sim')
        sim_write_s = time.perf_counter() - t0
        params = sim_params(result)
        del result
        rows.append(_replay_one('sim', work / 'sim', params, work, args.replay_repeats))
        rows[-1]['bag_write_s'] = sim_write_s
        bags = [('sim', work / 'sim', params)]
        pathfinder = Path(args.pathfinder).resolve() if args.pathfinder else None
        if pathfinder is not None and pathfinder.exists():
            from slip_estimator.pathfinder import import_pathfinder

            t0 = time.perf_counter()
            _, _, pf_params = import_pathfinder(pathfinder, work / 's5t1')
            import_s = time.perf_counter() - t0
            rows.append(_replay_one('s5t1', work / 's5t1', pf_params, work, args.replay_repeats))
            rows[-1]['bag_write_s'] = import_s
            bags.append(('s5t1', work / 's5t1', pf_params))
        skipped = None if (pathfinder is not None and pathfinder.exists()) else \
            f'{args.pathfinder} not found'
        process = replay_processes(bags, args, work)
    return {'rows': rows, 'pathfinder_skipped': skipped, 'process': process}


def replay_processes(bags: list[tuple[str, Path, Any]], args: argparse.Namespace, work: Path
                     ) -> list[dict[str, Any]]:
    """Whole-process ``slip-estimator replay`` of each bag by this tree and (``--baseline``)
    the baseline tree, interleaved, best of ``--replay-repeats`` by wall time; the baseline's
    slip and odometry outputs compared with this tree's (:mod:`slip_estimator.bench.identical`).
    """
    import resource
    import subprocess
    import sys

    from slip_estimator.bagio import bag_duration_s
    from slip_estimator.bench.identical import compare_bags
    from slip_estimator.bench.live import live_variants, save_params_for_tree, tree_env

    out = []
    for name, bag, params in bags:
        best: dict[str, dict[str, Any]] = {}
        for k in range(max(1, args.replay_repeats)):
            for label, tree in live_variants(args):
                params_file = work / f'{name}.{label.split()[0]}.yaml'
                save_params_for_tree(params, params_file, tree)
                env = tree_env(dict(os.environ), tree)
                dest = work / f'{name}_process_{len(best)}_{k}_{label.split()[0]}'
                cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                proc = subprocess.run(
                    [sys.executable, '-m', 'slip_estimator.cli', 'replay', str(bag),
                     '--params-file', str(params_file), '--output', str(dest)],
                    env=env, capture_output=True, text=True, check=False)
                wall = time.perf_counter() - t0
                cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                if proc.returncode not in (0, 1):
                    raise RuntimeError(f'replay of {name} by {label} failed: '
                                       f'{proc.stderr.strip()[-500:]}')
                cpu = cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime
                if label not in best or wall < best[label]['wall_s']:
                    best[label] = {'bag': name, 'label': label, 'wall_s': wall, 'cpu_s': cpu,
                                   'output': dest}
        mine = best['this tree']
        data_s = bag_duration_s(bag)
        for row in best.values():
            row['data_s'] = data_s
            row['realtime_ratio'] = data_s / row['wall_s']
            if row is not mine:
                counts, diffs = compare_bags(mine['output'], row['output'])
                row['identical'] = (f'identical ({sum(counts.values())} messages)' if not diffs
                                    else f'DIFFERENT: {diffs[0]}')
            row['output'] = str(row['output'])
            out.append(row)
    return out



def bench_scaling(args: argparse.Namespace) -> dict[str, Any]:
    """µs per IMU step vs IMU rate (short scenario simulated at each rate) and vs log length."""
    from slip_estimator.sim import short_scenario, simulate

    by_rate = []
    for rate in args.scaling_rates:
        cfg = short_scenario(args.seed).replace(rate_imu_hz=float(rate))
        if args.scaling_rate_duration_s:
            cfg = cfg.replace(duration_s=max(10.0, min(args.scaling_rate_duration_s,
                                                       cfg.total_duration_s)))
        drive = drive_from_sim(simulate(cfg))
        recs = list(records(drive.data))
        wall, _, _ = time_core(drive.params, recs, args.repeats)
        by_rate.append(_core_row(f'{rate:g} Hz', drive.data.n_imu, drive.data.duration_s, wall,
                                 float(rate)))
        by_rate[-1]['rate_hz'] = float(rate)
        del recs, drive
    by_length = []
    for length in args.scaling_lengths:
        drive = chained_drive(float(length))
        recs = list(records(drive.data))
        wall, _, _ = time_core(drive.params, recs, args.repeats)
        by_length.append(_core_row(f'{length:g} s', drive.data.n_imu, drive.data.duration_s,
                                   wall))
        by_length[-1]['length_s'] = float(length)
        del recs, drive
    return {'by_rate': by_rate, 'by_length': by_length, 'repeats': args.repeats}
