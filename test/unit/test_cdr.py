"""The CDR decoders (slip_estimator.ros.cdr) against rclpy's and rosbags' decoding of the same
bytes: the same records as from message objects, bit for bit, whatever the frame_id's length
(alignment); big-endian and malformed bytes are named rejections, never an exception."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core import frames
from slip_estimator.ros import cdr, convert

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
NAMES = ['front_left_wheel_joint', 'front_right_wheel_joint',
         'rear_left_wheel_joint', 'rear_right_wheel_joint']
MOUNTINGS = [frames.imu_to_body_dcm(rpy) for rpy in
             ([0.0, 0.0, 0.0], [math.pi, 0.0, 0.0], [0.1, -0.2, 0.3], [0.02, 1.4, -2.9])]


def random_imu(rng: np.random.Generator, frame_len: int, stamp_ns: int) -> Imu:
    m = Imu()
    m.header.stamp = convert.ns_to_stamp(stamp_ns)
    m.header.frame_id = 'i' * frame_len
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = (
        rng.normal(0.0, 5.0, 3).tolist())
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = (
        rng.normal(0.0, 0.5, 3).tolist())
    m.orientation_covariance[0] = -1.0
    m.linear_acceleration_covariance = rng.uniform(0.0, 1e-3, 9)
    m.angular_velocity_covariance = rng.uniform(0.0, 1e-5, 9)
    return m


def same_sample(a, b) -> None:
    """Two convert results are the same (reasons equal, arrays bit for bit)."""
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    assert a.stamp_ns == b.stamp_ns
    assert a.f_ib_b.tobytes() == b.f_ib_b.tobytes()
    assert a.omega_ib_b.tobytes() == b.omega_ib_b.tobytes()
    assert a.tilt_rp_rad == b.tilt_rp_rad and a.noise_var == b.noise_var


@pytest.mark.parametrize('C_imu_b', MOUNTINGS)
def test_imu_records_equal_those_of_message_objects(C_imu_b):
    rng = np.random.default_rng(7)
    msgs = [random_imu(rng, k % 11, 1_600_000_000_000_000_000 + 4_000_000 * k)
            for k in range(400)]
    # Samples the batch cannot take on its vectorised path: each goes through imu_from_values.
    msgs[3].orientation_covariance[0] = 0.01
    msgs[3].orientation.w, msgs[3].orientation.x = 0.9, 0.1
    msgs[5].linear_acceleration.y = math.nan
    msgs[6].angular_velocity.z = 99.9  # just inside the limit
    msgs[7].angular_velocity.z = 100.1  # absurd
    msgs[8].header.stamp = convert.ns_to_stamp(0)
    msgs[9].linear_acceleration_covariance = [0.0] * 9  # unknown noise
    msgs[10].angular_velocity_covariance[4] = math.nan
    msgs[11].linear_acceleration_covariance[0] = math.inf
    raws = [serialize_message(m) for m in msgs]
    batch = convert.imu_samples_from_cdr(raws, C_imu_b)
    for msg, raw, (stamp_ns, from_batch) in zip(msgs, raws, batch):
        expected = convert.imu_from_msg(msg, C_imu_b)
        same_sample(convert.imu_from_cdr(raw, C_imu_b), expected)
        same_sample(from_batch, expected)
        assert stamp_ns == convert.stamp_to_ns(msg.header.stamp)
    assert sum(isinstance(s, str) for _, s in batch) == 3  # NaN, absurd, zero stamp


@pytest.mark.parametrize('frame_len', range(9))
def test_imu_doubles_equal_rosbags_decode(frame_len):
    rng = np.random.default_rng(frame_len)
    msg = random_imu(rng, frame_len, 123_456_789_012)
    msg.orientation.x, msg.orientation.w = 0.25, -0.5
    raw = bytes(TYPESTORE.serialize_cdr(
        TYPESTORE.deserialize_cdr(serialize_message(msg)[:_imu_size(frame_len)],
                                  'sensor_msgs/msg/Imu'), 'sensor_msgs/msg/Imu'))
    ref = TYPESTORE.deserialize_cdr(raw, 'sensor_msgs/msg/Imu')
    stamps, values = cdr.imu_values([raw])
    assert stamps == [ref.header.stamp.sec * 10**9 + ref.header.stamp.nanosec]
    q = ref.orientation
    expected = np.concatenate([
        [q.x, q.y, q.z, q.w], ref.orientation_covariance,
        [ref.angular_velocity.x, ref.angular_velocity.y, ref.angular_velocity.z],
        ref.angular_velocity_covariance,
        [ref.linear_acceleration.x, ref.linear_acceleration.y, ref.linear_acceleration.z],
        ref.linear_acceleration_covariance])
    assert values[0].tobytes() == expected.tobytes()


def _imu_size(frame_len: int) -> int:
    """Bytes of a serialized Imu without the writer's trailing padding (rosbags is strict)."""
    return 4 + ((12 + frame_len + 1 + 7) & ~7) + 8 * cdr.IMU_DOUBLES


def joint_state(stamp_ns: int, frame: str, names, position, velocity) -> JointState:
    m = JointState()
    m.header.stamp = convert.ns_to_stamp(stamp_ns)
    m.header.frame_id = frame
    m.name, m.position, m.velocity = list(names), list(position), list(velocity)
    return m


@pytest.mark.parametrize('frame', ['', 'b', 'base', 'base_link', 'base_link_1'])
def test_joint_state_fields_equal_rclpy_and_rosbags(frame):
    names = ['a', 'front_left_wheel_joint', 'xy', 'rear_right_wheel_joint',
             'front_right_wheel_joint']
    for position, velocity in (([], [0.5, 1.5, -2.0, 3.25, 4.0]),
                               ([0.1, 0.2, 0.3, 0.4, 0.5], []),
                               ([0.1, 0.2, 0.3, 0.4, 0.5], [1.0, 2.0, 3.0, 4.0, 5.0])):
        msg = joint_state(5_000_000_007, frame, names, position, velocity)
        raw = serialize_message(msg)
        fields = cdr.joint_state_fields(raw)
        assert (fields.stamp_ns, fields.name) == (5_000_000_007, names)
        assert (fields.position, fields.velocity) == (list(msg.position), list(msg.velocity))
        ref = TYPESTORE.deserialize_cdr(
            TYPESTORE.serialize_cdr(TYPESTORE.types['sensor_msgs/msg/JointState'](
                header=TYPESTORE.types['std_msgs/msg/Header'](
                    stamp=TYPESTORE.types['builtin_interfaces/msg/Time'](sec=5, nanosec=7),
                    frame_id=frame),
                name=names, position=np.array(position, dtype=float),
                velocity=np.array(velocity, dtype=float), effort=np.array([], dtype=float)),
                'sensor_msgs/msg/JointState'), 'sensor_msgs/msg/JointState')
        assert (ref.name, ref.position.tolist(), ref.velocity.tolist()) == (
            fields.name, fields.position, fields.velocity)
        # The wheel records of both paths (velocities, or rates from positions).
        rates_a = convert.JointRatesFromPositions(50.0)
        rates_b = convert.JointRatesFromPositions(50.0)
        for k in range(2):
            msg = joint_state(5_000_000_007 + k * 10**8, frame, names,
                              [p + 0.01 * k for p in position], velocity)
            assert convert.wheel_from_cdr_joint_state(
                serialize_message(msg), NAMES, 0.1, from_positions=rates_a
            ) == convert.wheel_from_joint_state(msg, NAMES, 0.1, from_positions=rates_b)


@pytest.mark.parametrize('child', ['', 'b', 'base_link', 'base_foot'])
def test_odometry_twist_equals_message(child):
    msg = Odometry()
    msg.header.stamp = convert.ns_to_stamp(9_000_000_001)
    msg.header.frame_id = 'odom'
    msg.child_frame_id = child
    msg.pose.pose.position.x = 7.0
    msg.pose.covariance[35] = 3.0
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = 0.75, -9.0
    msg.twist.twist.angular.y, msg.twist.twist.angular.z = 8.0, -0.2
    msg.twist.covariance[0] = 5.0
    raw = serialize_message(msg)
    assert cdr.odometry_twist(raw) == (9_000_000_001, 0.75, -0.2)
    assert (convert.wheel_from_cdr_odometry(raw, 0.8)
            == convert.wheel_from_odometry(msg, 0.8))


def test_big_endian_and_malformed_are_named_rejections():
    msg = random_imu(np.random.default_rng(1), 3, 10**9)
    little = serialize_message(msg)
    ref = TYPESTORE.deserialize_cdr(little[:_imu_size(3)], 'sensor_msgs/msg/Imu')
    big = bytes(TYPESTORE.serialize_cdr(ref, 'sensor_msgs/msg/Imu', little_endian=False))
    C = np.eye(3)
    assert convert.imu_from_cdr(big, C) == cdr.REASON_BIG_ENDIAN
    assert convert.imu_from_cdr(little[:100], C) == cdr.REASON_MALFORMED
    assert convert.imu_from_cdr(b'', C) == cdr.REASON_MALFORMED
    assert convert.imu_from_cdr(b'\x00\x07' + little[2:], C) == cdr.REASON_MALFORMED
    batch = convert.imu_samples_from_cdr([big, little, little[:50]], C)
    assert [s if isinstance(s, str) else 'ok' for _, s in batch] == [
        cdr.REASON_BIG_ENDIAN, 'ok', cdr.REASON_MALFORMED]
    js = serialize_message(joint_state(10**9, 'base', NAMES, [], [1.0] * 4))
    assert convert.wheel_from_cdr_joint_state(js[:-20], NAMES, 0.1) == cdr.REASON_MALFORMED
    assert convert.wheel_from_cdr_odometry(little[:60], 0.5) == cdr.REASON_MALFORMED


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400), st.integers(0, 3))
def test_arbitrary_bytes_never_raise(data, kind):
    """Whatever arrives on a raw subscription gives a record or a reason, never an exception."""
    raw = (b'\x00\x01\x00\x00' + data) if kind else data
    C = np.eye(3)
    rates = convert.JointRatesFromPositions(9.0)
    for result in (convert.imu_from_cdr(raw, C), convert.imu_samples_from_cdr([raw], C)[0][1],
                   convert.wheel_from_cdr_joint_state(raw, NAMES, 0.1, from_positions=rates),
                   convert.wheel_from_cdr_odometry(raw, 0.5)):
        assert isinstance(result, str) or result.stamp_ns > 0


def test_output_bytes_decode_to_the_same_messages():
    """cdr_out writes every output the node publishes as rclpy and rosbags (strict about the
    length) read it back: the same message, field for field."""
    from rclpy.serialization import deserialize_message

    from slip_estimator.bagio import message_type_name
    from slip_estimator.ros import publish
    from slip_estimator.ros.cdr_out import serialize

    outputs = publish._sample_outputs()
    odo = outputs[0]
    odo.header.frame_id, odo.child_frame_id = 'odom_x', 'b'  # other paddings
    diag = outputs[1]
    diag.status[0].values[0].value = 'üñí'  # multi-byte UTF-8
    assert {type(m).__name__ for m in outputs} == {'Odometry', 'DiagnosticArray',
                                                   'Vector3Stamped'}
    for msg in outputs:
        raw = serialize(msg)
        assert deserialize_message(raw, type(msg)) == msg
        TYPESTORE.deserialize_cdr(raw, message_type_name(msg))
