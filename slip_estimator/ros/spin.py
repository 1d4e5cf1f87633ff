"""How the node runs and stops: the spin loop (the events executor, input batches) and a
teardown bounded in time (see :mod:`slip_estimator.ros.node`, sections Receiving and Shutdown)."""
from __future__ import annotations

import faulthandler
import time
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

SPIN_ONCE_TIMEOUT_S = 0.5
"""Longest wait of one ``spin_once`` (the loop then checks that rclpy is still running)."""


def spin(node: Any) -> None:
    """Spin ``node`` (a :class:`~slip_estimator.ros.node.SlipEstimatorNode`: it counts
    ``input_callbacks`` and has ``input_batch_period_s``) until rclpy shuts down: the events
    executor in a ``spin_once`` loop (see the node's Receiving section), or the
    single-threaded executor where there is none; each round handles every input message
    that is ready, then sleeps ``node.input_batch_period_s``."""
    try:
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=node.context)
    except (ImportError, AttributeError):
        executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while node.context.ok():
            executor.spin_once(timeout_sec=SPIN_ONCE_TIMEOUT_S)  # the first (waits for it)
            handled = -1
            while handled != node.input_callbacks:  # the rest, until none was ready
                handled = node.input_callbacks
                executor.spin_once(timeout_sec=0.0)
            if node.input_batch_period_s:
                time.sleep(node.input_batch_period_s)
    finally:
        executor.shutdown(timeout_sec=1.0)


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
