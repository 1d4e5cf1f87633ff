"""Write ROS 1 bags (rosbags.rosbag1.Writer) from ROS 2 message objects, for replay tests."""
from __future__ import annotations

from pathlib import Path

from rclpy.serialization import serialize_message
from rosbags.rosbag1 import Writer
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore

from slip_estimator.bagio import message_type_name

_ROS1 = get_typestore(Stores.ROS1_NOETIC)
_ROS2 = get_typestore(Stores.ROS2_JAZZY)


def ros1_bytes(msg: object) -> bytes:
    """ROS 1 serialisation of a ROS 2 message (header ``seq`` 0).

    rclpy pads its CDR to 8 bytes and rosbags wants the exact size, so up to 7 trailing padding
    bytes are cut.
    """
    name, raw = message_type_name(msg), serialize_message(msg)
    for cut in range(8):
        try:
            obj = _ROS2.deserialize_cdr(raw[:len(raw) - cut], name)
        except SerdeError:
            continue
        return bytes(_ROS2.cdr_to_ros1(_ROS2.serialize_cdr(obj, name), name))
    raise SerdeError(f'cannot convert {name}')


def write_ros1_bag(path: Path, messages, rename: dict[str, str] | None = None) -> Path:
    """Write ``(topic, message, log_time_ns)`` to a ROS 1 bag, topics renamed by ``rename``."""
    rename = rename or {}
    with Writer(path) as writer:
        conns = {}
        for topic, msg, log_ns in messages:
            if topic not in conns:
                conns[topic] = writer.add_connection(rename.get(topic, topic),
                                                     message_type_name(msg), typestore=_ROS1)
            writer.write(conns[topic], log_ns, ros1_bytes(msg))
    return path
