"""The bench's plain-text tables: one ``print_<section>`` per section of the JSON report."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]], left: int = 1) -> str:
    """A plain-text table; the first ``left`` columns are left-aligned, the rest right."""
    cells = [[str(h) for h in headers]] + [[_fmt(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ['  ' + '  '.join(c.rjust(w) if k >= left else c.ljust(w)
                              for k, (c, w) in enumerate(zip(r, widths))) for r in cells]
    lines.insert(1, '  ' + '  '.join('-' * w for w in widths))
    return '\n'.join(lines)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        if np.isnan(value):
            return 'n/a'
        if abs(value) >= 1000:
            return f'{value:,.0f}'
        if abs(value) >= 10:
            return f'{value:.1f}'
        return f'{value:.3f}' if abs(value) < 1 else f'{value:.2f}'
    return str(value)


def print_machine(info: dict[str, Any]) -> None:
    print('== machine')
    print(f'  CPU {info["cpu_model"]}, {info["cores"]} cores; Python {info["python"]}, '
          f'numpy {info["numpy"]}; {info["platform"]}')
    print(f'  1-min load average at start: {info["loadavg_1min"]:.2f} (other processes share '
          'the cores; compare runs at similar load)')


def print_core(res: dict[str, Any]) -> None:
    print(f'\n== core throughput (SlipEstimator, {res["scenario"]} scenario seed {res["seed"]}, '
          f'best of {res["repeats"]}, records built before timing)')
    print(_table(('path', 'IMU steps', 'data s', 'wall s', 'steps/s', 'us/step', 'x real time',
                  'CPU us/step'),
                 [(r['label'], r['imu_steps'], r['data_s'], r['wall_s'], r['steps_per_s'],
                   r['us_per_step'], r['realtime_ratio'], r.get('cpu_us_per_step', float('nan')))
                  for r in res['rows']]))
    print('  x real time = steps/s / 250 Hz; CPU = the thread\'s CPU time (best of the runs), '
          'which waits for a core do not inflate')


def print_replay(res: dict[str, Any]) -> None:
    print('\n== offline replay (slip_estimator.replay.replay_bag, best of '
          f'{res["rows"][0]["repeats"] if res["rows"] else 1} by estimation time)')
    rows = []
    for r in res['rows']:
        io = r['read_s'] + r['write_s']
        rows.append((r['label'], r['messages_in'], r['messages_out'], r['data_s'], r['wall_s'],
                     r['realtime_ratio'], r['read_s'], r['write_s'],
                     f'{100 * io / r["wall_s"]:.0f}%', r['estimation_s'],
                     f'{100 * r["estimation_s"] / r["wall_s"]:.0f}%',
                     r['estimation_realtime_ratio']))
    print(_table(('bag', 'msgs in', 'msgs out', 'data s', 'wall s', 'x real time',
                  'read+deser s', 'ser+write s', 'bag IO %', 'estimation s', 'est. %',
                  'est. x real time'), rows))
    print('  read = read the serialized inputs + decode the IMU (ros.cdr) + header-stamp '
          'reorder; estimation = the adapter (wheel decode + core + output messages + NaN '
          'guard); write = serialize (ros.cdr_out) + write + close')
    if res.get('process'):
        print('\n  whole process (`slip-estimator replay BAG --params-file P --output O` in a '
              'subprocess: start-up, imports, read, estimation, write), runs interleaved')
        print(_table(('bag', 'code', 'data s', 'wall s', 'x real time', 'CPU s',
                      'outputs vs this tree'),
                     [(r['bag'], r['label'], r['data_s'], r['wall_s'], r['realtime_ratio'],
                       r['cpu_s'], r.get('identical', '')) for r in res['process']]))
    if res.get('pathfinder_skipped'):
        print(f'  s5t1 skipped: {res["pathfinder_skipped"]}')


def print_live(res: dict[str, Any]) -> None:
    runs = res['runs']
    first = runs[0]
    print(f'\n== live node over DDS ({first["duration_s"]:g} s per run, IMU at each rate + '
          f'JointState 10 Hz with wall-clock stamps, ROS_DOMAIN_ID {first["domain_id"]}, '
          'LOCALHOST discovery; runs one after another)')

    def column(r: dict[str, Any]) -> list[Any]:
        e2e = r['end_to_end']
        return [
            f'{r["imu_received"]} / {r["imu_sent"]}',
            f'{r["wheel_received"]} / {r["wheel_sent"]}',
            r['imu_stamp_gaps'],
            f'{r["publisher_late"]} ({r["publisher_max_late_ms"]:.2f})',
            (f'{_fmt(r["callback_p50_ms"])} / {_fmt(r["callback_p99_ms"])} / '
             f'{_fmt(r["callback_max_ms"])}'),
            (f'{_fmt(r.get("all_callbacks_p50_ms", np.nan))} / '
             f'{_fmt(r.get("all_callbacks_p99_ms", np.nan))} / '
             f'{_fmt(r.get("all_callbacks_max_ms", np.nan))}'),
            f'{_fmt(e2e["p50_ms"])} / {_fmt(e2e["p99_ms"])} / {_fmt(e2e["max_ms"])}',
            r.get('node_cpu_percent_of_one_core', float('nan')),
            (f'{_fmt(r.get("node_rss_mb", float("nan")))} / '
             f'{_fmt(r.get("node_peak_rss_mb", float("nan")))}'),
        ]

    names = ('IMU received / sent', 'JointState received / sent', 'IMU stamp gaps (node)',
             'publisher late sends (max ms)', 'IMU callback p50 / p99 / max ms',
             'every callback p50 / p99 / max ms',
             'IMU stamp -> odometry p50 / p99 / max ms', 'node CPU, % of one core',
             'node RSS / peak MiB')
    cols = [column(r) for r in runs]
    rows = [(name, *(c[i] for c in cols)) for i, name in enumerate(names)]
    print(_table(('figure', *(f'{r["label"]}, {r["imu_rate_hz"]:g} Hz' for r in runs)), rows))
    q = first['qos']
    print(f'  QoS: publisher IMU {q["imu_publisher"]}, JointState {q["wheel_publisher"]}; node '
          f'inputs {q["node_inputs"]}; listener {q["listener"]}')
    print(f'  odometry at the node default odometry_rate_hz = {first["odometry_rate_hz"]:g} '
          '(latency measured on those IMU stamps); counters from the node\'s final '
          '/diagnostics (watchdog STALE report); stamp gaps are publisher send jitter '
          '(> 1.5 periods between stamps), drops are received < sent; IMU callback: convert, '
          'core step, build the outputs (and publish them, in a node without an output step); '
          '"every callback": the '
          "input callbacks, the node's output step (publishing), its timers and services "
          '(n/a: a node that does not time them)')


def print_memory(res: dict[str, Any]) -> None:
    print(f'\n== memory (core at full speed in a subprocess, {res["data_s"]:.0f} s of 250 Hz '
          f'data, {res["imu_steps"]} IMU steps in {res["wall_s"]:.1f} s wall = '
          f'{res["realtime_ratio"]:.1f}x real time)')
    print(f'  RSS: start {res["rss_start_mb"]:.1f} MiB, peak during sim generation '
          f'{res["peak_rss_sim_mb"]:.1f}, before processing {res["rss_before_processing_mb"]:.1f}, '
          f'peak during processing {res["peak_rss_processing_mb"]:.1f}')
    print(_table(('data s', 'RSS MiB', 'wall s'),
                 [(s['data_s'], s['rss_mb'], s['wall_s']) for s in res['samples']]))
    print(f'  memory: {res["verdict"]}; filter aligned={res["aligned"]}, '
          f'health level {res["health_level"]}')


def print_scaling(res: dict[str, Any]) -> None:
    print('\n== scaling: core cost vs IMU rate (short scenario simulated at each rate, best of '
          f'{res["repeats"]})')
    print(_table(('IMU rate', 'IMU steps', 'wall s', 'us/step', 'x real time'),
                 [(r['label'], r['imu_steps'], r['wall_s'], r['us_per_step'],
                   r['realtime_ratio']) for r in res['by_rate']]))
    print('  x real time at the IMU rate of the row; covariance_decimation in samples, so the '
          'covariance rate scales with the IMU rate')
    print('\n== scaling: core cost vs log length (chained default scenarios, 250 Hz)')
    print(_table(('length', 'IMU steps', 'wall s', 'us/step', 'x real time'),
                 [(r['label'], r['imu_steps'], r['wall_s'], r['us_per_step'],
                   r['realtime_ratio']) for r in res['by_length']]))
