"""The node's quality of service: sensor-data QoS (best effort, volatile) on the inputs with
queues deep enough for a burst, reliable volatile outputs (REP-2003 style). Shared by the
node and the live benchmark's publisher and listener."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

IMU_QUEUE_DEPTH = 500
"""IMU messages the node's subscription queues (2 s at 250 Hz)."""
WHEEL_QUEUE_DEPTH = 100
"""Wheel messages the node's subscription queues."""


def input_qos(depth: int) -> QoSProfile:
    """Sensor-data QoS (best effort, volatile) with a deeper KEEP_LAST queue."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)


def output_qos(depth: int) -> QoSProfile:
    """Reliable, volatile output QoS."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
