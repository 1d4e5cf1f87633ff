"""Fault injection for message streams, and the measurements the fault tests make on replays.

A *stream* is a list of ``(topic, message, log_time_ns)`` in arrival (log-time) order, the
format of the fault-injection tests and of :mod:`slip_estimator.bench.soak`. Every mutator
returns a NEW list and never changes the messages of its input (a message it alters is copied
first), so one clean stream can be reused for many faults. Times are integer nanoseconds of the
header stamps (``stamp_ns``); windows are half-open ``[start_ns, end_ns)``.

Mutators: :func:`drop`, :func:`duplicate`, :func:`reorder`, :func:`corrupt_imu`,
:func:`corrupt_wheels`, :func:`spike`, :func:`zero_stamps`, :func:`shift_stamps` (forward or
backward clock jump), :func:`loop` (bag played again from its start), :func:`drift` (one
sensor's clock running fast against the other), :func:`flood`.

Runners: :func:`run_adapter` feeds a stream in arrival order to a
:class:`~slip_estimator.ros.adapter.SlipEstimatorAdapter` (what the live node does);
:func:`run_replay` writes it to a bag and runs :func:`slip_estimator.replay.replay_bag` (which
sorts by header stamp). Both return the published ``(topic, message)`` pairs in order.

Measurements: :func:`slip_classes`, :func:`truth_classes`, :func:`agreement`,
:func:`recovery_delay_s`, :func:`diagnostic_values`.
"""
from __future__ import annotations

import copy
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.bagio import BagWriter, read_messages
from slip_estimator.core.params import Params
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.stamps import header_stamp_ns, ns_to_stamp
from slip_estimator.ros.topics import (
    TOPIC_DIAGNOSTICS,
    TOPIC_IMU,
    TOPIC_JOINT_STATES,
    TOPIC_SLIP,
    TOPIC_WHEEL_ODOMETRY,
)

NS = 1_000_000_000
TOPIC_TRUTH_SLIP = '/truth/slip'
SENSOR_TOPICS = (TOPIC_IMU, TOPIC_JOINT_STATES, TOPIC_WHEEL_ODOMETRY)
WHEEL_TOPICS = (TOPIC_JOINT_STATES, TOPIC_WHEEL_ODOMETRY)

Stream = list[tuple[str, Any, int]]
Outputs = list[tuple[str, Any]]


# --- helpers ----------------------------------------------------------------------------------
def with_stamp(msg: Any, new_stamp_ns: int) -> Any:
    """A copy of ``msg`` with header stamp ``new_stamp_ns``."""
    out = copy.deepcopy(msg)
    out.header.stamp = ns_to_stamp(new_stamp_ns)
    return out


def _in(msg: Any, start_ns: int, end_ns: int) -> bool:
    return start_ns <= header_stamp_ns(msg) < end_ns


def first_stamp_ns(stream: Stream, topic: str = TOPIC_IMU) -> int:
    """Stamp of the first message of ``topic``."""
    return min(header_stamp_ns(m) for t, m, _ in stream if t == topic)


# --- mutators ---------------------------------------------------------------------------------
def drop(stream: Stream, start_ns: int, end_ns: int,
         topics: Iterable[str] = SENSOR_TOPICS) -> Stream:
    """Dropout: remove the messages of ``topics`` stamped in ``[start_ns, end_ns)``."""
    topics = set(topics)
    return [(t, m, lt) for t, m, lt in stream if not (t in topics and _in(m, start_ns, end_ns))]


def duplicate(stream: Stream, rng: np.random.Generator, fraction: float,
              topics: Iterable[str] = SENSOR_TOPICS) -> Stream:
    """Deliver a random ``fraction`` of the messages of ``topics`` twice (same stamp)."""
    topics = set(topics)
    out: Stream = []
    for item in stream:
        out.append(item)
        if item[0] in topics and rng.random() < fraction:
            out.append(item)
    return out


def reorder(stream: Stream, rng: np.random.Generator, fraction: float,
            max_shift: int = 5, start_ns: int | None = None, end_ns: int | None = None) -> Stream:
    """Arrival-order jitter: a random ``fraction`` of the messages (stamped in the window, if
    given) is delivered up to ``max_shift`` positions late. Stamps are unchanged, so a message
    can arrive after a newer one of the same topic."""
    start = -2 ** 63 if start_ns is None else start_ns
    end = 2 ** 63 if end_ns is None else end_ns
    out = list(stream)
    for i in range(len(out) - 1, -1, -1):
        t, m, _ = out[i]
        if t in SENSOR_TOPICS and _in(m, start, end) and rng.random() < fraction:
            j = min(len(out) - 1, i + int(rng.integers(1, max_shift + 1)))
            out.insert(j, out.pop(i))
    return out


def _set_vec(v: Any, values: tuple[float, float, float]) -> None:
    v.x, v.y, v.z = (float(a) for a in values)


def corrupt_imu(stream: Stream, start_ns: int, end_ns: int, value: float = math.nan,
                every: int = 1, accel: bool = True, gyro: bool = True) -> Stream:
    """Write ``value`` (NaN, Inf, huge) into the specific force and/or rate of every
    ``every``-th IMU message stamped in the window."""
    out: Stream = []
    k = 0
    for t, m, lt in stream:
        if t == TOPIC_IMU and _in(m, start_ns, end_ns):
            if k % every == 0:
                m = copy.deepcopy(m)
                if accel:
                    _set_vec(m.linear_acceleration, (value, value, value))
                if gyro:
                    _set_vec(m.angular_velocity, (value, value, value))
            k += 1
        out.append((t, m, lt))
    return out


def corrupt_wheels(stream: Stream, start_ns: int, end_ns: int,
                   value: float = math.nan) -> Stream:
    """Write ``value`` into the wheel speeds of the wheel messages stamped in the window."""
    out: Stream = []
    for t, m, lt in stream:
        if t in WHEEL_TOPICS and _in(m, start_ns, end_ns):
            m = copy.deepcopy(m)
            if t == TOPIC_JOINT_STATES:
                m.velocity = [float(value)] * len(m.velocity)
            else:
                m.twist.twist.linear.x = float(value)
        out.append((t, m, lt))
    return out


def spike(stream: Stream, at_ns: int, accel_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
          rate_rps: tuple[float, float, float] = (0.0, 0.0, 0.0), n_samples: int = 1) -> Stream:
    """Add ``accel_mps2`` / ``rate_rps`` (IMU frame) to the ``n_samples`` IMU messages from
    ``at_ns`` on: a shock (e.g. 50 g on one axis for one sample)."""
    out: Stream = []
    left = n_samples
    for t, m, lt in stream:
        if left and t == TOPIC_IMU and header_stamp_ns(m) >= at_ns:
            m = copy.deepcopy(m)
            a, w = m.linear_acceleration, m.angular_velocity
            _set_vec(a, (a.x + accel_mps2[0], a.y + accel_mps2[1], a.z + accel_mps2[2]))
            _set_vec(w, (w.x + rate_rps[0], w.y + rate_rps[1], w.z + rate_rps[2]))
            left -= 1
        out.append((t, m, lt))
    return out


def zero_stamps(stream: Stream, rng: np.random.Generator, fraction: float,
                topics: Iterable[str] = SENSOR_TOPICS) -> Stream:
    """Set the header stamp of a random ``fraction`` of the messages of ``topics`` to 0 (an
    uninitialised header)."""
    topics = set(topics)
    return [(t, with_stamp(m, 0), lt) if t in topics and rng.random() < fraction
            else (t, m, lt) for t, m, lt in stream]


def shift_stamps(stream: Stream, from_ns: int, offset_ns: int,
                 topics: Iterable[str] | None = None) -> Stream:
    """Clock jump: every message of ``topics`` (all topics if None) stamped at or after
    ``from_ns`` gets ``offset_ns`` added to its stamp and log time. Positive: a forward jump
    (no data lost); negative: a backward jump (the stamps repeat earlier times)."""
    out: Stream = []
    for t, m, lt in stream:
        if (topics is None or t in topics) and header_stamp_ns(m) >= from_ns:
            m = with_stamp(m, header_stamp_ns(m) + offset_ns)
            lt += offset_ns
        out.append((t, m, lt))
    if offset_ns > 0:
        out.sort(key=lambda item: item[2])
    return out


def loop(stream: Stream, at_ns: int, log_gap_ns: int = 10_000_000) -> Stream:
    """A bag played with ``--loop`` that restarts after ``at_ns``: the messages stamped before
    ``at_ns``, then the whole stream again with its ORIGINAL stamps (the clock jumps back by
    ``at_ns`` minus the first stamp). Log times keep increasing."""
    first = [item for item in stream if header_stamp_ns(item[1]) < at_ns]
    offset = first[-1][2] + log_gap_ns - stream[0][2]
    return first + [(t, m, lt + offset) for t, m, lt in stream]


def drift(stream: Stream, rate: float, from_ns: int | None = None,
          topics: Iterable[str] = WHEEL_TOPICS) -> Stream:
    """Clock drift: the stamps of ``topics`` run ``rate`` fast (2e-3 = 2 ms/s) against the
    others from ``from_ns`` (default: the first stamp of the stream) on. Log times follow the
    stamps so the arrival order stays realistic."""
    topics = set(topics)
    origin = first_stamp_ns(stream) if from_ns is None else from_ns
    out: Stream = []
    for t, m, lt in stream:
        if t in topics and header_stamp_ns(m) >= origin:
            shift = round((header_stamp_ns(m) - origin) * rate)
            m = with_stamp(m, header_stamp_ns(m) + shift)
            lt += shift
        out.append((t, m, lt))
    out.sort(key=lambda item: item[2])
    return out


def flood(stream: Stream, at_ns: int, count: int, topic: str = TOPIC_IMU) -> Stream:
    """A burst of ``count`` copies of the first ``topic`` message stamped at or after ``at_ns``
    (a publisher stuck in a loop)."""
    out: Stream = []
    done = False
    for t, m, lt in stream:
        out.append((t, m, lt))
        if not done and t == topic and header_stamp_ns(m) >= at_ns:
            out.extend([(t, m, lt)] * count)
            done = True
    return out


# --- runners ----------------------------------------------------------------------------------
def run_adapter(stream: Stream, params: Params,
                adapter: SlipEstimatorAdapter | None = None) -> tuple[Outputs,
                                                                      SlipEstimatorAdapter]:
    """Feed ``stream`` in arrival order to an adapter (new unless given); return its outputs
    and the adapter."""
    adapter = SlipEstimatorAdapter(params) if adapter is None else adapter
    out: Outputs = []
    for topic, msg, _ in stream:
        out.extend(adapter.on_message(topic, msg))
    return out, adapter


def write_bag(stream: Stream, path: Path) -> Path:
    """Write ``stream`` (log time = the stream's log time) to a new MCAP bag."""
    with BagWriter(path) as writer:
        for topic, msg, log_ns in stream:
            writer.write(topic, msg, log_ns)
    return path


def run_replay(stream: Stream, params: Params, workdir: Path, name: str,
               **replay_kwargs: Any) -> tuple[Outputs, Any]:
    """Write ``stream`` to ``workdir/name`` and replay it with ``replay_bag``; return the
    published ``(topic, message)`` pairs (output bag order) and the ReplaySummary."""
    from slip_estimator.replay import replay_bag

    bag = write_bag(stream, workdir / f'{name}_in')
    out_bag = workdir / f'{name}_out'
    summary = replay_bag(bag, params, out_bag, **replay_kwargs)
    return [(m.topic, m.msg) for m in read_messages(out_bag)], summary


# --- measurements -----------------------------------------------------------------------------
def key_values(status: Any) -> dict[str, str]:
    """KeyValues of a DiagnosticStatus as a dict."""
    return {kv.key: kv.value for kv in status.values}


def slip_statuses(outputs: Outputs) -> list[tuple[int, int, Any]]:
    """(stamp_ns, class or -1, status) of every ``/slip_estimator/slip`` output, in order."""
    rows = []
    for topic, msg in outputs:
        if topic == TOPIC_SLIP:
            (status,) = msg.status
            value = key_values(status)['slip_class']
            rows.append((header_stamp_ns(msg), -1 if value == 'unknown' else int(value), status))
    return rows


def slip_classes(outputs: Outputs) -> dict[int, int]:
    """Stamp -> estimated slip class (-1 unknown) of the slip statuses; a known class wins
    over an unknown report at the same stamp (a stale report can share a wheel stamp)."""
    classes: dict[int, int] = {}
    for stamp, cls, _ in slip_statuses(outputs):
        if classes.get(stamp, -1) < 0:
            classes[stamp] = cls
    return classes


def truth_classes(stream: Stream) -> list[tuple[int, float, int]]:
    """(stamp_ns, reference time s, class) of the ``/truth/slip`` messages of ``stream``.

    The reference time is ``vector.y`` (see :func:`tag_truth`)."""
    return [(header_stamp_ns(m), float(m.vector.y), round(m.vector.z))
            for t, m, _ in stream if t == TOPIC_TRUTH_SLIP]


def tag_truth(stream: Stream) -> Stream:
    """Store each truth message's original time (s since the first IMU stamp) in ``vector.y``
    (unused by the simulator), so windows stay comparable after a mutation moved stamps."""
    t0 = first_stamp_ns(stream)
    out: Stream = []
    for t, m, lt in stream:
        if t == TOPIC_TRUTH_SLIP:
            m = copy.deepcopy(m)
            m.vector.y = (header_stamp_ns(m) - t0) / NS
        out.append((t, m, lt))
    return out


def correctness(stream: Stream, outputs: Outputs) -> tuple[np.ndarray, np.ndarray]:
    """(reference times s, 1.0 where the estimated class equals the truth class else 0.0) per
    truth sample; a missing or unknown estimate counts as wrong."""
    est = slip_classes(outputs)
    rows = truth_classes(stream)
    t = np.array([r for _, r, _ in rows])
    ok = np.array([1.0 if est.get(s, -2) == c else 0.0 for s, _, c in rows])
    return t, ok


def agreement(t: np.ndarray, ok: np.ndarray, start_s: float, end_s: float) -> float:
    """Fraction of truth samples in ``[start_s, end_s)`` whose class was estimated right."""
    sel = (t >= start_s) & (t < end_s)
    return float(ok[sel].mean()) if sel.any() else float('nan')


def recovery_delay_s(base: tuple[np.ndarray, np.ndarray], fault: tuple[np.ndarray, np.ndarray],
                     fault_end_s: float, window_s: float = 10.0, margin: float = 0.1,
                     step_s: float = 0.5) -> float:
    """Smallest delay d after ``fault_end_s`` from which on the class agreement of the fault run
    stays within ``margin`` of the clean run's in EVERY sliding ``window_s`` window (windows
    that start at least d after the fault end, in ``step_s`` steps, up to the end of the data).
    ``inf`` if it never does."""
    t_b, ok_b = base
    t_f, ok_f = fault
    end = float(min(t_b.max(), t_f.max()))
    starts = np.arange(fault_end_s, max(fault_end_s, end - window_s) + 1e-9, step_s)
    good = [agreement(t_f, ok_f, s, s + window_s) >= agreement(t_b, ok_b, s, s + window_s)
            - margin for s in starts]
    # Latest failing window: recovery starts right after it.
    bad = [i for i, g in enumerate(good) if not g]
    if not bad:
        return 0.0
    if bad[-1] == len(good) - 1:
        return math.inf
    return float(starts[bad[-1] + 1] - fault_end_s)


def diagnostics(outputs: Outputs) -> list[tuple[int, Any]]:
    """(stamp_ns, status) of every ``/diagnostics`` output."""
    return [(header_stamp_ns(m), m.status[0]) for t, m in outputs if t == TOPIC_DIAGNOSTICS]


def diagnostic_values(outputs: Outputs, index: int = -1) -> dict[str, str]:
    """KeyValues of the ``index``-th ``/diagnostics`` output (default: the last)."""
    return key_values(diagnostics(outputs)[index][1])


def counter(values: dict[str, str], key: str) -> int:
    """An integer diagnostic value, 0 when absent or unknown."""
    try:
        return int(values.get(key, '0'))
    except ValueError:
        return 0
