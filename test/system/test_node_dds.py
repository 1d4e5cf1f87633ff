"""The real node over real DDS: a bag's messages in, odometry, slip and diagnostics out.

The node runs in a subprocess (``python -m slip_estimator.ros.node`` / the console script) on
an isolated ROS domain with LOCALHOST discovery; this test plays the synthetic drive of
``helpers.synthetic_messages`` through publishers and listens to every output.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from helpers import synthetic_messages, synthetic_params
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState

from slip_estimator.paramfile import save_params
from slip_estimator.ros.finite import message_is_finite


PLAY_SPEED = 2.0
"""Playback speed (x real time): 500 IMU messages/s reach the node."""
DOMAIN_ID = 40 + os.getpid() % 60


def node_env() -> dict[str, str]:
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(DOMAIN_ID), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    return env


def wait_for(predicate, timeout_s: float, what: str, proc: subprocess.Popen | None = None):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        if proc is not None and proc.poll() is not None:
            pytest.fail(f'node exited ({proc.returncode}) while waiting for {what}:\n'
                        f'{proc.communicate()[0]}')
        time.sleep(0.05)
    pytest.fail(f'timeout waiting for {what}')


def stop_node(proc: subprocess.Popen, timeout_s: float = 20.0,
              sig: signal.Signals = signal.SIGINT) -> str:
    """Signal the node (SIGINT, as Ctrl-C) and return its output; fail if it has not exited
    after ``timeout_s`` (its teardown is bounded by ``TEARDOWN_TIMEOUT_S``).

    Tests stop the node before their own client node leaves: a peer leaving during the
    node's DDS teardown is what can trip Fast DDS's teardown deadlock (see node.py)."""
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        return proc.communicate(timeout=timeout_s)[0]
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail(f'node still running {timeout_s} s after SIGINT:\n{proc.communicate()[0]}')


def kv(status: DiagnosticStatus) -> dict[str, str]:
    return {v.key: v.value for v in status.values}


@pytest.fixture
def ros_context(monkeypatch):
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    context = Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    try:
        yield context
    finally:
        rclpy.try_shutdown(context=context)


def n_odometry_played(messages: list) -> int:
    """Odometry messages at 20 Hz of data time over the IMU stamps of ``messages`` (an upper
    bound of what the node publishes: it starts once aligned)."""
    stamps = [log_ns for topic, _, log_ns in messages if topic == '/imu/data']
    return int((stamps[-1] - stamps[0]) * 1e-9 * 20)


@pytest.mark.parametrize('batch', [[], ['-p', 'input_batch_period_s:=0']],
                         ids=['inputs taken in batches', 'woken per message'])
def test_node_over_dds(ros_context, tmp_path, batch):
    params_file = tmp_path / 'params.yaml'
    save_params(synthetic_params(), params_file)
    proc = subprocess.Popen(
        [sys.executable, '-m', 'slip_estimator.ros.node', '--ros-args',
         '--params-file', str(params_file), '-p', 'odometry_rate_hz:=20', *batch],
        env=node_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node('bag_player', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    try:
        received: dict[str, list] = {'odom': [], 'slip': [], 'ratio': [], 'diag': []}
        lock = threading.Lock()

        def collect(key):
            def cb(msg):
                with lock:
                    received[key].append(msg)
            return cb

        out_qos = QoSProfile(depth=2000)
        subs = [node.create_subscription(Odometry, '/slip_estimator/odometry',
                                         collect('odom'), out_qos),
                node.create_subscription(DiagnosticArray, '/slip_estimator/slip',
                                         collect('slip'), out_qos),
                node.create_subscription(Vector3Stamped, '/slip_estimator/slip_ratio',
                                         collect('ratio'), out_qos),
                node.create_subscription(DiagnosticArray, '/diagnostics',
                                         collect('diag'), out_qos)]
        # An IMU driver publishes best effort; the wheel publisher is reliable: both must match
        # the node's sensor-data subscriptions.
        pubs = {'/imu/data': node.create_publisher(
                    Imu, '/imu/data',
                    QoSProfile(depth=500, reliability=ReliabilityPolicy.BEST_EFFORT)),
                '/joint_states': node.create_publisher(JointState, '/joint_states', 100)}
        spinner.start()

        t0 = time.monotonic()
        wait_for(lambda: all(p.get_subscription_count() >= 1 for p in pubs.values())
                 and all(s.get_publisher_count() >= 1 for s in subs),
                 30.0, 'discovery', proc)
        discovery_s = time.monotonic() - t0
        # Matching is seen first on one side: let the node's readers match our writers too,
        # otherwise the first best-effort samples can be dropped before the reader exists.
        time.sleep(1.0)

        messages = synthetic_messages(stationary_s=4.0, drive_s=4.0)
        log0 = messages[0][2]
        start = time.monotonic()
        for topic, msg, log_ns in messages:
            delay = start + (log_ns - log0) * 1e-9 / PLAY_SPEED - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            pubs[topic].publish(msg)
        n_imu = sum(t == '/imu/data' for t, _, _ in messages)
        n_wheel = len(messages) - n_imu

        # After the last IMU message the node's wall-clock watchdog reports STALE with its
        # final counters.
        def stale():
            with lock:
                return [d for d in received['diag']
                        if d.status and d.status[0].level == DiagnosticStatus.STALE]
        n_stale_before = len(stale())  # the watchdog also fired before the playback
        wait_for(lambda: len(stale()) > n_stale_before, 10.0, 'STALE no-IMU diagnostics', proc)
        final = stale()[-1].status[0]
        assert final.message == 'no IMU data'
        counters = kv(final)
        assert counters['/imu/data received'] == str(n_imu), counters  # nothing lost
        assert counters['/joint_states received'] == str(n_wheel), counters
        assert counters['/imu/data stamp_gaps'] == '0'
        # Every callback is timed: the IMU callbacks, and in the all-callbacks window also the
        # wheel callbacks, the output steps (one per odometry message at least) and the timer.
        assert int(counters['callback_window']) == n_imu
        assert int(counters['all_callbacks_window']) > n_imu + n_wheel + n_odometry_played(
            messages) // 2, counters
        for prefix in ('callback', 'all_callbacks'):
            p50, p99, top = (float(counters[f'{prefix}_{k}_ms']) for k in ('p50', 'p99', 'max'))
            assert 0 < p50 <= p99 <= top, counters

        # Runtime parameter changes: invalid rejected with the range, valid accepted.
        client = AsyncParameterClient(node, 'slip_estimator')
        assert client.wait_for_services(10.0)
        fut = client.set_parameters([Parameter('wheel_radius', value=-1.0),
                                     Parameter('odometry_rate_hz', value=10.0)])
        wait_for(fut.done, 10.0, 'set_parameters')
        bad, good = fut.result().results
        assert not bad.successful and 'wheel_radius' in bad.reason and '0.01' in bad.reason
        assert good.successful

        with lock:
            odoms, slips = list(received['odom']), list(received['slip'])
            ratios, diags = list(received['ratio']), list(received['diag'])
        # 8 s of data, aligned after ~2.5 s, odometry at 20 Hz of data time.
        assert 80 <= len(odoms) <= 160
        for m in odoms:
            assert (m.header.frame_id, m.child_frame_id) == ('odom', 'base_link')
            assert message_is_finite(m)
        assert odoms[-1].twist.twist.linear.x == pytest.approx(0.4, abs=0.1)
        assert len(slips) >= n_wheel - 5
        for m in slips:
            (status,) = m.status
            assert status.name == 'slip_estimator: wheel slip'
            assert status.hardware_id == 'base_link'
            values = kv(status)
            assert {'slip_ratio', 'slip_class', 'slip_ratio_std', 'body_speed',
                    'wheel_speed'} <= set(values)
            assert not any(v.lower() in ('nan', 'inf', '-inf') for v in values.values())
        assert ratios and all(message_is_finite(m) for m in ratios)
        assert ratios[-1].vector.x == pytest.approx(0.3, abs=0.05)
        health = [d for d in diags if d.status[0].level != DiagnosticStatus.STALE]
        assert len(health) >= 7 and all(message_is_finite(d) for d in diags)
        print(f'discovery {discovery_s:.1f} s, {len(odoms)} odometry, {len(slips)} slip')
    finally:
        output = stop_node(proc)
        executor.shutdown()
        if spinner.is_alive():  # no spin may use the node being destroyed
            spinner.join(timeout=10.0)
        node.destroy_node()
    assert proc.returncode == 0, output
    assert 'effective parameters' in output and 'wheel_radius=0.12' in output


@pytest.mark.parametrize('command', [
    [str(Path(sys.executable).parent / 'slip-estimator-node')],
    [sys.executable, '-m', 'slip_estimator.ros.node']])
def test_invalid_parameter_refuses_to_start(command):
    proc = subprocess.run(command + ['--ros-args', '-p', 'wheel_radius:=-1.0'],
                          env=node_env(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'wheel_radius' in proc.stderr and '[0.01, 5.0]' in proc.stderr, proc.stderr


def test_invalid_choice_refuses_to_start():
    proc = subprocess.run([sys.executable, '-m', 'slip_estimator.ros.node', '--ros-args',
                           '-p', 'wheel_input:=wheels'],
                          env=node_env(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'wheel_input' in proc.stderr and 'joint_states' in proc.stderr, proc.stderr
