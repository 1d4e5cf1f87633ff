"""``slip-estimator setup`` (issue 29) on simulated robots whose true values are known.

Each robot profile (:mod:`slip_estimator.sim.robots`) is simulated, written as its drivers
publish, and set up from a declared file holding only what a user knows from the robot's
documentation (geometry, wheel input): the mounting, the wheel lag, the IMU noise and the start
are left to ``setup``. Checked: the mounting exactly, the lag within 20 ms of the encoders'
mean age (half a wheel period), the effective track within 10 % of the simulated factor, the
radius ratio within 2 % of the true ground/rim speed ratio on the same straight pieces, and the
replay with the written file alone within 0.02 balanced accuracy of the hand-written params.
Then the mountings and IMUs a user gets wrong, a ROS 1 bag with its own topic names, and a log
that cannot decide the mounting.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

from slip_estimator.bagio import read_messages
from slip_estimator.core.params import Params
from slip_estimator.evaluation import evaluate_run
from slip_estimator.paramfile import load_params
from slip_estimator.replay import replay_main
from slip_estimator.report import load_run
from slip_estimator.robot_setup.cli import setup_main
from slip_estimator.robot_setup.measure import Measured, measure, straight_runs, yaw_rate_up
from slip_estimator.robot_setup.scan import Scan, scan_bag
from slip_estimator.sim import simulate
from slip_estimator.sim.bag import write_sim_bag
from slip_estimator.sim.robots import ROBOTS, RobotProfile

UNDECLARED = ('imu_to_base_rpy', 'wheel_latency_s', 'accel_noise_density_mps2_rthz',
              'gyro_noise_density_rps_rthz', 'initial_latitude_deg', 'initial_longitude_deg',
              'initial_height_m', 'initial_heading_deg')
"""What a user does not know before ``setup``: left out of the declared file."""


@dataclass
class SetupRun:
    """A simulated robot set up from its bag."""

    profile: RobotProfile
    result: object
    tmp: Path
    report: str
    hand: Params
    written: Params
    scan: Scan
    measured: Measured


def declared_file(params: Params, path: Path, drop: tuple[str, ...] = UNDECLARED,
                  **override: object) -> Path:
    values = {k: v for k, v in params.to_dict().items() if k not in drop}
    values.update(override)
    path.write_text(yaml.safe_dump({'slip_estimator': {'ros__parameters': values}}))
    return path


def set_up(profile: RobotProfile, tmp: Path, duration_s: float | None = None,
           **override: object) -> SetupRun:
    cfg = profile.scenario
    if duration_s is not None:
        cfg = cfg.replace(duration_s=duration_s)
    profile = dataclasses.replace(profile, scenario=cfg)
    result = simulate(cfg)
    write_sim_bag(result, tmp / 'bag', tmp / 'hand.yaml', profile=profile)
    hand = load_params(tmp / 'hand.yaml')
    declared = declared_file(hand, tmp / 'declared.yaml', **override)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert setup_main([str(tmp / 'bag'), '--declared', str(declared),
                           '--out', str(tmp / 'written.yaml')]) == 0
    report = out.getvalue()
    scan = scan_bag(tmp / 'bag', load_params(declared))
    return SetupRun(profile, result, tmp, report, hand, load_params(tmp / 'written.yaml'),
                    scan, measure(scan.imu, scan.wheels, scan.gnss, hand.track_width))


def balanced_accuracy(run: SetupRun, params_file: Path, name: str) -> float:
    out = run.tmp / name
    assert replay_main([str(run.tmp / 'bag'), '--params-file', str(params_file),
                        '--output', str(out)]) in (0, 1)
    data = load_run(run.tmp / 'bag', out, wheel_radius_m=run.hand.wheel_radius,
                    wheel_joint_names=list(run.hand.wheel_joint_names), progress=False)
    return evaluate_run(data).slip.balanced_accuracy


PROFILES = {'fifty_hz': None, 'skid_steer_30hz': 250.0, 'diff_drive_gravity_free': None}
"""Profile -> drive length, s (None: whole; the skid-steer's only stop is at 236-248 s)."""


@pytest.fixture(scope='module', params=sorted(PROFILES))
def robot(request, tmp_path_factory) -> SetupRun:
    return set_up(ROBOTS[request.param](0), tmp_path_factory.mktemp(request.param),
                  PROFILES[request.param])


def test_mounting_recovered_exactly(robot: SetupRun) -> None:
    true_rpy = robot.profile.scenario.rover.imu_to_base_rpy_rad
    assert robot.measured.mounting.exact, robot.report
    np.testing.assert_allclose(robot.written.imu_to_base_rpy, true_rpy, atol=1e-12)


def test_lag_within_20_ms_of_the_encoders_mean_age(robot: SetupRun) -> None:
    true_lag_s = 0.5 / robot.profile.scenario.rate_wheel_hz
    assert robot.measured.lag_s.n > 100
    assert abs(robot.written.wheel_latency_s - true_lag_s) <= 0.020, robot.report


def test_effective_track_within_10_percent(robot: SetupRun) -> None:
    track = robot.measured.track_m
    factor = robot.profile.scenario.rover.effective_track_factor
    assert track.ok and track.n >= 100 and track.spread < 0.05 * track.value
    assert abs(track.value / robot.hand.track_width / factor - 1.0) <= 0.10, robot.report


def test_radius_ratio_within_2_percent_of_the_truth_on_the_same_runs(robot: SetupRun) -> None:
    """Truth: ground speed over the measured rim speed on each straight piece, median."""
    m, scan, res = robot.measured, robot.scan, robot.result
    yaw = yaw_rate_up(scan.imu, np.array(m.mounting.up_imu),
                      np.array(m.noise.gyro_bias_imu_rps) if m.noise.gyro_bias_imu_rps
                      else None)
    truth = []
    t_true = res.wheel_t_s - res.imu_t_s[0]
    for a, b in straight_runs(scan.wheels, scan.imu, yaw):
        on = (scan.wheels.t_s >= a) & (scan.wheels.t_s <= b)
        true_on = (t_true >= a) & (t_true <= b)
        truth.append(res.wheel_speed_true_mps[true_on].mean() / scan.wheels.v_mps[on].mean())
    ratio = m.radius_ratio
    assert ratio.ok and ratio.n >= 5, ratio
    assert abs(ratio.value - float(np.median(truth))) <= 0.02, (ratio, np.median(truth))


def test_written_file_alone_replays_no_worse_than_the_hand_written(robot: SetupRun) -> None:
    """Balanced accuracy with the file ``setup`` wrote against the hand-written one: at most
    0.02 below it (the skid-steer robot's consumer IMU resolves no body-side slip, and its
    two figures, 0.34 written and 0.16 hand-written, are both near chance: the measured wheel
    lag and noise move single decisions)."""
    if robot.profile.imu_gravity_removed:
        assert 'gravity removed' in robot.report
        pytest.skip('a gravity-free IMU is refused by the estimator (named by setup)')
    written = balanced_accuracy(robot, robot.tmp / 'written.yaml', 'est_written')
    hand = balanced_accuracy(robot, robot.tmp / 'hand.yaml', 'est_hand')
    print(f'{robot.profile.name}: balanced accuracy written {written:.3f} hand {hand:.3f}')
    assert written >= hand - 0.02


def test_every_value_says_where_it_came_from(robot: SetupRun) -> None:
    text = (robot.tmp / 'written.yaml').read_text()
    values = [ln for ln in text.splitlines() if ln.startswith('    ') and not
              ln.lstrip().startswith(('#', '-'))]
    sources = [ln for ln in text.splitlines() if ln.lstrip().startswith('#   <- ')]
    assert len(values) == len(sources) == len(Params.__dataclass_fields__)
    assert any('<- measured' in s for s in sources) and any('<- declared' in s for s in sources)


@pytest.mark.parametrize('rpy, words', [((0.0, 0.0, math.pi / 2), 'yawed 90 deg (sideways)'),
                                        ((math.pi, 0.0, 0.0), 'upside down')])
def test_wrong_mounting_declared_is_found_and_said_in_one_line(rpy, words, tmp_path):
    profile = ROBOTS['fifty_hz'](1)
    rover = dataclasses.replace(profile.scenario.rover, imu_to_base_rpy_rad=rpy)
    profile = dataclasses.replace(profile, scenario=profile.scenario.replace(rover=rover))
    run = set_up(profile, tmp_path, 60.0, drop=UNDECLARED[1:],
                 imu_to_base_rpy=[0.0, 0.0, 0.0])
    lines = [ln for ln in run.report.splitlines() if 'declared (0, 0, 0) deg' in ln]
    assert len(lines) == 1 and words in lines[0], run.report
    np.testing.assert_allclose(run.written.imu_to_base_rpy, rpy, atol=1e-12)


def test_gravity_removed_is_said_in_one_line(tmp_path) -> None:
    run = set_up(ROBOTS['diff_drive_gravity_free'](1), tmp_path, 40.0)
    lines = [ln for ln in run.report.splitlines() if 'gravity removed' in ln]
    assert len(lines) == 2 and lines[1].startswith('PROBLEM:'), run.report
    assert 'publish the raw accelerometer' in lines[1]


def test_mounting_never_guessed_without_motion(tmp_path) -> None:
    """A log at rest: gravity gives up, nothing gives forward: the declared mounting stays and
    the report says so."""
    from slip_estimator.sim.robots import _drive

    profile = ROBOTS['fifty_hz'](2)
    segments = _drive(2, [(15.0, 0.0, 0.0, None, 'stationary')])
    profile = dataclasses.replace(profile, scenario=profile.scenario.replace(
        segments=segments, start_moving=False, duration_s=15.0))
    run = set_up(profile, tmp_path, drop=UNDECLARED[1:],
                 imu_to_base_rpy=[0.0, 0.0, 0.5])
    assert run.written.imu_to_base_rpy == [0.0, 0.0, 0.5]
    assert 'IMU mounting NOT decided' in run.report and 'kept declared' in run.report


def test_ros1_bag_with_its_own_topic_names(tmp_path, capsys) -> None:
    """A ROS 1 bag whose topics are not the node's: setup finds them by type, writes them, and
    replay runs on the written file alone."""
    from ros1bag import write_ros1_bag

    profile = dataclasses.replace(ROBOTS['fifty_hz'](3), wheel_input='joint_states')
    cfg = profile.scenario.replace(duration_s=60.0)
    write_sim_bag(simulate(cfg), tmp_path / 'sim', profile=profile)
    rename = {'/imu/data': '/sensors/imu_raw', '/joint_states': '/drive/joint_states',
              '/wheel/odometry': '/drive/odom_filtered', '/gnss/fix': '/ublox/fix'}
    bag = write_ros1_bag(tmp_path / 'robot.bag',
                         ((m.topic, m.msg, m.log_time_ns) for m in read_messages(tmp_path / 'sim')
                          if not m.topic.startswith('/truth')), rename)
    assert setup_main([str(bag), '--out', str(tmp_path / 'robot.yaml')]) == 0
    report = capsys.readouterr().out
    written = load_params(tmp_path / 'robot.yaml')
    assert (written.imu_topic, written.joint_states_topic, written.wheel_input) == (
        '/sensors/imu_raw', '/drive/joint_states', 'joint_states'), report
    assert '-r /sensors/imu_raw:=/imu/data' in report
    assert replay_main([str(bag), '--params-file', str(tmp_path / 'robot.yaml'),
                        '--output', str(tmp_path / 'out')]) == 0


def test_bag_without_imu_is_one_line(tmp_path, capsys) -> None:
    from ros1bag import write_ros1_bag
    from sensor_msgs.msg import JointState

    msg = JointState()
    msg.header.stamp.sec = 1
    bag = write_ros1_bag(tmp_path / 'x.bag', [('/joint_states', msg, 1_000_000_000)])
    assert setup_main([str(bag), '--out', str(tmp_path / 'x.yaml')]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'no sensor_msgs/Imu topic' in err


def test_measuring_modules_import_no_ros() -> None:
    """The measuring maths (signals, mounting, heading, measure) import numpy and the core
    only: the bag IO is around them."""
    import subprocess
    import sys

    code = ('import sys; import slip_estimator.robot_setup.measure; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "rosbags", "sensor_msgs", "nav_msgs")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == '[]'
