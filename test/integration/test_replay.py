"""Bag replay through the shared adapter: determinism, outputs, stamps, sqlite3 input.

The input is a small synthetic bag (``write_synthetic_bag``: stationary, then a straight drive
with 30 % slip), also used by test_node_dds.py.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import T0_NS, synthetic_messages, synthetic_params, write_synthetic_bag
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from slip_estimator.bagio import bag_topics, read_messages
from slip_estimator.paramfile import load_params, save_params
from slip_estimator.replay import replay_bag, replay_main
from slip_estimator.ros import adapter as ad
from slip_estimator.ros.convert import ns_to_stamp, stamp_to_ns
from slip_estimator.ros.finite import message_is_finite
from slip_estimator.ros.topics import OUTPUT_TYPES, TOPIC_ODOMETRY, TOPIC_SLIP_RATIO

def output_stream(bag: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, canonical CDR bytes) of every message of a bag, in bag order.

    The CDR written by rclpy (Fast CDR) leaves alignment padding uninitialised, so the raw
    bytes of equal messages can differ; rosbags re-serialises them with zeroed padding.
    """
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        return [(c.topic, t, bytes(typestore.serialize_cdr(
                    typestore.deserialize_cdr(raw, c.msgtype), c.msgtype)))
                for c, t, raw in reader.messages()]


@pytest.fixture(scope='module')
def input_bag(tmp_path_factory) -> Path:
    return write_synthetic_bag(tmp_path_factory.mktemp('in') / 'synthetic')


@pytest.fixture(scope='module')
def replayed(input_bag, tmp_path_factory):
    out = tmp_path_factory.mktemp('out') / 'replay'
    summary = replay_bag(input_bag, synthetic_params(), out)
    return summary, out


def test_replay_outputs_present_and_counted(replayed):
    summary, out = replayed
    assert summary.messages_in == 20 * 250 + 20 * 50
    assert summary.inputs == {'/imu/data': 5000, '/joint_states': 1000}
    assert not summary.rejected and not summary.dropped_non_finite
    topics = bag_topics(out)
    assert topics == {
        '/slip_estimator/odometry': 'nav_msgs/msg/Odometry',
        '/slip_estimator/slip': 'diagnostic_msgs/msg/DiagnosticArray',
        '/slip_estimator/slip_ratio': 'geometry_msgs/msg/Vector3Stamped',
        '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray'}
    # Odometry at odometry_rate_hz of data time once aligned, diagnostics every 1 s from the
    # first sample.
    rate = synthetic_params().odometry_rate_hz
    assert 17 * rate <= summary.outputs['/slip_estimator/odometry'] <= 20 * rate
    assert summary.outputs['/diagnostics'] == 20
    # One slip status per wheel sample (allow the last few to be still pending in the core).
    assert 990 <= summary.outputs['/slip_estimator/slip'] <= 1000
    assert summary.data_duration_s == pytest.approx(20.0, abs=0.01)
    assert summary.realtime_ratio > 1.0
    assert 'real time' in summary.line()
    # The phases split the wall time (timed around the phases, nothing overlaps).
    assert min(summary.read_s, summary.estimation_s, summary.write_s) > 0.0
    assert summary.read_s + summary.estimation_s + summary.write_s <= summary.wall_time_s
    assert summary.estimation_realtime_ratio == pytest.approx(
        summary.data_duration_s / summary.estimation_s)
    # The collector settings replay_bag changes while it holds the input are restored.
    import gc
    assert gc.isenabled() and gc.get_freeze_count() == 0


def test_replay_stamps_and_finite(replayed, input_bag):
    _, out = replayed
    input_stamps = {stamp_to_ns(m.msg.header.stamp) for m in read_messages(input_bag)}
    last_log = 0
    classes = []
    for m in read_messages(out):
        assert message_is_finite(m.msg), m.topic
        assert m.log_time_ns in input_stamps
        assert m.log_time_ns >= last_log
        last_log = m.log_time_ns
        stamp = stamp_to_ns(m.msg.header.stamp)
        if m.topic in ('/slip_estimator/odometry', '/diagnostics'):
            assert stamp == m.log_time_ns
        else:
            # Slip refers to a wheel sample time (or, for a wheel dropout, the IMU time).
            assert stamp in input_stamps and stamp <= m.log_time_ns
        if m.topic == '/slip_estimator/odometry':
            assert (m.msg.header.frame_id, m.msg.child_frame_id) == ('odom', 'base_link')
        if m.topic == '/slip_estimator/slip':
            (status,) = m.msg.status
            kv = {v.key: v.value for v in status.values}
            assert {'slip_ratio', 'slip_class', 'slip_ratio_std', 'body_speed',
                    'wheel_speed'} <= set(kv)
            assert not any(v.lower() in ('nan', 'inf', '-inf') for v in kv.values())
        if m.topic == '/slip_estimator/slip_ratio':
            classes.append((stamp, m.msg.vector.x, int(m.msg.vector.z)))
    # Straight drive with 30 % slip: slip seen as 'medium' at cruise speed.
    cruise = [s for t, s, _ in classes if t > T0_NS + 15 * 10**9]
    assert cruise and abs(float(np.median(cruise)) - 0.3) < 0.05
    standing = [c for t, _, c in classes if t < T0_NS + 9 * 10**9]
    assert standing and all(c == 0 for c in standing)


def test_replay_deterministic(replayed, input_bag, tmp_path):
    _, out = replayed
    again = tmp_path / 'again'
    replay_bag(input_bag, synthetic_params(), again)
    assert output_stream(again) == output_stream(out)


def test_replay_sqlite3_input_same_as_mcap(replayed, tmp_path):
    _, out = replayed
    db_bag = write_synthetic_bag(tmp_path / 'sqlite', sqlite3=True)
    assert list(db_bag.glob('*.db3'))
    replay_bag(db_bag, synthetic_params(), tmp_path / 'from_sqlite')
    assert output_stream(tmp_path / 'from_sqlite') == output_stream(out)


def test_replay_bad_input_counted_never_nan(tmp_path):
    messages = synthetic_messages(stationary_s=4.0, drive_s=4.0)
    imus = [m for t, m, _ in messages if t == '/imu/data']
    imus[100].linear_acceleration.x = math.nan
    imus[200].header.stamp = ns_to_stamp(0)
    joints = [m for t, m, _ in messages if t == '/joint_states']
    joints[250].velocity = [math.inf] * 4
    joints[300].velocity = [1000.0] * 4
    bag = write_synthetic_bag(tmp_path / 'bad', messages)
    summary = replay_bag(bag, synthetic_params(), tmp_path / 'out')
    assert summary.rejected == {'/imu/data non_finite': 1, '/imu/data zero_stamp': 1,
                                '/joint_states absurd_wheel_speed': 1,
                                '/joint_states non_finite': 1}
    for m in read_messages(tmp_path / 'out'):
        assert message_is_finite(m.msg)
    diags = [m.msg for m in read_messages(tmp_path / 'out', {'/diagnostics'})]
    kv = {v.key: v.value for v in diags[-1].status[0].values}
    assert kv['/imu/data rejected non_finite'] == '1'
    assert kv['/joint_states rejected absurd_wheel_speed'] == '1'


def test_replay_main_cli(input_bag, tmp_path, capsys):
    params_file = tmp_path / 'params.yaml'
    save_params(synthetic_params(), params_file)
    assert replay_main([str(input_bag), '--params-file', str(params_file),
                        '--output', str(tmp_path / 'cli_out')]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith('replay: 6000 messages in') and 'real time' in line
    assert all(part in line for part in ('bag read', 'estimation', 'bag write'))
    # Existing output and an invalid parameter file refuse to run.
    assert replay_main([str(input_bag), '--output', str(tmp_path / 'cli_out')]) == 2
    params_file.write_text('slip_estimator:\n  ros__parameters:\n    wheel_radius: -1.0\n')
    assert replay_main([str(input_bag), '--params-file', str(params_file),
                        '--output', str(tmp_path / 'x')]) == 2
    assert 'wheel_radius' in capsys.readouterr().err


def test_adapter_decimation_and_reset_on_jump_back():
    params = synthetic_params().replace(odometry_rate_hz=10.0, diagnostics_period_s=0.5)
    adapter = ad.SlipEstimatorAdapter(params)
    messages = synthetic_messages(stationary_s=4.0, drive_s=0.0)
    topics = []
    for topic, msg, _ in messages:
        topics += [t for t, _ in adapter.on_message(topic, msg)]
    assert topics.count('/diagnostics') == 8
    assert 15 <= topics.count('/slip_estimator/odometry') <= 40
    # A duplicate IMU stamp is rejected; a jump back by > 1 s restarts with pending params.
    imu = [m for t, m, _ in messages if t == '/imu/data']
    assert adapter.on_imu(imu[-1]) == []
    assert adapter.counters.rejected['/imu/data', 'non_monotonic'] == 1
    adapter.request_params(params.replace(odometry_rate_hz=0.0))
    assert adapter.pending_params is not None
    adapter.on_imu(imu[0])
    assert adapter.counters.resets == 1 and adapter.params.odometry_rate_hz == 0.0
    assert adapter.pending_params is None


def _message_object_replay(bag: Path, params) -> dict[str, list]:
    """The replay's outputs as the message-object path gives them: every input deserialized
    by rclpy into a message, converted by ``convert.*_from_msg`` (``adapter.on_message``), in
    the replay's order."""
    from slip_estimator.replay_inputs import ReorderWindow

    adapter = ad.SlipEstimatorAdapter(params)
    arrivals = ((stamp_to_ns(m.msg.header.stamp), m.topic, m.msg)
                for m in read_messages(bag, set(adapter.input_types)))
    out: dict[str, list] = {t: [] for t in OUTPUT_TYPES}
    for stamp_ns, topic, msg in ReorderWindow().order(arrivals):
        for t, o in adapter.on_message(topic, msg):
            out[t].append((stamp_ns, o))
    return out


@pytest.mark.parametrize('wheel_input', ['joint_states', 'odometry'])
def test_replay_from_bytes_equals_message_objects(tmp_path, wheel_input):
    """The replay decodes the serialized inputs itself (ros.cdr, the IMU in batches): every
    output message is the one the rclpy message objects give, field by field, bit for bit
    (bench.identical's comparison), on a simulated drive with turns, hills, stops and slip."""
    from slip_estimator.bench.identical import compare_messages
    from slip_estimator.sim.bag import write_sim_bag
    from slip_estimator.sim.drives import short_scenario
    from slip_estimator.sim.rover import simulate

    write_sim_bag(simulate(short_scenario(1).replace(duration_s=60.0)), tmp_path / 'sim',
                  tmp_path / 'params.yaml')
    params = load_params(tmp_path / 'params.yaml').replace(wheel_input=wheel_input)
    replay_bag(tmp_path / 'sim', params, tmp_path / 'out')
    expected = _message_object_replay(tmp_path / 'sim', params)
    got: dict[str, list] = {t: [] for t in OUTPUT_TYPES}
    for m in read_messages(tmp_path / 'out'):
        got[m.topic].append((m.log_time_ns, m.msg))
    assert len(got[TOPIC_SLIP_RATIO]) > 100 and len(got[TOPIC_ODOMETRY]) > 100
    for topic in OUTPUT_TYPES:
        assert compare_messages(expected[topic], got[topic], topic) == []
    # The comparison sees a one-bit change of one field.
    t, odo = got[TOPIC_ODOMETRY][50]
    odo.pose.pose.position.x = np.nextafter(odo.pose.pose.position.x, math.inf)
    assert compare_messages(expected[TOPIC_ODOMETRY], got[TOPIC_ODOMETRY],
                            TOPIC_ODOMETRY) == [
        f'{TOPIC_ODOMETRY}[50].pose.pose.position.x: '
        f'{expected[TOPIC_ODOMETRY][50][1].pose.pose.position.x!r} vs '
        f'{odo.pose.pose.position.x!r}']


def test_replay_simulated_bag_wheel_odometry_input(tmp_path):
    """The simulator's short scenario (turns, hills, stops, high slip), wheels taken from
    /wheel/odometry: every wheel sample gets a slip status, nothing is rejected or non-finite."""
    from slip_estimator.sim.bag import write_sim_bag
    from slip_estimator.sim.rover import simulate
    from slip_estimator.sim.drives import short_scenario

    write_sim_bag(simulate(short_scenario(0)), tmp_path / 'sim', tmp_path / 'params.yaml')
    params = load_params(tmp_path / 'params.yaml').replace(wheel_input='odometry')
    summary = replay_bag(tmp_path / 'sim', params, tmp_path / 'out')
    assert set(summary.inputs) == {'/imu/data', '/wheel/odometry'}
    assert not summary.rejected and not summary.dropped_non_finite
    wheel_stamps = {stamp_to_ns(m.msg.header.stamp)
                    for m in read_messages(tmp_path / 'sim', {'/wheel/odometry'})}
    slip_stamps = set()
    for m in read_messages(tmp_path / 'out'):
        assert message_is_finite(m.msg), m.topic
        if m.topic == '/slip_estimator/slip':
            slip_stamps.add(stamp_to_ns(m.msg.header.stamp))
    assert len(wheel_stamps - slip_stamps) <= 2  # the last samples may still be pending
    assert {1, 2, 3} <= {int(m.msg.vector.z) for m in
                         read_messages(tmp_path / 'out', {'/slip_estimator/slip_ratio'})}


def test_compare_json_finds_the_largest_difference():
    """Two figure files: every number compared, the largest absolute difference and where;
    NaN equals NaN, NaN against a number is infinitely different; other differences named."""
    from slip_estimator.bench.identical import compare_json

    a = {'rows': [{'ba': 0.5, 'fa': float('nan'), 'name': 'short'}, {'ba': 0.25, 'n': 3}]}
    assert compare_json(a, a) == (4, 0.0, '.rows[0].ba', [])
    b = {'rows': [{'ba': 0.5, 'fa': float('nan'), 'name': 'short'}, {'ba': 0.25 + 1e-15, 'n': 3}]}
    n, worst, where, other = compare_json(a, b)
    assert (n, where, other) == (4, '.rows[1].ba', []) and 0.0 < worst < 2e-15
    c = {'rows': [{'ba': 0.5, 'fa': 0.1, 'name': 'rough'}], 'extra': 1}
    n, worst, where, other = compare_json(a, c)
    assert worst == float('inf') and where == '.rows[0].fa' and len(other) == 3
