"""Soak test: an hour of simulated driving with seeded random faults, through the node adapter.

``python -m slip_estimator.bench.soak --minutes 60 --seed 0``   (about 6-8 min wall on 2 cores)
``python -m slip_estimator.bench.soak --minutes 2``             (quick check, < 1 min)

Not part of the test suite. The drive is a chain of the simulator's ``default`` scenario (6.5 min
each, truth seeds ``seed, seed+1, ...``; the last one cut to the requested length), stamps
continuing from one chunk to the next. Every 45-75 s of data after the first 20 s of a chunk one
fault is drawn (seeded) from ``FAULT_KINDS`` and injected with the mutators of
:mod:`slip_estimator.bench.faults`. Each chunk is fed in arrival order to TWO adapters: a clean
one and the faulty one, so every fault has a no-fault baseline over the same window.

Reported: RSS (VmRSS from /proc/self/status) sampled every simulated minute and its peak;
per fault kind the number injected and the number detected (the fault's diagnostic counter in
``/diagnostics`` rose between the report before the fault and the first report >= 2 s after
it, or, for a wheel dropout, STALE slip statuses inside the dropout); recovery (first delay
after the fault, 1 s steps, from which the slip class agreement with the simulator truth over
10 s is within 0.1 of the clean run's over the same window; ``inf`` = not within the chunk):
median and max per kind; NaN/Inf seen in any output and non-finite outputs the guard dropped
(both must be 0); total wall time. Exit status 1 if any NaN was seen or a fault went undetected.
"""
from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from collections import Counter, defaultdict
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import Vector3Stamped
from sensor_msgs.msg import Imu, JointState

from slip_estimator.bench import faults as F
from slip_estimator.bench.machine import proc_rss_mb
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.finite import message_is_finite
from slip_estimator.ros.stamps import ns_to_stamp
from slip_estimator.ros.topics import TOPIC_IMU, TOPIC_JOINT_STATES
from slip_estimator.sim.bag import sim_params
from slip_estimator.sim.drives import default_scenario
from slip_estimator.sim.rover import simulate
from slip_estimator.sim.scenario import WHEEL_JOINT_NAMES

NS = F.NS
G_MPS2 = 9.80665
WINDOW_S = 10.0
MARGIN = 0.1
FAULT_KINDS = ('imu_dropout_0.5s', 'imu_dropout_30s', 'wheel_dropout_3s', 'nan_burst',
               'accel_spike_50g', 'dup_reorder', 'forward_jump_10s', 'backward_jump_60s',
               'zero_stamps', 'imu_flood')
"""Fault kinds drawn uniformly. The IMU's declared range is set to 50 g so that the spike
saturates it (counted as clipping)."""

DETECTION_KEY = {
    'imu_dropout_0.5s': 'imu_gaps', 'imu_dropout_30s': 'imu_gaps',
    'nan_burst': '/imu/data rejected non_finite', 'accel_spike_50g': 'imu_saturated',
    'dup_reorder': '/imu/data rejected non_monotonic', 'forward_jump_10s': 'imu_gaps',
    'backward_jump_60s': 'node_resets', 'zero_stamps': '/imu/data rejected zero_stamp',
    'imu_flood': '/imu/data rejected non_monotonic',
}
"""The /diagnostics counter that must rise for each fault (wheel dropout: STALE statuses)."""


def chunk_stream(result, offset_ns: int) -> F.Stream:
    """IMU, joint states and truth slip of a simulation, stamps shifted by ``offset_ns``,
    in stamp order (IMU first at equal stamps), log time = stamp."""
    imu_ns = result.stamps_ns(result.imu_t_s) - result.config.epoch_ns + offset_ns
    wheel_ns = result.stamps_ns(result.wheel_t_s) - result.config.epoch_ns + offset_ns
    items: list[tuple[int, int, str, object]] = []
    for i, ns in enumerate(imu_ns.tolist()):
        m = Imu()
        m.header.stamp = ns_to_stamp(ns)
        m.header.frame_id = 'imu_link'
        m.orientation_covariance[0] = -1.0
        f, w = result.f_ib_imu[i], result.omega_ib_imu[i]
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = map(float, f)
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = map(float, w)
        items.append((ns, 0, TOPIC_IMU, m))
    for j, ns in enumerate(wheel_ns.tolist()):
        m = JointState()
        m.header.stamp = ns_to_stamp(ns)
        m.name = list(WHEEL_JOINT_NAMES)
        m.velocity = [float(a) for a in result.wheel_rate_rps[j]]
        m.position = [float(a) for a in result.wheel_angle_rad[j]]
        items.append((ns, 1, TOPIC_JOINT_STATES, m))
        t = Vector3Stamped()
        t.header.stamp = ns_to_stamp(ns)
        t.vector.z = float(result.slip_class[j])
        items.append((ns, 2, F.TOPIC_TRUTH_SLIP, t))
    items.sort(key=lambda it: (it[0], it[1]))
    return [(topic, msg, ns) for ns, _, topic, msg in items]


@dataclass
class Injected:
    kind: str
    start_s: float   # chunk time (s since the chunk's first IMU stamp, clean clock)
    end_s: float
    chunk: int


def _span(stream: F.Stream, start_ns: int, end_ns: int) -> tuple[int, int]:
    """Index range of the contiguous run of messages stamped in ``[start_ns, end_ns)`` (the
    stream is in stamp order there)."""
    idx = [i for i, it in enumerate(stream) if start_ns <= F.header_stamp_ns(it[1]) < end_ns]
    return (idx[0], idx[-1] + 1) if idx else (0, 0)


def inject(stream: F.Stream, kind: str, t0_ns: int, start_s: float,
           rng: np.random.Generator) -> tuple[F.Stream, float]:
    """Apply one fault at ``start_s``; return the new stream and the fault's end (s)."""
    def ns(t: float) -> int:
        return t0_ns + round(t * NS)
    s = start_s
    if kind == 'imu_dropout_0.5s':
        return F.drop(stream, ns(s), ns(s + 0.5), [TOPIC_IMU]), s + 0.5
    if kind == 'imu_dropout_30s':
        return F.drop(stream, ns(s), ns(s + 30.0), [TOPIC_IMU]), s + 30.0
    if kind == 'wheel_dropout_3s':
        return F.drop(stream, ns(s), ns(s + 3.0), [TOPIC_JOINT_STATES]), s + 3.0
    if kind == 'nan_burst':
        return F.corrupt_imu(stream, ns(s), ns(s + 0.2)), s + 0.2
    if kind == 'accel_spike_50g':
        return F.spike(stream, ns(s), (50.0 * G_MPS2, 0.0, 0.0)), s
    if kind == 'dup_reorder':
        lo, hi = _span(stream, ns(s), ns(s + 5.0))
        part = F.reorder(F.duplicate(stream[lo:hi], rng, 0.1, (TOPIC_IMU, TOPIC_JOINT_STATES)),
                         rng, 0.1, 5)
        return stream[:lo] + part + stream[hi:], s + 5.0
    if kind == 'forward_jump_10s':
        return F.shift_stamps(stream, ns(s), 10 * NS), s
    if kind == 'backward_jump_60s':
        # The last 60 s are delivered again (clock back by 60 s), then the drive goes on.
        lo, hi = _span(stream, ns(max(0.0, s - 60.0)), ns(s))
        lo = 0 if s <= 60.0 else lo
        return stream[:hi] + stream[lo:hi] + stream[hi:], s
    if kind == 'zero_stamps':
        lo, hi = _span(stream, ns(s), ns(s + 1.0))
        return (stream[:lo] + F.zero_stamps(stream[lo:hi], rng, 0.2, (TOPIC_IMU,))
                + stream[hi:]), s + 1.0
    if kind == 'imu_flood':
        return F.flood(stream, ns(s), 2000), s
    raise ValueError(kind)


def feed(adapter: SlipEstimatorAdapter, stream: F.Stream, stats: Counter,
         rss: list[tuple[float, float]] | None = None, minute0: float = 0.0) -> F.Outputs:
    """Feed ``stream`` in arrival order; count NaN outputs; sample RSS every 60 s of data
    (IMU messages) into ``rss`` as (data minute, MB)."""
    out: F.Outputs = []
    n_imu = 0
    for topic, msg, _ in stream:
        if rss is not None and topic == TOPIC_IMU:
            n_imu += 1
            if n_imu % 15000 == 0:  # 60 s at 250 Hz
                rss.append((minute0 + n_imu / 15000.0, proc_rss_mb()))
        for item in adapter.on_message(topic, msg):
            if not message_is_finite(item[1]):
                stats['nan_outputs'] += 1
            out.append(item)
    return out


def detected(kind: str, outputs: F.Outputs, start_ns: int, end_ns: int) -> bool:
    """The fault's counter rose between the last report before ``start_ns`` and the first
    report 2 s after ``end_ns`` (stamps of the faulty stream)."""
    if kind == 'wheel_dropout_3s':
        return any(c == -1 and start_ns + NS < s < end_ns
                   for s, c, _ in F.slip_statuses(outputs))
    key = DETECTION_KEY[kind]
    diags = F.diagnostics(outputs)
    before = [F.counter(F.key_values(st), key) for s, st in diags if s < start_ns]
    after = [F.counter(F.key_values(st), key) for s, st in diags if s >= end_ns + 2 * NS]
    return bool(after) and after[0] > (before[-1] if before else 0)


def recovery_s(clean: tuple, faulty: tuple, end_s: float, limit_s: float) -> float:
    for d in np.arange(0.0, limit_s, 1.0):
        a, b = end_s + d, end_s + d + WINDOW_S
        base = F.agreement(*clean, a, b)
        if math.isnan(base):
            break
        if F.agreement(*faulty, a, b) >= base - MARGIN:
            return float(d)
    return math.inf


def draw_faults(stream: F.Stream, rng: np.random.Generator, t0_ns: int, duration_s: float,
                chunk: int) -> tuple[F.Stream, list[Injected]]:
    """The faults of one chunk: every 45-75 s from 20 s, leaving 25 s for recovery."""
    faults: list[Injected] = []
    t = 20.0 + float(rng.uniform(0.0, 25.0))
    while t < duration_s - 25.0:
        kind = str(rng.choice(FAULT_KINDS))
        if kind == 'imu_dropout_30s' and t + 30.0 > duration_s - 25.0:
            kind = 'imu_dropout_0.5s'
        stream, end = inject(stream, kind, t0_ns, t, rng)
        faults.append(Injected(kind, t, end, chunk))
        t = end + float(rng.uniform(45.0, 75.0))
    return stream, faults


@dataclass
class Score:
    """Detections, misses and recovery times per fault kind, over all chunks."""

    found: Counter
    missed: list[Injected]
    recoveries: dict[str, list[float]]

    def add(self, faults: list[Injected], t0_ns: int, duration_s: float, resets_seen: int,
            out_fault: F.Outputs, clean_ok: tuple, fault_ok: tuple) -> None:
        """Score the faults of one chunk."""
        for k, inj in enumerate(faults):
            # Stamps of the faulty stream: earlier forward jumps moved them.
            jumps = sum(10 * NS for f in faults[:k] if f.kind == 'forward_jump_10s')
            start_ns = t0_ns + int(inj.start_s * NS) + jumps
            end_ns = t0_ns + int(inj.end_s * NS) + jumps + (
                10 * NS if inj.kind == 'forward_jump_10s' else 0)
            if inj.kind == 'backward_jump_60s':
                # Stamps go back: one node reset per jump (counted over the chunk).
                if resets_seen > 0:
                    self.found[inj.kind] += 1
                    resets_seen -= 1
                else:
                    self.missed.append(inj)
            elif detected(inj.kind, out_fault, start_ns, end_ns):
                self.found[inj.kind] += 1
            else:
                self.missed.append(inj)
            nxt = faults[k + 1].start_s if k + 1 < len(faults) else duration_s
            self.recoveries[inj.kind].append(recovery_s(clean_ok, fault_ok, inj.end_s,
                                                        nxt - inj.end_s - WINDOW_S + 1.0))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--minutes', type=float, default=60.0, help='simulated driving, min')
    ap.add_argument('--seed', type=int, default=0, help='scenario and fault seed')
    args = ap.parse_args(argv)
    wall0 = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    total_s = args.minutes * 60.0
    clean_ad: SlipEstimatorAdapter | None = None
    fault_ad: SlipEstimatorAdapter | None = None
    stats: Counter = Counter()
    injected: list[Injected] = []
    score = Score(Counter(), [], defaultdict(list))
    rss_samples: list[tuple[float, float]] = [(0.0, proc_rss_mb())]
    chunk_rss: list[float] = []
    done_s = 0.0
    offset_ns = 1_700_000_000 * NS
    chunk = 0
    while done_s < total_s - 30.0:
        cfg = default_scenario(args.seed + chunk)
        remaining = total_s - done_s
        if remaining < cfg.total_duration_s:
            cfg = cfg.replace(duration_s=max(30.0, remaining))
        result = simulate(cfg)
        params = sim_params(result).replace(accel_range_mps2=50.0 * G_MPS2)
        if clean_ad is None:
            clean_ad, fault_ad = SlipEstimatorAdapter(params), SlipEstimatorAdapter(params)
        clean_stream = F.tag_truth(chunk_stream(result, offset_ns))
        t0_ns = F.first_stamp_ns(clean_stream)
        duration = cfg.total_duration_s
        stream, chunk_faults = draw_faults(clean_stream, rng, t0_ns, duration, chunk)
        # Stamps after a forward jump stay shifted: the next chunk continues from the last one.
        last_ns = max(F.header_stamp_ns(m) for tp, m, _ in stream if tp == TOPIC_IMU)
        resets_before = fault_ad.counters.resets
        out_clean = feed(clean_ad, clean_stream, stats)
        out_fault = feed(fault_ad, stream, stats, rss_samples, done_s / 60.0)
        resets_seen = fault_ad.counters.resets - resets_before
        clean_ok = F.correctness(clean_stream, out_clean)
        fault_ok = F.correctness(stream, out_fault)
        score.add(chunk_faults, t0_ns, duration, resets_seen, out_fault, clean_ok, fault_ok)
        injected += chunk_faults
        del out_clean, out_fault, stream, clean_stream
        gc.collect()
        offset_ns = last_ns + 4_000_000
        done_s += duration
        chunk += 1
        chunk_rss.append(proc_rss_mb())
        rss_samples.append((done_s / 60.0, chunk_rss[-1]))
        print(f'  chunk {chunk}: {done_s / 60.0:5.1f} min of data, {len(chunk_faults)} faults, '
              f'RSS {rss_samples[-1][1]:.0f} MB, wall {time.perf_counter() - wall0:.0f} s',
              flush=True)

    return report(args.seed, done_s, time.perf_counter() - wall0, injected, score,
                  stats, rss_samples, chunk_rss, clean_ad, fault_ad)


def report(seed: int, done_s: float, wall: float, injected: list[Injected], score: Score,
           stats: Counter, rss_samples: list[tuple[float, float]], chunk_rss: list[float],
           clean_ad: SlipEstimatorAdapter, fault_ad: SlipEstimatorAdapter) -> int:
    """Print the soak figures; exit status 1 on any NaN or undetected fault."""
    found, missed, recoveries = score.found, score.missed, score.recoveries
    faults = fault_ad.counters
    dropped = (sum(faults.dropped_non_finite.values())
               + sum(clean_ad.counters.dropped_non_finite.values()))
    core_errors = sum(n for (_, r), n in faults.rejected.items() if r == 'core_error')
    print(f'\nsoak: {done_s / 60.0:.1f} min of simulated driving, seed {seed}, '
          f'{len(injected)} faults, wall {wall:.0f} s ({done_s / wall:.1f}x real time for two '
          f'adapters)')
    print('RSS MB by data minute: ' + ', '.join(f'{m:.1f}:{r:.0f}' for m, r in rss_samples))
    print(f'RSS peak {max(r for _, r in rss_samples):.0f} MB; after each chunk (gc): '
          + ', '.join(f'{r:.0f}' for r in chunk_rss) + ' MB')
    print(f'NaN/Inf in outputs: {stats["nan_outputs"]}; non-finite outputs dropped by the '
          f'guard: {dropped}; core errors: {core_errors}')
    print(f'{"fault":20s} {"injected":>8s} {"detected":>8s} {"recovery median s":>18s} '
          f'{"max s":>6s}  (inf = not within agreement margin before the next fault)')
    kinds = Counter(i.kind for i in injected)
    undetected = 0
    for kind in FAULT_KINDS:
        if not kinds[kind]:
            continue
        rec = recoveries[kind]
        undetected += kinds[kind] - found[kind]
        print(f'{kind:20s} {kinds[kind]:8d} {found[kind]:8d} {float(np.median(rec)):18.1f} '
              f'{max(rec):6.1f}')
    if missed:
        print('not detected (chunk, start s, kind; the core counters restart at a node reset, '
              'so a core-counted fault after a backward jump in the same chunk can read as '
              'missed): ' + ', '.join(f'({m.chunk}, {m.start_s:.0f}, {m.kind})' for m in missed))
    print(f'fault counters (faulty adapter, last report): '
          f'node_resets {faults.resets}, imu stamp gaps {faults.imu_stamp_gaps}, rejected '
          f'{dict(sorted((f"{t} {r}", n) for (t, r), n in faults.rejected.items()))}')
    return 1 if stats['nan_outputs'] or dropped or undetected else 0


if __name__ == '__main__':
    sys.exit(main())
