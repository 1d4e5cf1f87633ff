"""Live: the real node in a subprocess, fed over DDS by a publisher in another subprocess.

The only module of the package that imports rclpy (in :func:`live_worker`, the publisher /
listener process); :func:`bench_live` starts the processes and reads CPU and memory of the node
from ``/proc``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.bench.machine import proc_cpu_s, proc_rss_mb

LIVE_IMU_QOS = 'BEST_EFFORT, VOLATILE, KEEP_LAST 10'
LIVE_WHEEL_QOS = 'BEST_EFFORT, VOLATILE, KEEP_LAST 10'
LIVE_OUT_QOS = 'RELIABLE, VOLATILE, KEEP_LAST 100 (odometry), 10 (diagnostics)'


def _ros_env(domain_id: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    return env


def bench_live(args: argparse.Namespace) -> dict[str, Any]:
    """One live run per IMU rate of ``--live-imu-rates``, the node of this tree and, with
    ``--baseline DIR``, the node of that source tree right after it (same publisher, same
    load): ``{'runs': [figures of each run]}``."""
    runs = []
    for rate in args.live_imu_rates:
        for label, tree in live_variants(args):
            res = _bench_live_once(args, float(rate), tree)
            res.update(label=label, imu_rate_hz=float(rate))
            runs.append(res)
    return {'runs': runs}


def live_variants(args: argparse.Namespace) -> list[tuple[str, str | None]]:
    """(label, source tree or None for this one) of the nodes to measure."""
    base = getattr(args, 'baseline', None)
    return [('this tree', None)] + ([(f'baseline {Path(base).name}', str(base))] if base else [])


def save_params_for_tree(params: Any, path: Path, tree: str | None) -> None:
    """Write ``params`` for the node or replay of ``tree``; for an earlier tree (``tree`` given)
    the file allows parameters that tree does not know yet (added since), which it then
    ignores with a logged error instead of refusing to start."""
    import yaml

    from slip_estimator.paramfile import save_params

    save_params(params, path)
    if tree:
        doc = yaml.safe_load(path.read_text())
        for section in doc.values():
            section['ros__parameters']['allow_unknown_parameters'] = True
        path.write_text(yaml.safe_dump(doc, sort_keys=False))


def tree_env(env: dict[str, str], tree: str | None) -> dict[str, str]:
    """``env`` for a subprocess running the package of ``tree`` (None: this one).
    PYTHONSAFEPATH: ``python -m`` would otherwise put the working folder, maybe a checkout of
    another version, ahead of PYTHONPATH and the installed package."""
    env = dict(env, PYTHONSAFEPATH='1')
    if tree:
        env['PYTHONPATH'] = str(Path(tree).resolve())
    return env


def _bench_live_once(args: argparse.Namespace, rate_imu_hz: float, tree: str | None
                     ) -> dict[str, Any]:
    """Node subprocess (from ``tree`` when given) + publisher/listener subprocess at
    ``rate_imu_hz``; CPU of the node from /proc."""
    from slip_estimator.sim import default_scenario, simulate
    from slip_estimator.sim.bag import sim_params

    domain_id = args.domain_id if args.domain_id is not None else 100 + os.getpid() % 100
    env = _ros_env(domain_id)
    node_env = tree_env(env, tree)
    with tempfile.TemporaryDirectory(prefix='slip_bench_live_') as tmp:
        work = Path(tmp)
        cfg = default_scenario(args.seed)
        params = sim_params(simulate(cfg.replace(duration_s=10.0)))
        save_params_for_tree(params, work / 'params.yaml', tree)
        node_log = open(work / 'node.log', 'w')  # noqa: SIM115 -- closed below
        node = subprocess.Popen(
            [sys.executable, '-m', 'slip_estimator.ros.node', '--ros-args',
             '--params-file', str(work / 'params.yaml')],
            env=node_env, stdout=node_log, stderr=subprocess.STDOUT)
        pub = None
        marks: dict[str, tuple[float, float]] = {}
        try:
            pub = subprocess.Popen(
                [sys.executable, '-m', 'slip_estimator.bench', '--worker', 'live',
                 '--seed', str(args.seed), '--live-duration-s', str(args.live_duration_s),
                 '--live-imu-rates', f'{rate_imu_hz:g}',
                 '--worker-out', str(work / 'live.json')],
                env=tree_env(env, None), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                text=True)
            worker_log = []
            assert pub.stdout is not None
            for line in pub.stdout:
                word = line.strip()
                if word in ('START', 'END'):
                    marks[word] = (time.monotonic(), proc_cpu_s(node.pid))
                    if word == 'END':
                        marks['END_rss'] = (proc_rss_mb(node.pid), proc_rss_mb(node.pid, 'VmHWM'))
                else:
                    worker_log.append(line.rstrip())
                if node.poll() is not None:
                    break
            pub.wait(timeout=60)
            if not (work / 'live.json').exists():
                node_log.flush()
                raise RuntimeError('live publisher failed:\n' + '\n'.join(worker_log[-30:])
                                   + '\nnode log:\n' + (work / 'node.log').read_text()[-3000:])
            res = json.loads((work / 'live.json').read_text())
        finally:
            for proc in (pub, node):
                if proc is not None and proc.poll() is None:
                    proc.send_signal(2)  # SIGINT: clean rclpy shutdown
                    try:
                        proc.wait(timeout=10)
                    except subprocess.TimeoutExpired:
                        proc.kill()
                        proc.wait()
            node_log.close()
    if 'START' in marks and 'END' in marks:
        wall = marks['END'][0] - marks['START'][0]
        cpu = marks['END'][1] - marks['START'][1]
        res['node_cpu_s'] = cpu
        res['node_cpu_percent_of_one_core'] = 100.0 * cpu / wall if wall > 0 else float('nan')
        res['node_rss_mb'], res['node_peak_rss_mb'] = marks['END_rss']
    res['qos'] = {'imu_publisher': LIVE_IMU_QOS, 'wheel_publisher': LIVE_WHEEL_QOS,
                  'node_inputs': 'BEST_EFFORT, VOLATILE, KEEP_LAST 500 (IMU), 100 (wheels)',
                  'listener': LIVE_OUT_QOS}
    res['domain_id'] = domain_id
    res['odometry_rate_hz'] = params.odometry_rate_hz
    return res


def _percentiles(values: Sequence[float]) -> dict[str, float]:
    if not values:
        return {'n': 0, 'p50_ms': float('nan'), 'p99_ms': float('nan'), 'max_ms': float('nan')}
    a = np.asarray(values, dtype=float)
    return {'n': len(a), 'p50_ms': float(np.percentile(a, 50)),
            'p99_ms': float(np.percentile(a, 99)), 'max_ms': float(a.max())}


@dataclass
class _LiveDrive:
    """The simulated drive the publisher sends, as plain lists (fast to copy into messages)."""

    f_imu: list[list[float]]
    w_imu: list[list[float]]
    wheel_rates: list[list[float]]
    wheel_angles: list[list[float]]
    rate_imu_hz: float
    per_wheel: int
    n_send: int


def _live_drive(args: argparse.Namespace) -> _LiveDrive:
    from slip_estimator.sim import default_scenario, simulate

    cfg = default_scenario(args.seed).replace(rate_imu_hz=float(args.live_imu_rates[0]))
    result = simulate(cfg.replace(duration_s=max(10.0, min(args.live_duration_s + 1.0,
                                                           cfg.total_duration_s))))
    return _LiveDrive(result.f_ib_imu.tolist(), result.omega_ib_imu.tolist(),
                      result.wheel_rate_rps.tolist(), result.wheel_angle_rad.tolist(),
                      cfg.rate_imu_hz, round(cfg.rate_imu_hz / cfg.rate_wheel_hz),
                      round(args.live_duration_s * cfg.rate_imu_hz))


def _wait_for_discovery(timeout_s: float, pubs: Sequence[Any], subs: Sequence[Any]) -> float:
    """Seconds until every publisher has a reader and every subscription a writer, or -1."""
    t0 = time.monotonic()
    while time.monotonic() < t0 + timeout_s:
        if all(p.get_subscription_count() for p in pubs) and \
                all(s.get_publisher_count() for s in subs):
            return time.monotonic() - t0
        time.sleep(0.05)
    return -1.0


def _publish(drive: _LiveDrive, pub_imu: Any, pub_js: Any) -> dict[str, Any]:
    """Send ``n_send`` IMU messages at the IMU rate (wall-clock stamps) and a JointState every
    ``per_wheel`` of them; returns the send counts and lateness."""
    from sensor_msgs.msg import Imu, JointState

    from slip_estimator.ros.stamps import ns_to_stamp
    from slip_estimator.sim.scenario import WHEEL_JOINT_NAMES

    period_ns = round(1e9 / drive.rate_imu_hz)
    n_imu, n_wheel = len(drive.f_imu), len(drive.wheel_rates)
    sent_imu = sent_wheel = late = 0
    max_late_ms = 0.0
    t_start = time.monotonic_ns()
    for k in range(drive.n_send):
        due = t_start + k * period_ns
        now = time.monotonic_ns()
        if due > now:
            time.sleep((due - now) * 1e-9)
        else:
            late += 1
            max_late_ms = max(max_late_ms, (now - due) * 1e-6)
        i = k % n_imu
        m = Imu()
        m.header.stamp = ns_to_stamp(time.time_ns())
        m.header.frame_id = 'imu_link'
        m.orientation_covariance[0] = -1.0
        a, w = m.linear_acceleration, m.angular_velocity
        a.x, a.y, a.z = drive.f_imu[i]
        w.x, w.y, w.z = drive.w_imu[i]
        pub_imu.publish(m)
        sent_imu += 1
        if k % drive.per_wheel == 0:
            j = (k // drive.per_wheel) % n_wheel
            js = JointState()
            js.header.stamp = m.header.stamp
            js.header.frame_id = 'base_link'
            js.name = list(WHEEL_JOINT_NAMES)
            js.position = drive.wheel_angles[j]
            js.velocity = drive.wheel_rates[j]
            pub_js.publish(js)
            sent_wheel += 1
    return {'imu_sent': sent_imu, 'wheel_sent': sent_wheel, 'publisher_late': late,
            'publisher_max_late_ms': max_late_ms,
            'send_wall_s': (time.monotonic_ns() - t_start) * 1e-9}


def live_worker(args: argparse.Namespace) -> int:
    """Publisher + listener process of the live section (prints START / END for the parent)."""
    import threading

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Imu, JointState

    from slip_estimator.ros.topics import TOPIC_DIAGNOSTICS, TOPIC_IMU, TOPIC_ODOMETRY
    from slip_estimator.ros.stamps import header_stamp_ns
    from slip_estimator.ros.qos import input_qos, output_qos

    drive = _live_drive(args)
    # A best-effort sensor publisher (as IMU drivers are) and reliable listeners: the node's
    # own profiles.
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    latencies_ms: list[float] = []
    diags: list[tuple[float, dict[str, str]]] = []
    try:
        node = rclpy.create_node('slip_bench_publisher', context=context)
        pub_imu = node.create_publisher(Imu, TOPIC_IMU, input_qos(10))
        pub_js = node.create_publisher(JointState, '/joint_states', input_qos(10))

        def on_odom(msg: Odometry) -> None:
            latencies_ms.append((time.time_ns() - header_stamp_ns(msg)) * 1e-6)

        def on_diag(msg: DiagnosticArray) -> None:
            for st in msg.status:
                if st.name and any(v.key == '/imu/data received' for v in st.values):
                    diags.append((time.monotonic(), {v.key: v.value for v in st.values}))

        sub_odom = node.create_subscription(Odometry, TOPIC_ODOMETRY, on_odom, output_qos(100))
        sub_diag = node.create_subscription(DiagnosticArray, TOPIC_DIAGNOSTICS, on_diag,
                                            output_qos(10))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        threading.Thread(target=executor.spin, daemon=True).start()
        discovery_s = _wait_for_discovery(args.live_discovery_timeout_s, (pub_imu, pub_js),
                                          (sub_odom, sub_diag))
        if discovery_s < 0:
            print('discovery timeout', flush=True)
            return 1
        time.sleep(1.5)  # best effort: let the matched readers settle
        print('START', flush=True)
        sent = _publish(drive, pub_imu, pub_js)
        t_end = time.monotonic()
        print('END', flush=True)
        # The node's watchdog publishes a STALE report with the final counters ~1-2 s later.
        deadline = time.monotonic() + 6.0
        while time.monotonic() < deadline:
            if diags and diags[-1][0] > t_end + 0.5:
                break
            time.sleep(0.05)
        time.sleep(0.3)
        final = diags[-1][1] if diags else {}
        executor.shutdown(timeout_sec=1.0)
    finally:
        rclpy.try_shutdown(context=context)
    out = _live_figures(args, sent, discovery_s, final, latencies_ms, len(diags))
    Path(args.worker_out).write_text(json.dumps(out, indent=1))
    return 0


def _live_figures(args: argparse.Namespace, sent: dict[str, Any], discovery_s: float,
                  final: dict[str, str], latencies_ms: list[float], n_diags: int
                  ) -> dict[str, Any]:
    """The live section's figures from the send counts and the node's final /diagnostics."""
    from slip_estimator.report import number

    def num(key: str) -> float:
        return number(final.get(key))

    return {
        'duration_s': args.live_duration_s, 'send_wall_s': sent['send_wall_s'],
        'discovery_s': discovery_s,
        'imu_sent': sent['imu_sent'],
        'imu_received': int(num('/imu/data received')) if final else None,
        'wheel_sent': sent['wheel_sent'],
        'wheel_received': int(num('/joint_states received')) if final else None,
        'imu_stamp_gaps': num('/imu/data stamp_gaps'),
        'publisher_late': sent['publisher_late'],
        'publisher_max_late_ms': sent['publisher_max_late_ms'],
        'callback_p50_ms': num('callback_p50_ms'), 'callback_p99_ms': num('callback_p99_ms'),
        'callback_max_ms': num('callback_max_ms'), 'callback_window': num('callback_window'),
        # Every callback the node runs (inputs, its output step, timers, services); NaN for a
        # node that does not report them (before the output step).
        'all_callbacks_p50_ms': num('all_callbacks_p50_ms'),
        'all_callbacks_p99_ms': num('all_callbacks_p99_ms'),
        'all_callbacks_max_ms': num('all_callbacks_max_ms'),
        'all_callbacks_window': num('all_callbacks_window'),
        'odometry_received': len(latencies_ms),
        'end_to_end': _percentiles(latencies_ms),
        'diagnostics_received': n_diags,
        'final_diagnostics_rejected': {k: v for k, v in final.items() if 'rejected' in k},
    }
