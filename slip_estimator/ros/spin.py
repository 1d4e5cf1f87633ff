"""How the node runs and stops: the spin loop, the timing of every callback, the teardown.

Spin loop
---------
Jazzy's ``rclpy.experimental.EventsExecutor`` in a ``spin_once`` loop (its ``spin()`` would
hold the GIL from other Python threads); without it, the ``SingleThreadedExecutor``. One round:
wait ``input_batch_period_s`` (read-only node parameter, default 0.01 s) in the executor, which
runs the timers and services meanwhile; take every input message that arrived from the
subscriptions directly (rclpy's ``take_message``, serialized bytes) and handle them in arrival
order (the RMW's reception stamps), one callback per message, back to back; publish what they
gave (the output step). ``input_batch_period_s`` 0 wakes for every message instead: the
subscriptions are then the executor's, and a round handles what is ready after the first.

Taken by the loop, the inputs never pass through the executor: it would wake, take and call
back one message at a time (about 80 us of CPU per message at 250 Hz, docs/performance.md,
"Live node, fifth pass"), and the callbacks of a batch run back to back, warm. Reception
stamps order the messages of the two topics as the executor did; two messages of different
topics that arrive while the round is taking them can be handled in the other order (the
core waits for the IMU to reach a wheel sample's stamp, the replay does not use this loop).
The input queues (KEEP_LAST 500 for the IMU, 2 s at 250 Hz) hold far more than a period.

Batches: a callback that runs right after another one finds the interpreter's and the
estimator's data in the caches; one woken alone, 4 ms after the last, does not (about 0.3 ms
of CPU per IMU callback then, against about 0.1 ms warm). The price is up to that period of
extra latency of the outputs.

The output step: under :func:`spin` the input callbacks and the watchdog timer do not
publish; their outputs wait, in the order the adapter gave them, for the end of the round,
and go out in one step of their own (timed like a callback, below). A reliable publish to a
subscribed reader takes about 0.1 ms of CPU but returns after 0.2 to several ms of wall time
when the reader it wakes takes the core, and the callbacks after it then often wait for the
core as well. Measured at 250 Hz (docs/performance.md, "Live node, third pass"): the p99
over every callback was lower than with the publishes right after each callback in 6 of 6
paired runs (0.87-1.29 ms against 1.30-3.91 ms), at the price of about 1 ms more odometry
latency at the median (about 5 ms at the p99). Outputs and their order are unchanged. A node spun
by any other executor publishes from its callbacks.

Garbage collection: everything built before the loop (modules, the node, the estimator) is
frozen out of the collector's reach (:func:`gc.freeze`), so a full collection walks only what
was allocated since, instead of every object of rclpy and numpy (a 30-120 ms pause inside a
callback about once in 20 s at 250 Hz, measured in docs/performance.md).

Callback durations
------------------
Every callback the node runs is timed (``time.perf_counter``, wall) into ring buffers
(:class:`CallbackDurations`): the ``/imu/data`` callbacks (convert, core step, build the
outputs) in one of the last ``CALLBACK_WINDOW``, and every callback -- the input callbacks,
the output step, the watchdog timer, the ``~/reset`` service and rclpy's parameter services --
in one of the last ``ALL_CALLBACKS_WINDOW`` (:class:`CallbackStats`). Each
``/diagnostics`` status the node publishes carries ``callback_p50_ms``, ``callback_p99_ms``,
``callback_max_ms`` and ``callback_window`` (IMU callbacks) and ``all_callbacks_p50_ms``,
``all_callbacks_p99_ms``, ``all_callbacks_max_ms`` and ``all_callbacks_window`` (every
callback); ``unknown`` before the first. ``slip-estimator bench --only live`` reads both.

Shutdown
--------
Ctrl-C (SIGINT) or SIGTERM ends the spin, or the start when it comes before the node is
built, with status 0 (SIGTERM shuts rclpy's context down from its signal thread, under a
half-built node or a running callback: the call that then fails is the stop, not an error;
nothing is published once the context is down). The node then destroys its DDS
entities within ``TEARDOWN_TIMEOUT_S``. Fast DDS 2.14 (Jazzy) can deadlock in that teardown
when a peer's endpoints leave at the same moment (the participant's ``set_listener`` waits for
a discovery callback that waits for a lock the teardown holds; seen about once in 80 stops of
a test whose client node left just before the SIGINT). The wait holds the GIL, so the guard is
``faulthandler``'s C watchdog: past the timeout it prints every thread's stack and exits with
status 1 instead of hanging until launch escalates to SIGKILL.
"""
from __future__ import annotations

import faulthandler
import gc
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import KeyValue
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

SPIN_ONCE_TIMEOUT_S = 0.5
"""Longest wait of one ``spin_once`` (the loop then checks that rclpy is still running)."""


def spin(node: Any) -> None:
    """Spin ``node`` (a :class:`~slip_estimator.ros.node.SlipEstimatorNode`: it counts
    ``input_callbacks``, has ``input_batch_period_s``, takes its inputs itself in
    ``handle_ready_inputs`` while ``inputs_taken_by_spin``, queues its outputs while
    ``output_steps`` and publishes them in ``publish_outputs``) until rclpy shuts down, in
    rounds (see the module's Spin loop section)."""
    try:
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=node.context)
    except (ImportError, AttributeError):
        executor = SingleThreadedExecutor(context=node.context)
    period_s = node.input_batch_period_s
    node.inputs_taken_by_spin = period_s > 0.0  # before add_node: the executor skips them
    node.output_steps = True
    executor.add_node(node)
    gc.collect()
    gc.freeze()
    try:
        while node.context.ok():
            if period_s:
                executor.spin_once(timeout_sec=period_s)  # timers, services; or the period
                node.handle_ready_inputs()
            else:
                executor.spin_once(timeout_sec=SPIN_ONCE_TIMEOUT_S)  # the first (waits)
                handled = -1
                while handled != node.input_callbacks:  # the rest, until none was ready
                    handled = node.input_callbacks
                    executor.spin_once(timeout_sec=0.0)
            node.publish_outputs()
    finally:
        node.output_steps = False
        executor.shutdown(timeout_sec=1.0)
        node.inputs_taken_by_spin = False


class CallbackDurations:
    """Wall durations of the last ``window`` callbacks, s, in a ring buffer (a numpy array: the
    percentiles read it in place, no copy of a 15000-entry deque into an array per report)."""

    __slots__ = ('_s', 'count')

    def __init__(self, window: int) -> None:
        self._s = np.zeros(window)
        self.count = 0
        """Callbacks timed so far."""

    def add(self, seconds: float) -> None:
        """Record one callback's duration."""
        self._s[self.count % len(self._s)] = seconds
        self.count += 1

    def summary_ms(self) -> list[str]:
        """p50, p99 and max over the window in ms ('%.3f'; 'unknown' before the first
        callback) and the number of callbacks in the window."""
        n = min(self.count, len(self._s))
        if not n:
            return ['unknown'] * 3 + ['0']
        s = self._s[:n]
        p50, p99 = (_percentile_s(s, q) * 1e3 for q in (0.5, 0.99))
        return [f'{p50:.3f}', f'{p99:.3f}', f'{s.max() * 1e3:.3f}', str(n)]


def _percentile_s(values: np.ndarray, q: float) -> float:
    """``np.percentile(values, 100 q)`` (linear interpolation) from the two order statistics
    around it, by ``np.partition`` (half the cost of a full percentile on 15000 entries)."""
    pos = q * (len(values) - 1)
    lo = int(pos)
    hi = min(lo + 1, len(values) - 1)
    part = np.partition(values, (lo, hi))
    return float(part[lo] + (part[hi] - part[lo]) * (pos - lo))


CALLBACK_WINDOW = 15000
"""IMU callback durations kept for the ``callback_*_ms`` diagnostics (60 s at 250 Hz)."""
ALL_CALLBACKS_WINDOW = 18000
"""Durations of every callback kept for the ``all_callbacks_*_ms`` diagnostics (about 60 s at
250 Hz IMU, 10 Hz wheels and their output steps)."""


class CallbackStats:
    """The node's callback durations: its ``/imu/data`` callbacks' and every callback's, and
    the diagnostic values they give (see the module's Callback durations section)."""

    __slots__ = ('imu', 'all')

    def __init__(self) -> None:
        self.imu = CallbackDurations(CALLBACK_WINDOW)
        self.all = CallbackDurations(ALL_CALLBACKS_WINDOW)

    def add_to(self, msg: Any) -> None:
        """Append the duration percentiles to every status of a DiagnosticArray."""
        keys = ('p50_ms', 'p99_ms', 'max_ms', 'window')
        values = [KeyValue(key=f'callback_{k}', value=v)
                  for k, v in zip(keys, self.imu.summary_ms())]
        values += [KeyValue(key=f'all_callbacks_{k}', value=v)
                   for k, v in zip(keys, self.all.summary_ms())]
        for status in msg.status:
            status.values = list(status.values) + values


def timed(callback: Callable[..., Any], durations: CallbackDurations) -> Callable[..., Any]:
    """``callback`` with its wall duration recorded in ``durations`` (timers, services)."""
    def run(*args: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return callback(*args)
        finally:
            durations.add(time.perf_counter() - t0)
    return run


TEARDOWN_TIMEOUT_S = 4.0
"""Seconds the DDS teardown may take before the process exits anyway (status 1, stacks on
stderr); a normal teardown takes well under 1 s, launch escalates SIGINT to SIGTERM after 5 s."""


def bounded_teardown(node: Node | None, timeout_s: float = TEARDOWN_TIMEOUT_S) -> None:
    """Destroy ``node`` and shut rclpy down, or exit the process with status 1 after
    ``timeout_s`` if that hangs (see the module's Shutdown section)."""
    faulthandler.dump_traceback_later(timeout_s, exit=True)
    try:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    finally:
        faulthandler.cancel_dump_traceback_later()
