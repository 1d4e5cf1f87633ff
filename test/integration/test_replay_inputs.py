"""Replay of users' own logs: ROS 1 bags, remapped topic names, missing inputs, bad paths and
parameter files, a sensor clock that jumps back (all through ``replay_main`` or ``replay_bag``).
"""
from __future__ import annotations

import math

import pytest
from helpers import (
    T0_NS,
    one_line_exit_2,
    synthetic_messages,
    synthetic_params,
    write_synthetic_bag,
)
from ros1bag import write_ros1_bag

from slip_estimator.bagio import read_messages
from slip_estimator.paramfile import save_params
from slip_estimator.replay import replay_bag, replay_main
from slip_estimator.replay_inputs import ReorderWindow
from slip_estimator.ros.convert import header_stamp_ns, ns_to_stamp
from slip_estimator.ros.finite import message_is_finite


S_NS = 1_000_000_000
JUMP_BACK_S = 300.0


def clock_jump_messages() -> list[tuple[str, object, int]]:
    """12 s of the synthetic drive (stop, then 0.4 m/s at 30 % slip), then 30 s more of the
    same drive at constant speed whose sensor clock restarts ``JUMP_BACK_S`` earlier; log times
    keep increasing."""
    first = synthetic_messages(stationary_s=4.0, drive_s=8.0)
    later = synthetic_messages(stationary_s=4.0, drive_s=36.0, seed=1)
    end_ns = T0_NS + 12 * S_NS
    out = list(first)
    for topic, msg, log_ns in later:
        stamp_ns = header_stamp_ns(msg)
        if stamp_ns < T0_NS + 6 * S_NS:  # the constant-speed part only
            continue
        shift_ns = end_ns - (T0_NS + 6 * S_NS)
        msg.header.stamp = ns_to_stamp(stamp_ns + shift_ns - round(JUMP_BACK_S * S_NS))
        out.append((topic, msg, log_ns + shift_ns))
    return out


def test_backward_clock_jump_is_named_reset_and_slip_resumes(tmp_path):
    bag = write_synthetic_bag(tmp_path / 'jump', clock_jump_messages())
    summary = replay_bag(bag, synthetic_params(), tmp_path / 'out')
    assert summary.resets == 1
    out = list(read_messages(tmp_path / 'out'))
    assert all(message_is_finite(m.msg) for m in out if m.topic != '/slip_estimator/slip')
    jump_ns = T0_NS + 12 * S_NS - round(JUMP_BACK_S * S_NS)
    named = [m for m in out if m.topic == '/diagnostics'
             and 'clock jumped back by 300.0 s' in m.msg.status[0].message]
    assert len(named) == 1 and named[0].msg.status[0].level >= b"\x01"
    assert header_stamp_ns(named[0].msg) - jump_ns < 0.1 * S_NS
    ratios = [m.msg for m in out if m.topic == '/slip_estimator/slip_ratio'
              and header_stamp_ns(m.msg) >= jump_ns]
    assert ratios, 'no slip after the jump'
    assert (header_stamp_ns(ratios[0]) - jump_ns) * 1e-9 <= 30.0
    assert ratios[-1].vector.x == pytest.approx(0.3, abs=0.08)
    assert all(math.isfinite(r.vector.x) for r in ratios)


def test_reorder_window_sorts_within_window_and_flushes_on_jump():
    arrivals = [(round(t * S_NS), '/imu/data', k)
                for k, t in enumerate((100.0, 100.2, 100.1, 100.9, 50.0, 50.1, 49.95))]
    order = [s * 1e-9 for s, _, _ in ReorderWindow(0.5).order(arrivals)]
    # 100.0-100.9 in stamp order before the jump back to 50 (flush), then 49.95 first.
    assert order == pytest.approx([100.0, 100.1, 100.2, 100.9, 49.95, 50.0, 50.1])


def test_ros1_bag_with_remapped_topics(tmp_path, capsys):
    bag = write_ros1_bag(tmp_path / 'field.bag', synthetic_messages(4.0, 6.0),
                         {'/imu/data': '/imu/data_raw', '/joint_states': '/rover/joint_states'})
    params = tmp_path / 'p.yaml'
    save_params(synthetic_params(), params)
    args = [str(bag), '--params-file', str(params), '--output', str(tmp_path / 'out')]
    assert replay_main(args) == 2  # nothing under the expected names: listed, refused
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert '/imu/data_raw [sensor_msgs/msg/Imu]' in err and '/rover/joint_states' in err
    assert replay_main(args + ['-r', '/imu/data_raw:=/imu/data',
                               '--remap', 'rover/joint_states:=joint_states']) == 0
    assert 'replay:' in capsys.readouterr().out
    ratios = [m.msg for m in read_messages(tmp_path / 'out')
              if m.topic == '/slip_estimator/slip_ratio']
    assert ratios and ratios[-1].vector.x == pytest.approx(0.3, abs=0.05)


def test_wheel_input_mismatch_names_topics_and_fails(tmp_path, capsys):
    bag = write_synthetic_bag(tmp_path / 'in', synthetic_messages(3.0, 3.0))
    params = tmp_path / 'p.yaml'
    save_params(synthetic_params().replace(wheel_input='odometry'), params)
    rc = replay_main([str(bag), '--params-file', str(params), '--output', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert rc == 1
    assert '/wheel/odometry [nav_msgs/msg/Odometry]' in err and 'wheel_input: odometry' in err
    assert '/joint_states [sensor_msgs/msg/JointState]' in err
    assert 'no slip could be estimated' in err


def test_bad_inputs_one_line_exit_2(tmp_path, capsys):
    out = ['-o', str(tmp_path / 'out')]
    (tmp_path / 'empty').mkdir()
    (tmp_path / 'notabag').mkdir()
    (tmp_path / 'notabag' / 'notes.txt').write_text('x')
    (tmp_path / 'log.csv').write_text('t,x\n')
    bag = str(write_synthetic_bag(tmp_path / 'in', synthetic_messages(1.0, 1.0)))
    bad_yaml = tmp_path / 'bad.yaml'
    bad_yaml.write_text('slip_estimator:\n  ros__parameters:\n    wheel_radius: [0.1\n')
    for argv, words in (
            ([str(tmp_path / 'nope')], ('nope', 'no such file')),
            ([str(tmp_path / 'empty')], ('empty folder',)),
            ([str(tmp_path / 'notabag')], ('not a rosbag2 bag',)),
            ([str(tmp_path / 'log.csv')], ('not a bag',)),
            ([bag, '--params-file', str(bad_yaml)], ('bad.yaml', 'YAML syntax error at line')),
            ([bag, '--params-file', str(tmp_path / 'none.yaml')], ('none.yaml',)),
            ([bag, '-r', 'imu_only'], ('FROM:=TO',))):
        one_line_exit_2(replay_main, capsys, argv + out, *words)


def test_params_file_misspelled_section_or_name_refused(tmp_path, capsys):
    bag = str(write_synthetic_bag(tmp_path / 'in', synthetic_messages(1.0, 1.0)))
    params = tmp_path / 'p.yaml'
    argv = [bag, '--params-file', str(params), '-o', str(tmp_path / 'out')]
    params.write_text('slip_estimatr:\n  ros__parameters:\n    wheel_radius: 0.12\n')
    one_line_exit_2(replay_main, capsys, argv, "no section for node 'slip_estimator'",
                    'slip_estimatr')
    params.write_text('slip_estimator:\n  ros__parameters:\n    wheel_raduis: 0.12\n')
    one_line_exit_2(replay_main, capsys, argv, 'wheel_raduis')
    params.write_text('/**:\n  ros__parameters:\n    wheel_raduis: 0.12\n'
                      '    allow_unknown_parameters: true\n')
    assert replay_main(argv) in (0, 1)  # runs (2 s of data may be too short for slip)
    assert 'wheel_raduis' not in capsys.readouterr().err


def test_params_file_with_an_old_parameter_name_loads_with_a_one_line_warning(tmp_path, capsys):
    from slip_estimator.paramfile import load_params

    params = tmp_path / 'p.yaml'
    params.write_text('slip_estimator:\n  ros__parameters:\n    moving_speed_threshold: 0.03\n')
    assert load_params(params).moving_speed_threshold_mps == 0.03
    err = capsys.readouterr().err
    assert err == (f'{params}: warning: parameter moving_speed_threshold is renamed '
                   'moving_speed_threshold_mps (the old name still loads; rename it)\n')


def test_ros1_bag_simulated_drive_replay_and_evaluate(tmp_path, capsys):
    """A simulated drive (sensors and truth) rewritten as a ROS 1 bag: replay and evaluate
    read it like the rosbag2 original."""
    from slip_estimator.report import evaluate_main
    from slip_estimator.sim.bag import simulate_main

    assert simulate_main(['--scenario', 'short', '--duration-s', '30', '--output',
                          str(tmp_path / 'sim'), '--params-out', str(tmp_path / 'p.yaml')]) == 0
    messages = [(m.topic, m.msg, m.log_time_ns) for m in read_messages(tmp_path / 'sim')]
    bag = write_ros1_bag(tmp_path / 'sim.bag', messages)
    params = ['--params-file', str(tmp_path / 'p.yaml')]
    assert replay_main([str(bag), *params, '-o', str(tmp_path / 'est1')]) == 0
    assert replay_main([str(tmp_path / 'sim'), *params, '-o', str(tmp_path / 'est2')]) == 0
    capsys.readouterr()
    texts = []
    for est in ('est1', 'est2'):
        assert evaluate_main(['--input', str(bag), '--estimate', str(tmp_path / est),
                              '--params', str(tmp_path / 'p.yaml'), '--report-dir',
                              str(tmp_path / f'rep_{est}'), '--no-plots', '--quiet']) == 0
        texts.append(capsys.readouterr().out)
    assert 'truth: simulation' in texts[0] and 'balanced accuracy' in texts[0]
    assert texts[0] == texts[1]  # the ROS 1 copy replays to the same figures
