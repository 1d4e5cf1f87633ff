"""``slip-estimator bench``: throughput, latency and memory of the estimator on this machine.

Sections (``--only`` selects a comma-separated subset; every duration is an argument so a smoke
test runs the whole bench in seconds):

core     IMU steps/s of the full :class:`~slip_estimator.core.estimator.SlipEstimator` on a
         simulated drive (records built before timing, best of ``--repeats``), with the default
         ``covariance_decimation`` and the reference path (``covariance_decimation=1``).
replay   :func:`slip_estimator.replay.replay_bag` on a simulated 250 Hz bag (and the real s5t1
         Pathfinder log when ``../shared/data/pathfinder/s5t1.mat`` exists), with the split
         bag read (read + deserialize + sort) / estimation (adapter: conversion, core, output
         messages, NaN guard) / bag write (serialize + write) that replay_bag itself measures
         (best of ``--replay-repeats`` replays).
live     the real node (``python -m slip_estimator.ros.node``) in a subprocess, fed over DDS by
         a publisher in another subprocess (IMU 250 Hz, JointState 10 Hz, wall-clock stamps);
         messages received vs sent, IMU callback latency (the node's ``callback_*_ms``
         diagnostics), end-to-end latency IMU stamp -> ``/slip_estimator/odometry`` arrival,
         node CPU (``/proc/<pid>/stat`` utime+stime).
memory   RSS of a subprocess pushing a chained simulated drive (default one hour at 250 Hz)
         through the core at full speed, sampled every ``--memory-sample-s`` of data time.
scaling  core cost vs IMU rate (50..1000 Hz, same drive simulated at that rate) and vs log
         length.

``--json FILE`` writes every figure. Only the standard library, numpy and the package are used
(CPU and memory from ``/proc``).
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

SECTIONS = ('core', 'replay', 'live', 'memory', 'scaling')
IMU_RATE_HZ = 250.0
PATHFINDER_S5T1 = Path(__file__).resolve().parents[1] / '..' / 'shared' / 'data' / 'pathfinder' \
    / 's5t1.mat'
CLK_TCK = os.sysconf('SC_CLK_TCK')


# --- machine and process facts ------------------------------------------------------------------

def machine_info() -> dict[str, Any]:
    """CPU model, core count, Python and numpy versions."""
    model = platform.processor() or 'unknown'
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return {'cpu_model': model, 'cores': os.cpu_count(), 'python': platform.python_version(),
            'numpy': np.__version__, 'platform': platform.platform(),
            'loadavg_1min': os.getloadavg()[0]}


def proc_cpu_s(pid: int) -> float:
    """utime + stime of a process, s (from /proc/<pid>/stat)."""
    text = Path(f'/proc/{pid}/stat').read_text()
    fields = text[text.rindex(')') + 2:].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14, 15 of stat(5)


def proc_rss_mb(pid: int | str = 'self', key: str = 'VmRSS') -> float:
    """VmRSS (or VmHWM, ...) of a process, MiB."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith(key + ':'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


# --- simulated drives as core records -----------------------------------------------------------

@dataclass
class Drive:
    """A simulated drive as compact arrays in the body frame (the core's input), plus params.

    ``imu_stamp_ns`` (N,), ``f_ib_b`` / ``omega_ib_b`` (N, 3); ``wheel_stamp_ns`` (M,),
    ``rim_mps`` (M, 3) = mean, left, right rim speed.
    """

    params: Any
    imu_stamp_ns: np.ndarray
    f_ib_b: np.ndarray
    omega_ib_b: np.ndarray
    wheel_stamp_ns: np.ndarray
    rim_mps: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.imu_stamp_ns[-1] - self.imu_stamp_ns[0]) * 1e-9

    @property
    def n_imu(self) -> int:
        return len(self.imu_stamp_ns)


def drive_from_sim(result: Any) -> Drive:
    """Rotate a :class:`SimResult`'s IMU into the body frame and reduce the wheels to rims."""
    from slip_estimator.core import frames
    from slip_estimator.sim.bag import sim_params

    p = sim_params(result)
    C_imu_b = frames.imu_to_body_dcm(p.imu_to_base_rpy)
    rates = result.wheel_rate_rps * p.wheel_radius
    rim = np.stack([rates.mean(axis=1), rates[:, [0, 2]].mean(axis=1),
                    rates[:, [1, 3]].mean(axis=1)], axis=1)
    return Drive(p, result.stamps_ns(result.imu_t_s), result.f_ib_imu @ C_imu_b.T,
                 result.omega_ib_imu @ C_imu_b.T, result.stamps_ns(result.wheel_t_s), rim)


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
        d.imu_stamp_ns = d.imu_stamp_ns + offset_ns
        d.wheel_stamp_ns = d.wheel_stamp_ns + offset_ns
        parts.append(d)
        offset_ns = int(d.imu_stamp_ns[-1] - parts[0].imu_stamp_ns[0]) + round(1e9 / rate_imu_hz)
        left -= cfg.total_duration_s
        seed += 1
    cat = np.concatenate
    return Drive(parts[0].params, cat([d.imu_stamp_ns for d in parts]),
                 cat([d.f_ib_b for d in parts]), cat([d.omega_ib_b for d in parts]),
                 cat([d.wheel_stamp_ns for d in parts]), cat([d.rim_mps for d in parts]))


def drive_records(drive: Drive, start: int = 0, stop: int | None = None
                  ) -> tuple[list[Any], list[Any]]:
    """ImuSample / WheelSample records of IMU samples [start, stop) and the wheel samples
    up to the last IMU stamp of that range (after the previous range)."""
    from slip_estimator.core.types import ImuSample, WheelSample

    stop = drive.n_imu if stop is None else stop
    st = drive.imu_stamp_ns
    imu = [ImuSample(int(s), f, w) for s, f, w in zip(
        st[start:stop].tolist(), drive.f_ib_b[start:stop], drive.omega_ib_b[start:stop])]
    lo = 0 if start == 0 else int(np.searchsorted(drive.wheel_stamp_ns, st[start - 1], 'right'))
    hi = int(np.searchsorted(drive.wheel_stamp_ns, st[stop - 1], 'right'))
    wheels = [WheelSample(int(s), float(r[0]), float(r[1]), float(r[2])) for s, r in zip(
        drive.wheel_stamp_ns[lo:hi].tolist(), drive.rim_mps[lo:hi])]
    return imu, wheels


def feed(est: Any, imu: Sequence[Any], wheels: Sequence[Any]) -> None:
    """Feed records in stamp order as the replay does: at equal stamps the IMU goes first."""
    j, nw = 0, len(wheels)
    add_wheel, add_imu = est.add_wheel, est.add_imu
    for s in imu:
        stamp = s.stamp_ns
        while j < nw and wheels[j].stamp_ns < stamp:
            add_wheel(wheels[j])
            j += 1
        add_imu(s)
    while j < nw:
        add_wheel(wheels[j])
        j += 1


def time_core(params: Any, imu: Sequence[Any], wheels: Sequence[Any], repeats: int = 1
              ) -> tuple[float, Any]:
    """Best wall time (s) of feeding the records into a fresh SlipEstimator, and that estimator."""
    from slip_estimator.core.estimator import SlipEstimator

    best, est = float('inf'), None
    for _ in range(repeats):
        est = SlipEstimator(params)
        gc.collect()
        t0 = time.perf_counter()
        feed(est, imu, wheels)
        best = min(best, time.perf_counter() - t0)
    return best, est


def _core_row(label: str, n: int, data_s: float, wall_s: float, rate_hz: float = IMU_RATE_HZ
              ) -> dict[str, Any]:
    steps = n / wall_s
    return {'label': label, 'imu_steps': n, 'data_s': round(data_s, 3), 'wall_s': wall_s,
            'steps_per_s': steps, 'us_per_step': 1e6 / steps,
            'realtime_ratio': steps / rate_hz}


# --- sections -----------------------------------------------------------------------------------

def bench_core(args: argparse.Namespace) -> dict[str, Any]:
    """Core throughput on the short (or default) scenario, default and reference covariance."""
    from slip_estimator.sim import default_scenario, short_scenario, simulate

    make = short_scenario if args.core_scenario == 'short' else default_scenario
    cfg = make(args.seed)
    if args.core_duration_s:
        cfg = cfg.replace(duration_s=max(10.0, min(args.core_duration_s, cfg.total_duration_s)))
    drive = drive_from_sim(simulate(cfg))
    imu, wheels = drive_records(drive)
    rows = []
    for label, params in (
            (f'default (covariance_decimation={drive.params.covariance_decimation})',
             drive.params),
            ('reference (covariance_decimation=1)', drive.params.replace(covariance_decimation=1))):
        wall, est = time_core(params, imu, wheels, args.repeats)
        row = _core_row(label, len(imu), drive.duration_s, wall)
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
        pathfinder = Path(args.pathfinder).resolve() if args.pathfinder else None
        if pathfinder is not None and pathfinder.exists():
            from slip_estimator.pathfinder import import_pathfinder

            t0 = time.perf_counter()
            _, _, pf_params = import_pathfinder(pathfinder, work / 's5t1')
            import_s = time.perf_counter() - t0
            rows.append(_replay_one('s5t1', work / 's5t1', pf_params, work, args.replay_repeats))
            rows[-1]['bag_write_s'] = import_s
        skipped = None if (pathfinder is not None and pathfinder.exists()) else \
            f'{args.pathfinder} not found'
    return {'rows': rows, 'pathfinder_skipped': skipped}


# --- live: the node over DDS --------------------------------------------------------------------

LIVE_IMU_QOS = 'BEST_EFFORT, VOLATILE, KEEP_LAST 10'
LIVE_WHEEL_QOS = 'BEST_EFFORT, VOLATILE, KEEP_LAST 10'
LIVE_OUT_QOS = 'RELIABLE, VOLATILE, KEEP_LAST 100 (odometry), 10 (diagnostics)'


def _ros_env(domain_id: int) -> dict[str, str]:
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    return env


def bench_live(args: argparse.Namespace) -> dict[str, Any]:
    """Node subprocess + publisher/listener subprocess; CPU of the node from /proc."""
    from slip_estimator.paramfile import save_params
    from slip_estimator.sim import default_scenario, simulate
    from slip_estimator.sim.bag import sim_params

    domain_id = args.domain_id if args.domain_id is not None else 100 + os.getpid() % 100
    env = _ros_env(domain_id)
    with tempfile.TemporaryDirectory(prefix='slip_bench_live_') as tmp:
        work = Path(tmp)
        cfg = default_scenario(args.seed)
        params = sim_params(simulate(cfg.replace(duration_s=10.0)))
        save_params(params, work / 'params.yaml')
        node_log = open(work / 'node.log', 'w')  # noqa: SIM115 -- closed below
        node = subprocess.Popen(
            [sys.executable, '-m', 'slip_estimator.ros.node', '--ros-args',
             '--params-file', str(work / 'params.yaml')],
            env=env, stdout=node_log, stderr=subprocess.STDOUT)
        pub = None
        marks: dict[str, tuple[float, float]] = {}
        try:
            pub = subprocess.Popen(
                [sys.executable, '-m', 'slip_estimator.bench', '--worker', 'live',
                 '--seed', str(args.seed), '--live-duration-s', str(args.live_duration_s),
                 '--worker-out', str(work / 'live.json')],
                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
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


def live_worker(args: argparse.Namespace) -> int:
    """Publisher + listener process of the live section (prints START / END for the parent)."""
    import threading

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Imu, JointState

    from slip_estimator.ros.adapter import TOPIC_DIAGNOSTICS, TOPIC_IMU, TOPIC_ODOMETRY
    from slip_estimator.ros.node import input_qos, output_qos
    from slip_estimator.sim import default_scenario, simulate
    from slip_estimator.sim.scenario import WHEEL_JOINT_NAMES

    cfg = default_scenario(args.seed)
    result = simulate(cfg.replace(duration_s=max(10.0, min(args.live_duration_s + 1.0,
                                                           cfg.total_duration_s))))
    f_imu = result.f_ib_imu.tolist()
    w_imu = result.omega_ib_imu.tolist()
    wheel_rates = result.wheel_rate_rps.tolist()
    wheel_angles = result.wheel_angle_rad.tolist()
    n_imu, n_wheel = len(f_imu), len(wheel_rates)
    per_wheel = round(cfg.rate_imu_hz / cfg.rate_wheel_hz)
    n_send = round(args.live_duration_s * cfg.rate_imu_hz)
    del result

    # A best-effort sensor publisher (as IMU drivers are) and reliable listeners: the node's
    # own profiles.
    best_effort = input_qos(10)
    reliable = output_qos

    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    latencies_ms: list[float] = []
    diags: list[tuple[float, dict[str, str]]] = []
    odom_count = [0]
    try:
        node = rclpy.create_node('slip_bench_publisher', context=context)
        pub_imu = node.create_publisher(Imu, TOPIC_IMU, best_effort)
        pub_js = node.create_publisher(JointState, '/joint_states', best_effort)

        def on_odom(msg: Odometry) -> None:
            now = time.time_ns()
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            odom_count[0] += 1
            latencies_ms.append((now - stamp) * 1e-6)

        def on_diag(msg: DiagnosticArray) -> None:
            for st in msg.status:
                if st.name and any(v.key == '/imu/data received' for v in st.values):
                    diags.append((time.monotonic(), {v.key: v.value for v in st.values}))

        sub_odom = node.create_subscription(Odometry, TOPIC_ODOMETRY, on_odom, reliable(100))
        sub_diag = node.create_subscription(DiagnosticArray, TOPIC_DIAGNOSTICS, on_diag,
                                            reliable(10))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        spin = threading.Thread(target=executor.spin, daemon=True)
        spin.start()

        deadline = time.monotonic() + args.live_discovery_timeout_s
        while time.monotonic() < deadline:
            if (pub_imu.get_subscription_count() and pub_js.get_subscription_count()
                    and sub_odom.get_publisher_count() and sub_diag.get_publisher_count()):
                break
            time.sleep(0.05)
        else:
            print('discovery timeout', flush=True)
            return 1
        time.sleep(1.5)  # best effort: let the matched readers settle
        discovery_s = args.live_discovery_timeout_s - (deadline - time.monotonic())

        period_ns = round(1e9 / cfg.rate_imu_hz)
        sent_imu = sent_wheel = late = 0
        max_late_ms = 0.0
        print('START', flush=True)
        t_start = time.monotonic_ns()
        for k in range(n_send):
            due = t_start + k * period_ns
            now = time.monotonic_ns()
            if due > now:
                time.sleep((due - now) * 1e-9)
            else:
                late += 1
                max_late_ms = max(max_late_ms, (now - due) * 1e-6)
            stamp = time.time_ns()
            i = k % n_imu
            m = Imu()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            m.header.frame_id = 'imu_link'
            m.orientation_covariance[0] = -1.0
            a, w = m.linear_acceleration, m.angular_velocity
            a.x, a.y, a.z = f_imu[i]
            w.x, w.y, w.z = w_imu[i]
            pub_imu.publish(m)
            sent_imu += 1
            if k % per_wheel == 0:
                j = (k // per_wheel) % n_wheel
                js = JointState()
                js.header.stamp = m.header.stamp
                js.header.frame_id = 'base_link'
                js.name = list(WHEEL_JOINT_NAMES)
                js.position = wheel_angles[j]
                js.velocity = wheel_rates[j]
                pub_js.publish(js)
                sent_wheel += 1
        send_wall_s = (time.monotonic_ns() - t_start) * 1e-9
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

    def num(key: str) -> float:
        try:
            return float(final[key])
        except (KeyError, ValueError):
            return float('nan')

    out = {
        'duration_s': args.live_duration_s, 'send_wall_s': send_wall_s,
        'discovery_s': discovery_s,
        'imu_sent': sent_imu, 'imu_received': int(num('/imu/data received'))
        if final else None,
        'wheel_sent': sent_wheel, 'wheel_received': int(num('/joint_states received'))
        if final else None,
        'imu_stamp_gaps': num('/imu/data stamp_gaps'),
        'publisher_late': late, 'publisher_max_late_ms': max_late_ms,
        'callback_p50_ms': num('callback_p50_ms'), 'callback_p99_ms': num('callback_p99_ms'),
        'callback_max_ms': num('callback_max_ms'), 'callback_window': num('callback_window'),
        'odometry_received': odom_count[0],
        'end_to_end': _percentiles(latencies_ms),
        'diagnostics_received': len(diags),
        'final_diagnostics_rejected': {k: v for k, v in final.items() if 'rejected' in k},
    }
    Path(args.worker_out).write_text(json.dumps(out, indent=1))
    return 0


# --- memory -------------------------------------------------------------------------------------

def bench_memory(args: argparse.Namespace) -> dict[str, Any]:
    """Run :func:`memory_worker` in a fresh subprocess and collect its samples."""
    with tempfile.TemporaryDirectory(prefix='slip_bench_mem_') as tmp:
        out = Path(tmp) / 'memory.json'
        proc = subprocess.run(
            [sys.executable, '-m', 'slip_estimator.bench', '--worker', 'memory',
             '--memory-duration-s', str(args.memory_duration_s),
             '--memory-sample-s', str(args.memory_sample_s), '--worker-out', str(out)],
            check=False, capture_output=True, text=True)
        if proc.returncode != 0 or not out.exists():
            raise RuntimeError(f'memory worker failed ({proc.returncode}):\n{proc.stderr[-3000:]}')
        return json.loads(out.read_text())


def memory_worker(args: argparse.Namespace) -> int:
    """Generate the chained drive (compact arrays), then push it through the core at full
    speed, reading VmRSS every ``memory_sample_s`` of data time (and every 10 s for the peak)."""
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.core.types import ImuSample, WheelSample

    t0 = time.perf_counter()
    rss_start = proc_rss_mb()
    drive = chained_drive(args.memory_duration_s)
    gc.collect()
    sim_s = time.perf_counter() - t0
    rss_after_sim = proc_rss_mb()
    hwm_after_sim = proc_rss_mb('self', 'VmHWM')

    est = SlipEstimator(drive.params)
    st = drive.imu_stamp_ns.tolist()
    ws = drive.wheel_stamp_ns.tolist()
    rim = drive.rim_mps.tolist()
    f, w = drive.f_ib_b, drive.omega_ib_b
    rss_before = proc_rss_mb()
    t_first = st[0]
    sample_ns = int(args.memory_sample_s * 1e9)
    peak_ns = int(min(10.0, args.memory_sample_s) * 1e9)
    next_sample, next_peak = t_first, t_first
    samples: list[dict[str, float]] = []
    peak = rss_before
    j, nw = 0, len(ws)
    t1 = time.perf_counter()
    for i, stamp in enumerate(st):
        while j < nw and ws[j] < stamp:
            r = rim[j]
            est.add_wheel(WheelSample(ws[j], r[0], r[1], r[2]))
            j += 1
        est.add_imu(ImuSample(stamp, f[i], w[i]))
        if stamp >= next_peak:
            rss = proc_rss_mb()
            peak = max(peak, rss)
            next_peak += peak_ns
            if stamp >= next_sample:
                samples.append({'data_s': (stamp - t_first) * 1e-9, 'rss_mb': rss,
                                'wall_s': time.perf_counter() - t1})
                next_sample += sample_ns
    wall = time.perf_counter() - t1
    rss_end = proc_rss_mb()
    peak = max(peak, rss_end)
    if not samples or samples[-1]['data_s'] < (st[-1] - t_first) * 1e-9 - 1.0:
        samples.append({'data_s': (st[-1] - t_first) * 1e-9, 'rss_mb': rss_end, 'wall_s': wall})
    out = {'data_s': drive.duration_s, 'imu_steps': drive.n_imu, 'sim_s': sim_s, 'wall_s': wall,
           'steps_per_s': drive.n_imu / wall, 'realtime_ratio': drive.n_imu / wall / IMU_RATE_HZ,
           'rss_start_mb': rss_start, 'rss_after_sim_mb': rss_after_sim,
           'peak_rss_sim_mb': hwm_after_sim, 'rss_before_processing_mb': rss_before,
           'peak_rss_processing_mb': peak, 'peak_rss_process_mb': proc_rss_mb('self', 'VmHWM'),
           'samples': samples, 'aligned': bool(est.aligned),
           'health_level': int(est.health().level), 'counters': dict(est.counters)}
    Path(args.worker_out).write_text(json.dumps(out, indent=1))
    return 0


def memory_verdict(res: dict[str, Any], tolerance_mb: float = 5.0) -> tuple[float, str]:
    """Growth from the sample nearest 10 min of data (or the first) to the last, and a verdict."""
    samples = res['samples']
    ref = min(samples, key=lambda s: abs(s['data_s'] - 600.0)) if res['data_s'] > 600.0 \
        else samples[0]
    growth = samples[-1]['rss_mb'] - ref['rss_mb']
    flat = 'flat' if abs(growth) <= tolerance_mb else 'GROWING' if growth > 0 else 'shrinking'
    return growth, (f'{flat} ({growth:+.1f} MiB from {ref["data_s"]:.0f} s to '
                    f'{samples[-1]["data_s"]:.0f} s of data; tolerance {tolerance_mb:.0f} MiB)')


# --- scaling ------------------------------------------------------------------------------------

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
        imu, wheels = drive_records(drive)
        wall, _ = time_core(drive.params, imu, wheels, args.repeats)
        by_rate.append(_core_row(f'{rate:g} Hz', len(imu), drive.duration_s, wall, float(rate)))
        by_rate[-1]['rate_hz'] = float(rate)
        del imu, wheels, drive
    by_length = []
    for length in args.scaling_lengths:
        drive = chained_drive(float(length))
        imu, wheels = drive_records(drive)
        wall, _ = time_core(drive.params, imu, wheels, args.repeats)
        by_length.append(_core_row(f'{length:g} s', len(imu), drive.duration_s, wall))
        by_length[-1]['length_s'] = float(length)
        del imu, wheels, drive
    return {'by_rate': by_rate, 'by_length': by_length, 'repeats': args.repeats}


# --- printing -----------------------------------------------------------------------------------

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
    print(_table(('path', 'IMU steps', 'data s', 'wall s', 'steps/s', 'us/step', 'x real time'),
                 [(r['label'], r['imu_steps'], r['data_s'], r['wall_s'], r['steps_per_s'],
                   r['us_per_step'], r['realtime_ratio']) for r in res['rows']]))
    print('  x real time = steps/s / 250 Hz')


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
    print('  read = read_messages + header-stamp sort; estimation = adapter.on_message '
          '(convert + core + output messages + NaN guard); write = serialize + write + close')
    if res.get('pathfinder_skipped'):
        print(f'  s5t1 skipped: {res["pathfinder_skipped"]}')


def print_live(res: dict[str, Any]) -> None:
    e2e = res['end_to_end']
    print(f'\n== live node over DDS ({res["duration_s"]:g} s, IMU 250 Hz + JointState 10 Hz '
          f'with wall-clock stamps, ROS_DOMAIN_ID {res["domain_id"]}, LOCALHOST discovery)')
    rows = [
        ('IMU received / sent', f'{res["imu_received"]} / {res["imu_sent"]}'),
        ('JointState received / sent', f'{res["wheel_received"]} / {res["wheel_sent"]}'),
        ('IMU stamp gaps (node)', res['imu_stamp_gaps']),
        ('publisher late sends (max ms)',
         f'{res["publisher_late"]} ({res["publisher_max_late_ms"]:.2f})'),
        ('IMU callback p50 / p99 / max ms',
         (f'{_fmt(res["callback_p50_ms"])} / {_fmt(res["callback_p99_ms"])} / '
          f'{_fmt(res["callback_max_ms"])} (last {res["callback_window"]:.0f} callbacks)')),
        ('end-to-end IMU stamp -> odometry p50 / p99 / max ms',
         (f'{_fmt(e2e["p50_ms"])} / {_fmt(e2e["p99_ms"])} / {_fmt(e2e["max_ms"])} '
          f'({e2e["n"]} odometry messages)')),
        ('node CPU, % of one core', res.get('node_cpu_percent_of_one_core', float('nan'))),
        ('node RSS / peak MiB', (f'{_fmt(res.get("node_rss_mb", float("nan")))} / '
                                 f'{_fmt(res.get("node_peak_rss_mb", float("nan")))}')),
    ]
    print(_table(('figure', 'value'), rows, left=2))
    q = res['qos']
    print(f'  QoS: publisher IMU {q["imu_publisher"]}, JointState {q["wheel_publisher"]}; node '
          f'inputs {q["node_inputs"]}; listener {q["listener"]}')
    print(f'  odometry at the node default odometry_rate_hz = {res["odometry_rate_hz"]:g} '
          '(latency measured on those IMU stamps); counters from the node\'s final '
          '/diagnostics (watchdog STALE report)')


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


# --- command line -------------------------------------------------------------------------------

def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(',') if x.strip()]


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog='slip-estimator bench',
        description='Measure core throughput, replay speed, the live node over DDS, memory '
                    'and scaling on this machine.')
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


RUNNERS: dict[str, tuple[Callable[[argparse.Namespace], dict[str, Any]],
                         Callable[[dict[str, Any]], None]]] = {
    'core': (bench_core, print_core), 'replay': (bench_replay, print_replay),
    'live': (bench_live, print_live), 'memory': (bench_memory, print_memory),
    'scaling': (bench_scaling, print_scaling)}


def bench_main(argv: list[str] | None = None) -> int:
    """``slip-estimator bench`` (argv without the subcommand). Returns the exit status."""
    args = build_parser().parse_args(argv)
    if args.worker == 'live':
        return live_worker(args)
    if args.worker == 'memory':
        return memory_worker(args)
    only = [s.strip() for s in args.only.split(',') if s.strip()]
    unknown = [s for s in only if s not in SECTIONS]
    if unknown:
        print(f'slip-estimator bench: unknown section(s) {unknown}; choose from {SECTIONS}',
              file=sys.stderr)
        return 2
    report: dict[str, Any] = {'machine': machine_info(), 'argv': list(argv or sys.argv[1:])}
    print_machine(report['machine'])
    status = 0
    for name in SECTIONS:
        if name not in only:
            continue
        run, show = RUNNERS[name]
        t0 = time.perf_counter()
        try:
            res = run(args)
        except Exception as exc:  # noqa: BLE001 -- report and go on with the other sections
            print(f'\n== {name}: FAILED: {exc}', flush=True)
            report[name] = {'error': str(exc)}
            status = 1
            continue
        if name == 'memory':
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


if __name__ == '__main__':
    sys.exit(bench_main())
