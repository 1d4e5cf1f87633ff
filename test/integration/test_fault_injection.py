"""Fault injection on a simulated drive and on the real test17run log, replayed end to end.

One fault at a time is injected into the input stream of the simulator's ``short`` scenario
(91 s: 12 s rest, cruise, arcs, medium/high/extreme slip, stops) and replayed with
:func:`slip_estimator.replay.replay_bag`. Unless said otherwise the fault starts at t = 22 s
(cruise at 0.5 m/s, low slip). Every case checks:

1. no NaN/Inf in any output and nothing dropped by the output guard;
2. outputs resume after the fault (slip with a known class, odometry);
3. ``/diagnostics`` names the fault (key names found by replaying and printing the
   diagnostics; see ``FAULTS``);
4. recovery: over the window ``[end + R, end + R + 10 s]`` (times of the clean run) the slip
   class agreement with the simulator truth (``/truth/slip``, ``vector.z``) is within
   ``MARGIN`` of the clean run's agreement over the same window. ``R`` is the stated recovery
   time of each case; the measured first-return time (smallest such R, 0.5 s steps) is printed
   with ``-s`` and written down in the case table.

The real log has no simulator truth; there the truth is the slip class from its RTK GNSS
(``truth.gnss_slip_truth``, paper eq. 30) and the same comparison with the clean replay is
made. Faults that ``replay_bag`` cannot express because it sorts by header stamp (arrival-order
jitter, a looped bag) are also fed in arrival order to the adapter, as the live node sees them.

The wheel dropout (STALE during the dropout), a looped bag (reset, then the clean run again)
and arrival-order jitter have their own tests. Runtime about 100 s on the 2-core machine
(13 replays of the 91 s scenario, 3 of the 70 s real log).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from helpers import mat_or_skip

from slip_estimator.bagio import read_messages
from slip_estimator.bench import faults as F
from slip_estimator.ros.topics import (
    TOPIC_IMU,
    TOPIC_JOINT_STATES,
    TOPIC_ODOMETRY,
    TOPIC_SLIP,
)
from slip_estimator.ros.finite import message_is_finite

NS = F.NS
G_MPS2 = 9.80665
WINDOW_S = 10.0
MARGIN = 0.1
"""Allowed drop of the class agreement against the clean run over the recovery window."""
T_FAULT_S = 22.0


# --- fixtures ----------------------------------------------------------------------------------
@dataclass
class Drive:
    """A clean input stream, its parameters, its clean replay and helpers for times."""

    stream: F.Stream
    params: object
    outputs: F.Outputs
    t0_ns: int
    workdir: Path

    def ns(self, t_s: float) -> int:
        """Stamp of time ``t_s`` after the first IMU sample."""
        return self.t0_ns + round(t_s * NS)

    def s(self, stamp_ns: int) -> float:
        return (stamp_ns - self.t0_ns) / NS


def check_finite(outputs: F.Outputs, summary=None) -> None:
    bad = [t for t, m in outputs if not message_is_finite(m)]
    assert not bad, f'non-finite outputs on {set(bad)}'
    if summary is not None:
        assert not summary.dropped_non_finite, summary.dropped_non_finite
        assert not any(k.endswith('core_error') for k in summary.rejected), summary.rejected


@pytest.fixture(scope='module')
def sim(tmp_path_factory) -> Drive:
    from slip_estimator.sim.bag import sim_params, write_sim_bag
    from slip_estimator.sim.rover import simulate
    from slip_estimator.sim.drives import short_scenario

    work = tmp_path_factory.mktemp('faults')
    result = simulate(short_scenario(0))
    write_sim_bag(result, work / 'sim')
    topics = {TOPIC_IMU, TOPIC_JOINT_STATES, F.TOPIC_TRUTH_SLIP}
    stream = F.tag_truth([(m.topic, m.msg, m.log_time_ns)
                          for m in read_messages(work / 'sim', topics)])
    params = sim_params(result)
    outputs, summary = F.run_replay(stream, params, work, 'clean')
    check_finite(outputs, summary)
    return Drive(stream, params, outputs, F.first_stamp_ns(stream), work)


@pytest.fixture(scope='module')
def clean_correct(sim):
    return F.correctness(sim.stream, sim.outputs)


# --- the fault table ---------------------------------------------------------------------------
def _diag_after(outputs: F.Outputs, t_ns: int) -> list[tuple[int, object]]:
    return [(s, st) for s, st in F.diagnostics(outputs) if s >= t_ns]


def _any_value(outputs: F.Outputs, t_ns: int, key: str, pred: Callable[[str], bool]) -> bool:
    return any(pred(F.key_values(st).get(key, '')) for _, st in _diag_after(outputs, t_ns))


def _any_message(outputs: F.Outputs, t_ns: int, text: str) -> bool:
    return any(text in st.message for _, st in _diag_after(outputs, t_ns))


def _positive(v: str) -> bool:
    try:
        return int(v) > 0
    except ValueError:
        return False


@dataclass(frozen=True)
class Fault:
    """One fault case: how to inject it, when it ends (clean-run time), how diagnostics name
    it, and the stated recovery time R (s after the end of the fault)."""

    name: str
    inject: Callable[[Drive], F.Stream]
    end_s: float
    named: Callable[[Drive, F.Outputs], bool]
    recovery_s: float
    doc: str
    params_changes: tuple = ()


def _t(drive: Drive, t_s: float) -> int:
    return drive.ns(t_s)


T = T_FAULT_S
FAULTS = [
    Fault('imu_dropout_0.5s',
          lambda d: F.drop(d.stream, _t(d, T), _t(d, T + 0.5), [TOPIC_IMU]), T + 0.5,
          lambda d, o: (_any_value(o, _t(d, T), 'imu_gaps', _positive)
                        and _any_value(o, _t(d, T), '/imu/data stamp_gaps', _positive)
                        and _any_message(o, _t(d, T), 'IMU gap of 0.50 s')),
          10.0, 'keys imu_gaps, /imu/data stamp_gaps; message "IMU gap of 0.50 s"'),
    Fault('imu_dropout_30s',
          lambda d: F.drop(d.stream, _t(d, T), _t(d, T + 30.0), [TOPIC_IMU]), T + 30.0,
          lambda d, o: (_any_value(o, _t(d, T), 'imu_gaps', _positive)
                        and _any_value(o, _t(d, T), 'recoveries', _positive)
                        and _any_message(o, _t(d, T), 'IMU gap of 30.00 s')),
          10.0, 'keys imu_gaps, recoveries; message "IMU gap of 30.00 s ... velocity '
          're-initialised"'),
    Fault('nan_burst_0.2s',
          lambda d: F.corrupt_imu(d.stream, _t(d, T), _t(d, T + 0.2)), T + 0.2,
          lambda d, o: (_any_value(o, _t(d, T), '/imu/data rejected non_finite',
                                   lambda v: v == '50')
                        and _any_message(o, _t(d, T), 'input message(s) rejected')),
          10.0, 'key "/imu/data rejected non_finite" = 50; message "50 input message(s) '
          'rejected"'),
    Fault('accel_spike_50g',
          lambda d: F.spike(d.stream, _t(d, T), (50.0 * G_MPS2, 0.0, 0.0)), T,
          lambda d, o: _any_value(o, _t(d, T), 'imu_saturated', _positive),
          10.0, 'one sample of +50 g on the forward axis of an IMU whose declared range '
          '(accel_range_mps2) is 50 g: key imu_saturated, message "IMU at its measurement '
          'range (clipping)"',
          (('accel_range_mps2', 50.0 * G_MPS2),)),
    Fault('duplicated_reordered',
          lambda d: F.reorder(F.duplicate(d.stream, np.random.default_rng(0), 0.1),
                              np.random.default_rng(1), 0.1, 5, _t(d, T), _t(d, T + 5.0)),
          T + 5.0,
          lambda d, o: (_any_value(o, _t(d, 0.0), '/imu/data rejected non_monotonic',
                                   _positive)
                        and _any_value(o, _t(d, 0.0), 'wheel_rejected', _positive)),
          0.0, '10 % of all sensor messages twice, 10 % delivered up to 5 places late in '
          '22-27 s; keys "/imu/data rejected non_monotonic", wheel_rejected'),
    Fault('forward_jump_10s',
          lambda d: F.shift_stamps(d.stream, _t(d, T), 10 * NS), T,
          lambda d, o: (_any_value(o, _t(d, T), 'imu_gaps', _positive)
                        and _any_message(o, _t(d, T), 'IMU gap of 10.00 s')),
          10.0, 'every stamp from 22 s on +10 s (truth too); keys imu_gaps, '
          '/imu/data stamp_gaps; message "IMU gap of 10.00 s"'),
    Fault('wheel_clock_drift_2ms_per_s',
          lambda d: F.drift(d.stream, 2e-3, topics=(TOPIC_JOINT_STATES, F.TOPIC_TRUTH_SLIP)),
          0.0, lambda d, o: True, 0.0,
          'wheel (and wheel-stamped truth) clock 2 ms/s fast from the start: 0.18 s ahead at '
          'the end; not detectable by design and not named'),
]


def recovery_window(clean: tuple[np.ndarray, np.ndarray], faulty: tuple[np.ndarray, np.ndarray],
                    start_s: float) -> tuple[float, float]:
    """(clean, faulty) agreement over ``[start_s, start_s + WINDOW_S)``."""
    return (F.agreement(*clean, start_s, start_s + WINDOW_S),
            F.agreement(*faulty, start_s, start_s + WINDOW_S))


def first_return_s(clean, faulty, end_s: float, limit_s: float) -> float:
    """Measured recovery: the smallest R (0.5 s steps) whose window is within MARGIN."""
    for r in np.arange(0.0, limit_s, 0.5):
        a_clean, a_fault = recovery_window(clean, faulty, end_s + r)
        if a_fault >= a_clean - MARGIN:
            return float(r)
    return math.inf


# --- simulated drive ---------------------------------------------------------------------------
XFAIL: dict[str, str] = {}  # fault name -> reason, for a case that is a known defect
CASES = [pytest.param(f, id=f.name, marks=[pytest.mark.xfail(strict=True, reason=XFAIL[f.name])]
                      if f.name in XFAIL else []) for f in FAULTS]


@pytest.mark.parametrize('fault', CASES)
def test_fault_on_simulated_drive(sim, clean_correct, fault):
    """Each row of FAULTS (see the module docstring). Measured recovery (first return within
    MARGIN; 0.5 s steps) with the re-levelling recovery (issue 11): IMU dropout 0.5 s: 0 s;
    IMU dropout 30 s: 3 s (26.5 s before: the attitude kept across the gap was 17 deg off in
    pitch, the INS diverged again and again); NaN burst 0.2 s: 0 s; 50 g spike: 0 s (6 s
    before commit 899fbbd); duplicated/reordered: 0 s; forward jump 10 s: 3.5 s (2 s before
    the re-levelling: one more window of slip unknown); wheel clock drift 2 ms/s: 0 s. Stated bound R: 10 s for the
    faults that disturb the INS, 0 s for the others."""
    stream = fault.inject(sim)
    params = sim.params.replace(**dict(fault.params_changes))
    outputs, summary = F.run_replay(stream, params, sim.workdir, fault.name)
    check_finite(outputs, summary)
    # Outputs resume: a known slip class and odometry after the end of the fault (in the
    # stamps of the faulty stream, which a forward jump moved).
    end_ns = max(F.header_stamp_ns(m) for t, m, _ in stream if t == TOPIC_IMU) - 15 * NS
    known_after = [c for s, c, _ in F.slip_statuses(outputs) if s >= end_ns and c >= 0]
    assert known_after, 'no known slip class in the last 15 s'
    assert any(t == TOPIC_ODOMETRY and F.header_stamp_ns(m) >= end_ns for t, m in outputs)
    assert fault.named(sim, outputs), f'/diagnostics does not name {fault.name}: ' \
        f'{F.diagnostic_values(outputs)}'
    faulty = F.correctness(stream, outputs)
    measured = first_return_s(clean_correct, faulty, fault.end_s, 60.0)
    a_clean, a_fault = recovery_window(clean_correct, faulty, fault.end_s + fault.recovery_s)
    print(f'\n{fault.name}: measured recovery {measured} s; agreement over '
          f'[end+{fault.recovery_s:.0f}, +{WINDOW_S:.0f}] s: {a_fault:.2f} vs clean {a_clean:.2f}; '
          f'whole run {faulty[1].mean():.2f} vs {clean_correct[1].mean():.2f}')
    assert a_fault >= a_clean - MARGIN, (
        f'{fault.name}: class agreement {a_fault:.2f} vs {a_clean:.2f} clean over '
        f'[{fault.end_s + fault.recovery_s:.1f}, +{WINDOW_S:.0f}] s (measured recovery '
        f'{measured} s)')


def test_wheel_dropout_reports_stale_not_a_guess(sim, clean_correct):
    """3 s without wheel messages from 22 s: every slip status stamped in the dropout (after
    wheel_timeout_s) is STALE / 'unknown', there is at least one per timeout, no slip_ratio
    companion is published for it, and known classes resume at once (measured recovery 0 s)."""
    start, end = sim.ns(T), sim.ns(T + 3.0)
    stream = F.drop(sim.stream, start, end, [TOPIC_JOINT_STATES])
    outputs, summary = F.run_replay(stream, sim.params, sim.workdir, 'wheel_dropout')
    check_finite(outputs, summary)
    timeout_ns = int(sim.params.wheel_timeout_s * NS)
    inside = [(s, c, st) for s, c, st in F.slip_statuses(outputs)
              if start + timeout_ns < s < end]
    assert len(inside) >= int(3.0 / sim.params.wheel_timeout_s) - 2, inside
    for s, c, st in inside:
        assert c == -1 and st.message == 'unknown' and st.level == b'\x03', (sim.s(s), st)
    ratios = [m for t, m in outputs if t == '/slip_estimator/slip_ratio'
              and start + timeout_ns < F.header_stamp_ns(m) < end]
    assert not ratios
    # Named: the unknown reports are counted and the wheel rate drops in /diagnostics.
    clean_unknown = F.counter(F.diagnostic_values(sim.outputs), 'slip_unknown')
    assert F.counter(F.diagnostic_values(outputs), 'slip_unknown') > clean_unknown
    rates = [float(F.key_values(st).get('/joint_states rate_hz', 'nan'))
             for s, st in F.diagnostics(outputs) if start < s <= end + NS]
    assert min(rates) < 5.0, rates
    faulty = F.correctness(stream, outputs)
    a_clean, a_fault = recovery_window(clean_correct, faulty, T + 3.0)
    assert a_fault >= a_clean - MARGIN


def test_bag_loop_resets_and_repeats_the_clean_run(sim):
    """A bag played again from its start at 60 s (clock 60 s back), in arrival order as the
    live node sees it: one node reset, then the second pass is the clean run again, message for
    message (slip statuses and odometry), i.e. recovery 0 s and nothing leaks across the
    reset. replay_bag (arrival order, reorder window flushed at the jump) sees the same."""
    stream = F.loop(sim.stream, sim.ns(60.0))
    n_first = len(stream) - len(sim.stream)
    first, adapter = F.run_adapter(stream[:n_first], sim.params)
    second, adapter = F.run_adapter(stream[n_first:], sim.params, adapter)
    outputs = first + second
    check_finite(outputs)
    assert adapter.counters.resets == 1
    assert not adapter.counters.dropped_non_finite
    # After the reset the outputs are the clean run's, field for field.
    for topic in (TOPIC_SLIP, TOPIC_ODOMETRY):
        again = [m for t, m in second if t == topic]
        clean = [m for t, m in sim.outputs if t == topic]
        assert len(again) == len(clean), topic
        assert again == clean, topic
    values = F.diagnostic_values(outputs)
    assert values['node_resets'] == '1'

    replayed, summary = F.run_replay(stream, sim.params, sim.workdir, 'loop')
    check_finite(replayed, summary)
    assert summary.resets == 1
    assert F.slip_classes(replayed) == F.slip_classes(outputs)


def test_arrival_order_jitter_live_path(sim, clean_correct):
    """Duplicated (10 %) and late (10 %, up to 5 places) messages in 22-27 s fed in ARRIVAL
    order to the adapter (replay_bag would sort the jitter away): late IMU samples are rejected
    as non_monotonic, late wheel samples by the core (wheel_rejected); no NaN, and the class
    agreement over 27-37 s stays within MARGIN of the clean run (measured recovery 0 s)."""
    stream = F.reorder(F.duplicate(sim.stream, np.random.default_rng(0), 0.1,
                                   topics=(TOPIC_IMU, TOPIC_JOINT_STATES)),
                       np.random.default_rng(1), 0.1, 5, sim.ns(T), sim.ns(T + 5.0))
    outputs, adapter = F.run_adapter(stream, sim.params)
    check_finite(outputs)
    assert not adapter.counters.dropped_non_finite
    values = F.diagnostic_values(outputs)
    assert F.counter(values, '/imu/data rejected non_monotonic') > 0
    assert F.counter(values, 'wheel_rejected') > 0
    faulty = F.correctness(stream, outputs)
    a_clean, a_fault = recovery_window(clean_correct, faulty, T + 5.0)
    assert a_fault >= a_clean - MARGIN


def test_fault_tables_can_fail(sim, clean_correct):
    """The recovery measure is not a tautology: an output stream with every slip class shifted
    by one disagrees with the truth and fails the margin."""
    shifted = []
    for t, m in sim.outputs:
        if t == TOPIC_SLIP:
            import copy
            m = copy.deepcopy(m)
            for kv in m.status[0].values:
                if kv.key == 'slip_class' and kv.value != 'unknown':
                    kv.value = str((int(kv.value) + 1) % 5)
        shifted.append((t, m))
    faulty = F.correctness(sim.stream, shifted)
    a_clean, a_fault = recovery_window(clean_correct, faulty, T)
    assert a_fault < a_clean - MARGIN
    assert first_return_s(clean_correct, faulty, T, 30.0) == math.inf


# --- real log ----------------------------------------------------------------------------------
@dataclass
class RealLog:
    drive: Drive
    truth: dict[int, int]
    """Wheel stamp -> slip class from RTK GNSS (truth.gnss_slip_truth, paper eq. 30)."""


@pytest.fixture(scope='module')
def pathfinder(tmp_path_factory) -> RealLog:
    mat = mat_or_skip('test17run')
    from slip_estimator.truth import gnss_slip_truth
    from slip_estimator.pathfinder import gnss_enu, import_pathfinder, rim_speed_mps

    work = tmp_path_factory.mktemp('pathfinder')
    log, _, params = import_pathfinder(mat, work / 't17')
    stream = [(m.topic, m.msg, m.log_time_ns)
              for m in read_messages(work / 't17', {TOPIC_IMU, TOPIC_JOINT_STATES})]
    wheel_ns = np.array([F.header_stamp_ns(m) for t, m, _ in stream if t == TOPIC_JOINT_STATES])
    # Wheel stamps lag the motion by 0.1-0.2 s on this log (README): compare with GNSS 0.15 s
    # earlier.
    gt = gnss_slip_truth(wheel_ns, rim_speed_mps(log), log.gnss_t_s, gnss_enu(log),
                         wheel_time_offset_s=-0.15)
    truth = {int(t): int(c) for t, c in zip(gt.stamp_ns, gt.slip_class) if c >= 0}
    outputs, summary = F.run_replay(stream, params, work, 'clean')
    check_finite(outputs, summary)
    return RealLog(Drive(stream, params, outputs, F.first_stamp_ns(stream), work), truth)


def _truth_agreement(real: RealLog, outputs: F.Outputs, start_s: float, end_s: float) -> float:
    est = F.slip_classes(outputs)
    t0 = real.drive.t0_ns
    keys = [s for s in real.truth if start_s <= (s - t0) / NS < end_s]
    return float(np.mean([est.get(s, -2) == real.truth[s] for s in keys])) if keys else math.nan


@pytest.mark.parametrize('name', ['imu_dropout_0.5s', 'wheel_dropout_3s'])
def test_fault_on_real_log(pathfinder, name):
    """test17run (≈5 s rest, ≈50 s straight drive at ≈0.7 m/s, ≈15 s rest), fault at 25 s of
    the log (mid-drive). Truth: RTK GNSS slip classes. No NaN, outputs resume, the fault is
    named, and over [end + 10 s, end + 20 s] the class agreement with the GNSS truth is within
    MARGIN of the clean replay's. Measured recovery (estimator at commit 88b1d40): 0 s for both.
    Before commit 899fbbd (hold aid re-measuring on any discrepancy) the same faults took 28 s
    (IMU dropout: body speed 1.0-1.4 m/s, classes medium..extreme instead of low until the
    stop) and 25 s (wheel dropout) to recover: this test caught that."""
    d = pathfinder.drive
    t = 25.0
    if name == 'imu_dropout_0.5s':
        stream, end = F.drop(d.stream, d.ns(t), d.ns(t + 0.5), [TOPIC_IMU]), t + 0.5
    else:
        stream, end = F.drop(d.stream, d.ns(t), d.ns(t + 3.0), [TOPIC_JOINT_STATES]), t + 3.0
    outputs, summary = F.run_replay(stream, d.params, d.workdir, name)
    check_finite(outputs, summary)
    known_after = [c for s, c, _ in F.slip_statuses(outputs) if s >= d.ns(end + 1.0) and c >= 0]
    assert known_after
    if name == 'imu_dropout_0.5s':
        assert _any_value(outputs, d.ns(t), 'imu_gaps', _positive)
        assert _any_message(outputs, d.ns(t), 'IMU gap of 0.50 s')
    else:
        stale = [c for s, c, _ in F.slip_statuses(outputs) if d.ns(t + 0.6) < s < d.ns(t + 3.0)]
        assert stale and all(c == -1 for c in stale)
    measured = math.inf
    for r in np.arange(0.0, 40.0, 0.5):
        if _truth_agreement(pathfinder, outputs, end + r, end + r + WINDOW_S) >= \
                _truth_agreement(pathfinder, d.outputs, end + r, end + r + WINDOW_S) - MARGIN:
            measured = float(r)
            break
    a_clean = _truth_agreement(pathfinder, d.outputs, end + 10.0, end + 10.0 + WINDOW_S)
    a_fault = _truth_agreement(pathfinder, outputs, end + 10.0, end + 10.0 + WINDOW_S)
    print(f'\nreal log {name}: measured recovery {measured} s; GNSS-truth agreement over '
          f'[end+10, +10] s: {a_fault:.2f} vs clean {a_clean:.2f}')
    assert a_fault >= a_clean - MARGIN
