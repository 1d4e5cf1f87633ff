"""The node's topics: input and output names, their message classes, the topics an input is
read from (the ``*_topic`` parameters). Shared by the adapter, the node, the replay and the
benchmarks."""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core.params import Params

TOPIC_IMU = '/imu/data'
TOPIC_JOINT_STATES = '/joint_states'
TOPIC_WHEEL_ODOMETRY = '/wheel/odometry'
TOPIC_ODOMETRY = '/slip_estimator/odometry'
TOPIC_SLIP = '/slip_estimator/slip'
TOPIC_SLIP_RATIO = '/slip_estimator/slip_ratio'
TOPIC_DIAGNOSTICS = '/diagnostics'

OUTPUT_TYPES: dict[str, type] = {
    TOPIC_ODOMETRY: Odometry,
    TOPIC_SLIP: DiagnosticArray,
    TOPIC_SLIP_RATIO: Vector3Stamped,
    TOPIC_DIAGNOSTICS: DiagnosticArray,
}

Output = tuple[str, Any]
"""(output topic, message) to publish."""


def wheel_topic(params: Params) -> str:
    """The wheel input topic selected by ``wheel_input``."""
    return TOPIC_JOINT_STATES if params.wheel_input == 'joint_states' else TOPIC_WHEEL_ODOMETRY


def input_types(params: Params) -> dict[str, type]:
    """Input topics to subscribe to (IMU first) and their message classes."""
    wheel = wheel_topic(params)
    return {TOPIC_IMU: Imu, wheel: JointState if wheel == TOPIC_JOINT_STATES else Odometry}


def input_sources(params: Params) -> dict[str, str]:
    """The topic each input is read from (``imu_topic`` and the wheel topic parameter), by the
    input topic name the adapter takes it under."""
    source = {TOPIC_IMU: params.imu_topic, TOPIC_JOINT_STATES: params.joint_states_topic,
              TOPIC_WHEEL_ODOMETRY: params.wheel_odometry_topic}
    return {topic: source[topic] for topic in input_types(params)}
