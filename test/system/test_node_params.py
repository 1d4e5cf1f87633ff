"""The real node over real DDS: parameter-file mistakes and the ``~/reset`` service."""
from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import Trigger

from slip_estimator.paramfile import save_params

sys.path.insert(0, str(Path(__file__).parent))
from test_node_dds import kv, node_env, ros_context, stop_node, wait_for  # noqa: E402,F401
from helpers import synthetic_messages, synthetic_params  # noqa: E402

NODE = [sys.executable, '-m', 'slip_estimator.ros.node', '--ros-args']


def run_briefly(args: list[str], seconds: float = 4.0) -> tuple[int | None, str]:
    """Start the node; stop it after ``seconds`` (SIGINT) if it did not exit by itself."""
    proc = subprocess.Popen(NODE + args, env=node_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        out, _ = proc.communicate(timeout=seconds)
        return proc.returncode, out
    except subprocess.TimeoutExpired:
        return None, stop_node(proc)


@pytest.mark.parametrize('after_s', [0.0, 1.0])
def test_sigterm_stops_the_node_cleanly(after_s):
    """SIGTERM (systemd, launch's escalation after SIGINT) ends the node with status 0, while
    it is still being built (0 s after it logs its subscriptions: its service and timer come
    after) and once it spins."""
    proc = subprocess.Popen(NODE, env=node_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    for line in iter(proc.stdout.readline, ''):  # until it is being built (or exits)
        if 'subscribed to' in line:
            break
    time.sleep(after_s)
    out = stop_node(proc, sig=signal.SIGTERM)
    assert proc.returncode == 0, out


def test_misspelled_parameter_refused_unless_allowed(tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text('slip_estimator:\n  ros__parameters:\n    wheel_raduis: 0.2\n')
    rc, out = run_briefly(['--params-file', str(f)], seconds=60.0)
    assert rc == 2 and 'wheel_raduis' in out and 'allow_unknown_parameters' in out, out
    rc, out = run_briefly(['--params-file', str(f), '-p', 'allow_unknown_parameters:=true'])
    assert rc is None, out  # running until stopped
    assert 'ignoring unknown parameter(s) wheel_raduis' in out and 'ERROR' in out, out


def test_removed_parameter_does_not_refuse_the_start(tmp_path):
    """A params file written before a parameter's removal starts the node, as it loads in
    replay (Params.from_dict); a misspelled name in it is still refused."""
    from slip_estimator.paramfile import unknown_parameters

    assert unknown_parameters(['max_wheel_latency_s', 'wheel_radius']) == []
    assert unknown_parameters(['max_wheel_latency', 'wheel_radius']) == ['max_wheel_latency']
    f = tmp_path / 'p.yaml'
    f.write_text('slip_estimator:\n  ros__parameters:\n    max_wheel_latency_s: 0.5\n')
    rc, out = run_briefly(['--params-file', str(f)])
    assert rc is None and 'unknown parameter' not in out, out


def test_renamed_parameter_applies_under_its_old_name_with_a_warning(tmp_path):
    """A params file that sets a parameter under its name before it carried its unit starts the
    node with that value, and one warning names the new name."""
    from slip_estimator.paramfile import unknown_parameters

    assert unknown_parameters(['wheel_aid_std', 'wheel_aid_stdd']) == ['wheel_aid_stdd']
    f = tmp_path / 'p.yaml'
    f.write_text('slip_estimator:\n  ros__parameters:\n    wheel_aid_std: 0.05\n')
    rc, out = run_briefly(['--params-file', str(f)])
    assert rc is None and 'unknown parameter' not in out, out
    assert 'wheel_aid_std_mps=0.05' in out, out
    assert out.count('parameter wheel_aid_std is renamed wheel_aid_std_mps') == 1, out


def test_misspelled_section_reported_loudly(tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text('slip_estimatr:\n  ros__parameters:\n    wheel_radius: 0.2\n')
    rc, out = run_briefly(['--params-file', str(f)])
    assert rc is None, out
    line = next(x for x in out.splitlines() if 'NO section' in x)
    assert '[ERROR]' in line and 'slip_estimatr' in line and '/slip_estimator' in line


def test_yaml_syntax_error_one_line_exit_2(tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text('slip_estimator:\n  ros__parameters:\n    wheel_radius: [0.2\n')
    rc, out = run_briefly(['--params-file', str(f)], seconds=60.0)
    assert rc == 2 and out.strip().count('\n') == 0 and 'YAML syntax error' in out, out


def test_reset_service_applies_pending_change(ros_context, tmp_path):
    params_file = tmp_path / 'params.yaml'
    save_params(synthetic_params(), params_file)
    proc = subprocess.Popen(NODE + ['--params-file', str(params_file)], env=node_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    import rclpy
    node = rclpy.create_node('reset_caller', context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    diags: list[DiagnosticArray] = []
    try:
        node.create_subscription(DiagnosticArray, '/diagnostics', diags.append,
                                 QoSProfile(depth=100))
        imu = node.create_publisher(Imu, '/imu/data', 500)
        client = node.create_client(Trigger, '/slip_estimator/reset')
        spinner.start()
        wait_for(lambda: client.service_is_ready() and imu.get_subscription_count() >= 1,
                 30.0, 'reset service', proc)
        params = AsyncParameterClient(node, 'slip_estimator')
        fut = params.set_parameters([Parameter('odometry_rate_hz', value=5.0)])
        wait_for(fut.done, 10.0, 'set_parameters', proc)
        assert fut.result().results[0].successful
        call = client.call_async(Trigger.Request())
        wait_for(call.done, 10.0, 'reset call', proc)
        assert call.result().success
        assert "parameter change applied: {'odometry_rate_hz': 5.0}" in call.result().message
        for topic, msg, _ in synthetic_messages(1.0, 0.0)[:100]:  # data time for a report
            if topic == '/imu/data':
                imu.publish(msg)

        def reported():
            return [d for d in list(diags) if 'reset requested on ~/reset' in d.status[0].message]
        wait_for(reported, 10.0, 'the reset named in /diagnostics', proc)
        values = kv(reported()[0].status[0])
        assert values['parameter_change_pending'] == 'false' and values['node_resets'] == '1'
    finally:
        stop_node(proc)
        executor.shutdown()
        if spinner.is_alive():  # no spin may use the node being destroyed
            spinner.join(timeout=10.0)
        node.destroy_node()


def test_stuck_teardown_exits_with_the_stacks():
    """A DDS teardown that never returns (Fast DDS's deadlock, here a loop holding the GIL)
    ends the process with status 1 and every thread's stack on stderr; a normal one returns."""
    stuck = ('from slip_estimator.ros.spin import bounded_teardown\n'
             'class Stuck:\n'
             '    def destroy_node(self):\n'
             '        while True:\n'
             '            pass\n'
             'bounded_teardown(Stuck(), timeout_s=0.5)\n')
    proc = subprocess.run([sys.executable, '-c', stuck], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1 and 'Timeout' in proc.stderr, proc.stderr
    assert 'in destroy_node' in proc.stderr and 'in bounded_teardown' in proc.stderr
    normal = ('import time\n'
              'from slip_estimator.ros.spin import bounded_teardown\n'
              'bounded_teardown(None, timeout_s=0.2)\n'
              'time.sleep(0.6)\n'  # the watchdog was cancelled: still alive past it
              'print("alive")\n')
    proc = subprocess.run([sys.executable, '-c', normal], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == 'alive', proc.stderr


@pytest.mark.parametrize('value', ['0.5', 'fast'])
def test_invalid_input_batch_period_refuses_to_start(value):
    """``input_batch_period_s`` out of [0, 0.1] s, or not a number: one line, exit 2."""
    rc, out = run_briefly(['-p', f'input_batch_period_s:={value}'], seconds=60.0)
    assert rc == 2 and 'input_batch_period_s' in out and 'from 0 to 0.1' in out, out


def test_spin_takes_the_inputs_in_arrival_order(ros_context):
    """Under the spin loop's batches the executor does not see the input subscriptions, and
    :meth:`handle_ready_inputs` handles every message that arrived, interleaved IMU and wheel
    messages in the order they were sent (reception stamps), each through its callback."""
    from rclpy.experimental import EventsExecutor

    from slip_estimator.ros.node import SlipEstimatorNode

    node = SlipEstimatorNode(context=ros_context)
    executor = EventsExecutor(context=ros_context)
    node_player = None
    try:
        handled: list[str] = []
        inputs = list(node._subs)

        def recording(topic, callback):
            def run(raw):
                handled.append(topic)
                callback(raw)
            return run
        for sub, topic in zip(inputs, ('/imu/data', '/joint_states')):
            sub.callback = recording(topic, sub.callback)
        node.inputs_taken_by_spin = True
        assert not set(node.subscriptions) & set(inputs)
        executor.add_node(node)  # as spin() does: the executor must not take the inputs
        node_player = rclpy.create_node('player', context=ros_context)
        pubs = {'/imu/data': node_player.create_publisher(Imu, '/imu/data', QoSProfile(depth=500)),
                '/joint_states': node_player.create_publisher(JointState, '/joint_states',
                                                              QoSProfile(depth=100))}
        wait_for(lambda: all(p.get_subscription_count() for p in pubs.values()), 30.0,
                 'discovery')
        time.sleep(0.5)
        messages = synthetic_messages(stationary_s=0.4, drive_s=0.0)
        sent = [topic for topic, _, _ in messages]
        for topic, msg, _ in messages:
            pubs[topic].publish(msg)
            time.sleep(0.0005)
        time.sleep(0.5)
        for _ in range(5):
            executor.spin_once(timeout_sec=0.05)  # timers and services only
        assert handled == []
        node.handle_ready_inputs()
        assert handled == sent and node.input_callbacks == len(sent)
        assert node.adapter.counters.received['/joint_states'] == sent.count('/joint_states')
        assert sent.count('/joint_states') > 1
    finally:
        executor.shutdown()
        node.inputs_taken_by_spin = False
        if node_player is not None:
            node_player.destroy_node()
        node.destroy_node()
