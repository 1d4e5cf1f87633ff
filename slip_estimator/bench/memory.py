"""Memory: RSS of a fresh process pushing a long chained drive through the core."""
from __future__ import annotations

import argparse
import gc
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from slip_estimator.bench.machine import proc_rss_mb
from slip_estimator.bench.throughput import IMU_RATE_HZ, chained_drive
from slip_estimator.streams import feed, records


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

    t0 = time.perf_counter()
    rss_start = proc_rss_mb()
    drive = chained_drive(args.memory_duration_s)
    gc.collect()
    sim_s = time.perf_counter() - t0
    rss_after_sim = proc_rss_mb()
    hwm_after_sim = proc_rss_mb('self', 'VmHWM')

    est = SlipEstimator(drive.params)
    rss_before = proc_rss_mb()
    probe = _RssProbe(int(drive.data.imu_ns[0]), args.memory_sample_s, rss_before)
    t1 = probe.t_wall0 = time.perf_counter()
    feed(est, records(drive.data), probe, keep_estimates=False)
    wall = time.perf_counter() - t1
    samples, peak = probe.finish(int(drive.data.imu_ns[-1]), wall)
    data = drive.data
    out = {'data_s': data.duration_s, 'imu_steps': data.n_imu, 'sim_s': sim_s, 'wall_s': wall,
           'steps_per_s': data.n_imu / wall, 'realtime_ratio': data.n_imu / wall / IMU_RATE_HZ,
           'rss_start_mb': rss_start, 'rss_after_sim_mb': rss_after_sim,
           'peak_rss_sim_mb': hwm_after_sim, 'rss_before_processing_mb': rss_before,
           'peak_rss_processing_mb': peak, 'peak_rss_process_mb': proc_rss_mb('self', 'VmHWM'),
           'samples': samples, 'aligned': bool(est.aligned),
           'health_level': int(est.health().level), 'counters': dict(est.counters)}
    Path(args.worker_out).write_text(json.dumps(out, indent=1))
    return 0


class _RssProbe:
    """Called after each IMU sample: VmRSS every 10 s of data time (for the peak) and a
    sample every ``sample_s`` of data time."""

    def __init__(self, t_first_ns: int, sample_s: float, rss_mb: float) -> None:
        self.t_first_ns = t_first_ns
        self.sample_ns = int(sample_s * 1e9)
        self.peak_ns = int(min(10.0, sample_s) * 1e9)
        self.next_sample = self.next_peak = t_first_ns
        self.samples: list[dict[str, float]] = []
        self.peak = rss_mb
        self.t_wall0 = time.perf_counter()

    def __call__(self, sample: Any) -> None:
        stamp = sample.stamp_ns
        if stamp < self.next_peak:
            return
        rss = proc_rss_mb()
        self.peak = max(self.peak, rss)
        self.next_peak += self.peak_ns
        if stamp >= self.next_sample:
            self.samples.append({'data_s': (stamp - self.t_first_ns) * 1e-9, 'rss_mb': rss,
                                 'wall_s': time.perf_counter() - self.t_wall0})
            self.next_sample += self.sample_ns

    def finish(self, t_last_ns: int, wall_s: float) -> tuple[list[dict[str, float]], float]:
        """The samples (with one at the end of the data) and the peak, MiB."""
        rss_end = proc_rss_mb()
        end_s = (t_last_ns - self.t_first_ns) * 1e-9
        if not self.samples or self.samples[-1]['data_s'] < end_s - 1.0:
            self.samples.append({'data_s': end_s, 'rss_mb': rss_end, 'wall_s': wall_s})
        return self.samples, max(self.peak, rss_end)


def memory_verdict(res: dict[str, Any], tolerance_mb: float = 5.0) -> tuple[float, str]:
    """Growth from the sample nearest 10 min of data (or the first) to the last, and a verdict."""
    samples = res['samples']
    ref = min(samples, key=lambda s: abs(s['data_s'] - 600.0)) if res['data_s'] > 600.0 \
        else samples[0]
    growth = samples[-1]['rss_mb'] - ref['rss_mb']
    flat = 'flat' if abs(growth) <= tolerance_mb else 'GROWING' if growth > 0 else 'shrinking'
    return growth, (f'{flat} ({growth:+.1f} MiB from {ref["data_s"]:.0f} s to '
                    f'{samples[-1]["data_s"]:.0f} s of data; tolerance {tolerance_mb:.0f} MiB)')
