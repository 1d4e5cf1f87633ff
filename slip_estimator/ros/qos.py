"""The node's quality of service: sensor-data QoS (best effort, volatile) on the inputs with
queues deep enough for a burst, reliable volatile outputs (REP-2003 style). Shared by the
node and the live benchmark's publisher and listener.

Inputs use the sensor-data profile (BEST_EFFORT, VOLATILE, KEEP_LAST) with a deeper queue:
depth 500 for ``/imu/data`` (2 s at 250 Hz) and 100 for the wheel topic. A best-effort
subscription matches both best-effort publishers (the usual IMU driver setting) and reliable
ones (bag players, ``ros2 topic pub``); a reliable subscription would silently not connect to a
best-effort driver. The deep queue absorbs executor stalls (GIL, garbage collection, a burst
from a bag player) so that no sample is overwritten before the callback runs; lost samples
would show up in ``/diagnostics`` as the ``/imu/data stamp_gaps`` counter and as a difference
between the publisher's count and ``/imu/data received``.
Outputs are RELIABLE, VOLATILE, KEEP_LAST: depth 10 for odometry and diagnostics, 100 for the
slip topics (one message per wheel sample, consumers must not miss class changes).
"""

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
