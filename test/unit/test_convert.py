"""Message <-> record conversions of slip_estimator.ros.convert (no DDS needed)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus
from hypothesis import given
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core import frames
from slip_estimator.core.types import Health, ImuSample, OdometryEstimate, SlipEstimate, WheelSample
from slip_estimator.ros import convert, finite, publish

G = 9.81
NAMES = ['front_left_wheel_joint', 'front_right_wheel_joint',
         'rear_left_wheel_joint', 'rear_right_wheel_joint']


def imu_msg(stamp_ns: int, f=(0.0, 0.0, G), w=(0.0, 0.0, 0.0)) -> Imu:
    msg = Imu()
    msg.header.stamp = convert.ns_to_stamp(stamp_ns)
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = f
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = w
    return msg


def joint_msg(stamp_ns: int, names, velocities) -> JointState:
    msg = JointState()
    msg.header.stamp = convert.ns_to_stamp(stamp_ns)
    msg.name = list(names)
    msg.velocity = [float(v) for v in velocities]
    return msg


def slip(**kw) -> SlipEstimate:
    base = dict(stamp_ns=5_000_000_123, slip_ratio=0.3, slip_ratio_std=0.02, slip_class=2,
                body_speed_mps=0.35, body_speed_std_mps=0.01, wheel_speed_mps=0.5)
    base.update(kw)
    return SlipEstimate(**base)


def values(diag) -> dict[str, str]:
    return {kv.key: kv.value for kv in diag.status[0].values}


# --- stamps -----------------------------------------------------------------------------------
@given(st.integers(min_value=-(2**62), max_value=2**62))
def test_stamp_round_trip(ns):
    stamp = convert.ns_to_stamp(ns)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert convert.stamp_to_ns(stamp) == ns


def test_stamp_to_ns_known_value():
    assert convert.stamp_to_ns(Time(sec=12, nanosec=345)) == 12_000_000_345


# --- IMU ----------------------------------------------------------------------------------------
def test_imu_level_z_up_is_minus_g_in_frd():
    sample = convert.imu_from_msg(imu_msg(1_000, w=(0.1, 0.2, 0.3)),
                                  frames.imu_to_body_dcm([0.0, 0.0, 0.0]))
    assert isinstance(sample, ImuSample)
    assert sample.stamp_ns == 1_000
    np.testing.assert_allclose(sample.f_ib_b, [0.0, 0.0, -G])
    np.testing.assert_allclose(sample.omega_ib_b, [0.1, -0.2, -0.3])


def test_imu_mounted_upside_down_flips_y_and_z():
    # IMU rolled by pi in base_link: its y and z axes point opposite to base_link's; b is FRD,
    # so the net effect is the identity between IMU axes and the body frame.
    C_imu_b = frames.imu_to_body_dcm([math.pi, 0.0, 0.0])
    sample = convert.imu_from_msg(imu_msg(1, f=(1.0, 2.0, -G), w=(0.1, 0.2, 0.3)), C_imu_b)
    # In base_link (FLU) the reading is (1, -2, +G); in FRD (1, 2, -G).
    C_imu_base = frames.rpy_to_dcm(math.pi, 0.0, 0.0)
    np.testing.assert_allclose(C_imu_base @ [1.0, 2.0, -G], [1.0, -2.0, G], atol=1e-12)
    np.testing.assert_allclose(sample.f_ib_b, [1.0, 2.0, -G], atol=1e-12)
    np.testing.assert_allclose(sample.omega_ib_b, [0.1, 0.2, 0.3], atol=1e-12)


def test_imu_yawed_mounting():
    # IMU x axis along base_link y (yaw +90 deg): IMU-x specific force is base_link left.
    C_imu_b = frames.imu_to_body_dcm([0.0, 0.0, math.pi / 2])
    sample = convert.imu_from_msg(imu_msg(1, f=(1.0, 0.0, G)), C_imu_b)
    np.testing.assert_allclose(sample.f_ib_b, [0.0, -1.0, -G], atol=1e-12)  # FRD: left = -y


@pytest.mark.parametrize('bad', [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize('where', ['f', 'w'])
def test_imu_non_finite_rejected(bad, where):
    f = (0.0, bad, G) if where == 'f' else (0.0, 0.0, G)
    w = (bad, 0.0, 0.0) if where == 'w' else (0.0, 0.0, 0.0)
    assert convert.imu_from_msg(imu_msg(1, f, w), np.eye(3)) == convert.REASON_NON_FINITE


def test_imu_zero_stamp_and_absurd_rejected():
    assert convert.imu_from_msg(imu_msg(0), np.eye(3)) == convert.REASON_ZERO_STAMP
    assert convert.imu_from_msg(imu_msg(1, f=(1e6, 0, 0)), np.eye(3)) == convert.REASON_ABSURD_IMU
    assert convert.imu_from_msg(imu_msg(1, w=(0, 0, 1e3)), np.eye(3)) == convert.REASON_ABSURD_IMU


# --- wheels ---------------------------------------------------------------------------------------
def test_joint_state_sides_and_means():
    # Order in the message differs from the parameter order; an arm joint is ignored.
    msg = joint_msg(7, ['arm_joint', 'rear_right_wheel_joint', 'front_left_wheel_joint',
                        'front_right_wheel_joint', 'rear_left_wheel_joint'],
                    [100.0, 4.0, 1.0, 3.0, 2.0])
    sample = convert.wheel_from_joint_state(msg, NAMES, 0.1)
    assert isinstance(sample, WheelSample)
    assert sample.stamp_ns == 7
    assert sample.rim_speed_mps == pytest.approx(0.25)
    assert sample.rim_speed_left_mps == pytest.approx(0.15)
    assert sample.rim_speed_right_mps == pytest.approx(0.35)


def test_joint_state_side_unknown_and_missing_wheels():
    sample = convert.wheel_from_joint_state(joint_msg(7, ['wheel_a', 'wheel_b'], [1.0, 3.0]),
                                            ['wheel_a', 'wheel_b'], 0.5)
    assert sample.rim_speed_mps == pytest.approx(1.0)
    assert sample.rim_speed_left_mps is None and sample.rim_speed_right_mps is None
    # Only some listed wheels present: use those.
    sample = convert.wheel_from_joint_state(joint_msg(7, ['front_left_wheel_joint'], [2.0]),
                                            NAMES, 0.5)
    assert sample.rim_speed_mps == pytest.approx(1.0)
    assert sample.rim_speed_left_mps == pytest.approx(1.0)
    assert sample.rim_speed_right_mps is None
    assert convert.wheel_side('LeftWheel') == 'left'
    assert convert.wheel_side('wheel') is None


def test_joint_state_rejections():
    r = 0.1
    assert (convert.wheel_from_joint_state(joint_msg(7, ['arm'], [1.0]), NAMES, r)
            == convert.REASON_NO_WHEEL_JOINTS)
    no_vel = joint_msg(7, NAMES, [])
    assert convert.wheel_from_joint_state(no_vel, NAMES, r) == convert.REASON_NO_VELOCITY
    assert (convert.wheel_from_joint_state(joint_msg(0, NAMES, [1] * 4), NAMES, r)
            == convert.REASON_ZERO_STAMP)
    assert (convert.wheel_from_joint_state(joint_msg(7, NAMES, [1, math.nan, 1, 1]), NAMES, r)
            == convert.REASON_NON_FINITE)
    assert (convert.wheel_from_joint_state(joint_msg(7, NAMES, [1, 100, 1, 1]), NAMES, r,
                                           max_speed_mps=5.0) == convert.REASON_ABSURD_SPEED)


def test_wheel_odometry_differential_drive():
    msg = Odometry()
    msg.header.stamp = convert.ns_to_stamp(9)
    msg.twist.twist.linear.x = 1.0
    msg.twist.twist.angular.z = 0.5  # turning left: right wheels faster
    sample = convert.wheel_from_odometry(msg, 0.8)
    assert sample.rim_speed_mps == 1.0
    assert sample.rim_speed_left_mps == pytest.approx(0.8)
    assert sample.rim_speed_right_mps == pytest.approx(1.2)
    msg.twist.twist.angular.z = math.nan
    assert convert.wheel_from_odometry(msg, 0.8) == convert.REASON_NON_FINITE
    msg.twist.twist.angular.z = 0.0
    msg.twist.twist.linear.x = 7.0
    assert convert.wheel_from_odometry(msg, 0.8, max_speed_mps=5.0) == convert.REASON_ABSURD_SPEED


# --- outputs --------------------------------------------------------------------------------------
def test_odometry_to_msg():
    P = np.arange(36.0).reshape(6, 6)
    odo = OdometryEstimate(stamp_ns=3_000_000_001, p_ob_o=np.array([1.0, 2.0, 3.0]),
                           q_ob_wxyz=np.array([0.5, 0.5, 0.5, 0.5]),
                           v_ob_b=np.array([0.4, 0.0, 0.0]), omega_ob_b=np.array([0, 0, 0.1]),
                           pose_covariance=P, twist_covariance=2 * P)
    msg = publish.odometry_to_msg(odo, 'odom', 'base_link')
    assert (msg.header.frame_id, msg.child_frame_id) == ('odom', 'base_link')
    assert convert.stamp_to_ns(msg.header.stamp) == 3_000_000_001
    q = msg.pose.pose.orientation
    assert (q.w, q.x, q.y, q.z) == (0.5, 0.5, 0.5, 0.5)
    assert msg.pose.pose.position.z == 3.0
    assert msg.twist.twist.angular.z == 0.1
    assert msg.pose.covariance[7] == 7.0  # row-major: (1, 1)
    assert msg.twist.covariance[35] == 70.0
    assert finite.message_is_finite(msg)
    msg.twist.covariance[3] = math.nan
    assert not finite.message_is_finite(msg)


@pytest.mark.parametrize('cls,level,name', [
    (0, DiagnosticStatus.OK, 'none'), (1, DiagnosticStatus.OK, 'low'),
    (2, DiagnosticStatus.WARN, 'medium'), (3, DiagnosticStatus.ERROR, 'high'),
    (4, DiagnosticStatus.ERROR, 'extreme'), (-1, DiagnosticStatus.STALE, 'unknown')])
def test_slip_diagnostic_levels(cls, level, name):
    diag = publish.slip_to_diagnostic_array(slip(slip_class=cls), 'base_link')
    status = diag.status[0]
    assert (status.level, status.message, status.name, status.hardware_id) == (
        level, name, 'slip_estimator: wheel slip', 'base_link')
    assert convert.stamp_to_ns(diag.header.stamp) == 5_000_000_123


def test_slip_diagnostic_values_and_unknown():
    kv = values(publish.slip_to_diagnostic_array(
        slip(slip_ratio_left=0.25, slip_ratio_right=0.35), 'base_link'))
    assert {'slip_ratio', 'slip_class', 'slip_ratio_std', 'body_speed', 'wheel_speed',
            'slip_ratio_left', 'slip_ratio_right'} <= set(kv)
    assert float(kv['slip_ratio']) == 0.3 and kv['slip_class'] == '2'
    assert kv['p_medium_or_worse'] == 'unknown' and kv['slip_resolved'] == 'true'
    kv = values(publish.slip_to_diagnostic_array(
        slip(slip_class=1, p_medium_or_worse=0.75, resolved=False), 'base_link'))
    assert kv['p_medium_or_worse'] == '0.75' and kv['slip_resolved'] == 'false'
    kv = values(publish.slip_to_diagnostic_array(
        slip(slip_ratio=math.nan, slip_ratio_std=math.inf, slip_class=-1,
             body_speed_mps=math.nan), 'base_link'))
    assert 'slip_ratio_left' not in kv
    assert kv['slip_ratio'] == kv['slip_ratio_std'] == kv['body_speed'] == 'unknown'
    assert not any(v.lower() in ('nan', 'inf', '-inf') for v in kv.values())


def test_slip_vector3_only_when_known():
    vec = publish.slip_to_vector3(slip(), 'base_link')
    assert (vec.vector.x, vec.vector.y, vec.vector.z) == (0.3, 0.02, 2.0)
    assert convert.stamp_to_ns(vec.header.stamp) == 5_000_000_123
    assert publish.slip_to_vector3(slip(slip_ratio=math.nan, slip_class=-1), 'b') is None


def test_health_diagnostics_formatting():
    health = Health(level=1, message='aligning', values={
        'nis': 1.23456789, 'bias': np.array([1e-3, math.nan, 2.0]), 'count': 3,
        'ok': True, 'x': math.inf})
    diag = publish.health_to_diagnostic_array(health, 42, 'base_link', {'/imu/data received': 7})
    status = diag.status[0]
    assert status.level == DiagnosticStatus.WARN and status.message == 'aligning'
    kv = values(diag)
    assert kv == {'nis': '1.23457', 'bias': '[0.001, unknown, 2]', 'count': '3',
                  'ok': 'true', 'x': 'unknown', '/imu/data received': '7'}
    assert finite.message_is_finite(diag)
    diag.status[0].values[0].value = 'nan'
    assert not finite.message_is_finite(diag)


def _positions_msg(stamp_ns: int, positions):
    msg = joint_msg(stamp_ns, NAMES, [])
    msg.position = [float(x) for x in positions]
    return msg


def test_positions_only_joint_states_give_rates_from_differences():
    """velocity empty, positions present: the first message seeds, the next ones give
    r * dtheta/dt; a wrap at +-pi is unwrapped; an encoder reset is rejected and re-seeds."""
    r = 0.1
    rates = convert.JointRatesFromPositions(max_rate_rps=30.0)
    ns = 100_000_000  # 10 Hz

    def call(k, pos):
        return convert.wheel_from_joint_state(_positions_msg(1 + k * ns, pos), NAMES, r,
                                              from_positions=rates)

    assert call(0, [0.0, 0.0, 0.0, 0.0]) == convert.REASON_FIRST_POSITION
    s = call(1, [0.5, 0.7, 0.5, 0.7])  # left 5 rad/s, right 7 rad/s
    assert s.rim_speed_left_mps == pytest.approx(0.5)
    assert s.rim_speed_right_mps == pytest.approx(0.7)
    assert s.rim_speed_mps == pytest.approx(0.6)
    # positions wrapped to +-pi: 3.0 -> -3.0 is +0.283 rad, not -6 rad
    call(2, [3.0, 3.0, 3.0, 3.0])
    s = call(3, [-3.0, -3.0, -3.0, -3.0])
    assert s.rim_speed_mps == pytest.approx(r * (2.0 * math.pi - 6.0) / 0.1)
    # encoder reset: a jump of 50 rad in 0.1 s is no wheel motion
    assert call(4, [47.0, 47.0, 47.0, 47.0]) == convert.REASON_POSITION_RESET
    s = call(5, [47.1, 47.1, 47.1, 47.1])
    assert s.rim_speed_mps == pytest.approx(0.1)
    # without the helper a positions-only message is still 'no_velocity'
    assert (convert.wheel_from_joint_state(_positions_msg(7, [0.0] * 4), NAMES, r)
            == convert.REASON_NO_VELOCITY)


def test_node_adapter_accepts_positions_only_joint_states():
    from slip_estimator.core.params import Params
    from slip_estimator.ros.adapter import SlipEstimatorAdapter

    adapter = SlipEstimatorAdapter(Params().replace(wheel_input='joint_states',
                                           wheel_joint_names=list(NAMES)))
    for k in range(5):
        adapter.on_joint_states(_positions_msg(1 + k * 100_000_000, [0.1 * k] * 4))
    topic = '/joint_states'
    assert adapter.counters.received[topic] == 5
    assert dict(adapter.counters.rejected) == {(topic, convert.REASON_FIRST_POSITION): 1}


def test_imu_orientation_used_only_when_provided():
    """orientation_covariance[0] = -1 (REP-145: no orientation): no tilt; otherwise the
    quaternion gives the body's roll and pitch through the mounting."""
    import math

    from sensor_msgs.msg import Imu

    from slip_estimator.core.frames import imu_to_body_dcm
    from slip_estimator.ros.convert import imu_from_msg

    m = Imu()
    m.header.stamp.sec = 5
    m.linear_acceleration.z = 9.8
    half = math.radians(5.0) / 2  # imu_link rolled 5 deg about its x axis
    m.orientation.w, m.orientation.x = math.cos(half), math.sin(half)
    C = imu_to_body_dcm([0.0, 0.0, 0.0])
    roll, pitch = imu_from_msg(m, C).tilt_rp_rad
    assert roll == pytest.approx(math.radians(5.0), abs=1e-9) and abs(pitch) < 1e-9
    m.orientation_covariance[0] = -1.0
    assert imu_from_msg(m, C).tilt_rp_rad is None


def test_imu_noise_variances_from_the_message_covariances():
    """The largest diagonal variances when both covariances are given; None when unknown."""
    from sensor_msgs.msg import Imu

    from slip_estimator.ros.convert import imu_from_msg

    m = Imu()
    m.header.stamp.sec = 5
    m.linear_acceleration.z = 9.8
    C = frames.imu_to_body_dcm([0.0, 0.0, 0.0])
    assert imu_from_msg(m, C).noise_var is None
    m.linear_acceleration_covariance[0] = m.linear_acceleration_covariance[8] = 0.0025
    m.linear_acceleration_covariance[4] = 0.003
    assert imu_from_msg(m, C).noise_var is None  # gyro covariance unknown
    m.angular_velocity_covariance[0] = 4e-4
    assert imu_from_msg(m, C).noise_var == (0.003, 4e-4)
