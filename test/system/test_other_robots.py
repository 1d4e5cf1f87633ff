"""Issue 10 system tests: other robots than the rover, built like the ones the issue describes
(:mod:`slip_estimator.sim.robots`), written by the simulator's MCAP writer and replayed through
``slip-estimator replay`` (the node adapter) with their declared parameters; and a rate sweep
at core level.

The checks are the issue's: no crash, no NaN; odometry over >= 90 % of the log after its
first 5 s; a known slip over >= 80 % of the moving time (REP-145 IMUs); a gravity-free IMU
named in a non-OK /diagnostics status; on the 395 s skid-steer log the final position error
against GNSS <= 6 m and better than the robot's own wheel odometry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from slip_estimator.bagio import read_messages
from slip_estimator.core.planet import PLANETS, llh_to_local_enu
from slip_estimator.effects import run_core
from slip_estimator.streams import from_simulation
from slip_estimator.replay import replay_main
from slip_estimator.ros.convert import header_stamp_ns
from slip_estimator.sim import simulate
from slip_estimator.sim.bag import sim_params, write_sim_bag
from slip_estimator.sim.robots import ROBOTS, rate_sweep_scenario

_NS = 1_000_000_000
_INPUTS = {'/imu/data', '/gnss/fix', '/truth/slip', '/truth/odometry', '/wheel/odometry'}


@dataclass
class RobotRun:
    """A replayed robot: the input and output messages by topic as (stamp ns, message)."""

    result: object
    topics: dict[str, list[tuple[int, object]]]

    def stamps(self, topic: str) -> np.ndarray:
        return np.array([t for t, _ in self.topics.get(topic, [])], dtype=np.int64)

    def odometry_coverage(self) -> float:
        """Share of the 0.5 s bins after the log's first 5 s that hold an odometry message."""
        t_imu = self.stamps('/imu/data')
        edges = np.arange(t_imu[0] + 5 * _NS, t_imu[-1] + 1, _NS // 2)
        counts = np.histogram(self.stamps('/slip_estimator/odometry'), bins=edges)[0]
        return float(np.mean(counts > 0))

    def known_slip_share(self) -> float:
        """Share of the wheel samples where the robot truly moves that got a known slip."""
        known = {t for t, m in self.topics.get('/slip_estimator/slip_ratio', [])
                 if m.vector.z >= 0}
        moving = [t for t, m in self.topics['/truth/slip'] if m.vector.z > 0]
        return float(np.mean([t in known for t in moving]))

    def honest_slip_share(self) -> float:
        """Share of the known slips of a truly moving robot within max(3 sigma, 0.1) of the
        truth (the sigma it publishes says how far off it may be)."""
        truth = {t: m.vector.x for t, m in self.topics['/truth/slip'] if m.vector.z > 0}
        ok = [abs(m.vector.x - truth[t]) <= max(3.0 * m.vector.y, 0.1)
              for t, m in self.topics.get('/slip_estimator/slip_ratio', [])
              if t in truth and m.vector.z > 0]
        return float(np.mean(ok))

    def all_finite(self) -> bool:
        odo = all(np.isfinite([m.pose.pose.position.x, m.pose.pose.position.y,
                               m.pose.pose.position.z, m.twist.twist.linear.x]).all()
                  and np.isfinite(m.pose.covariance).all()
                  and np.isfinite(m.twist.covariance).all()
                  for _, m in self.topics.get('/slip_estimator/odometry', []))
        slip = all(np.isfinite([m.vector.x, m.vector.y, m.vector.z]).all()
                   for _, m in self.topics.get('/slip_estimator/slip_ratio', []))
        return odo and slip

    def gnss_enu(self) -> tuple[np.ndarray, np.ndarray]:
        fixes = self.topics['/gnss/fix']
        llh = [np.array([math.radians(m.latitude), math.radians(m.longitude), m.altitude])
               for _, m in fixes]
        enu = np.array([llh_to_local_enu(PLANETS['earth'], x, llh[0]) for x in llh])
        return self.stamps('/gnss/fix'), enu[:, :2]

    def displacement_error_m(self, stamps_ns: np.ndarray, xy_m: np.ndarray) -> float:
        """End error of a planar track against GNSS, both taken from the track's first stamp
        (the odometry's origin is where it starts)."""
        tg, enu = self.gnss_enu()
        at = [np.array([np.interp(t, tg, enu[:, k]) for k in range(2)])
              for t in (stamps_ns[0], stamps_ns[-1])]
        return float(np.linalg.norm((xy_m[-1] - xy_m[0]) - (at[1] - at[0])))

    def estimate_error_m(self) -> float:
        odo = self.topics['/slip_estimator/odometry']
        xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for _, m in odo])
        return self.displacement_error_m(self.stamps('/slip_estimator/odometry'), xy)

    def wheel_odometry_error_m(self, track_factor: float = 1.0) -> float:
        """The robot's own wheel odometry over the estimate's interval: its published pose
        (``track_factor`` 1: the geometric track), or its twist dead-reckoned with the yaw
        rate divided by ``track_factor`` (a controller with a hand-tuned track multiplier)."""
        t0 = self.stamps('/slip_estimator/odometry')[0]
        wheel = [(t, m) for t, m in self.topics['/wheel/odometry'] if t >= t0]
        t = np.array([s for s, _ in wheel], dtype=np.int64)
        if track_factor == 1.0:
            xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for _, m in wheel])
            return self.displacement_error_m(t, xy)
        o = wheel[0][1].pose.pose.orientation
        yaw = 2.0 * math.atan2(o.z, o.w)
        xy = [np.zeros(2)]
        for k in range(1, len(wheel)):
            dt = (t[k] - t[k - 1]) * 1e-9
            twist = wheel[k][1].twist.twist
            yaw += twist.angular.z / track_factor * dt
            xy.append(xy[-1] + twist.linear.x * dt * np.array([math.cos(yaw), math.sin(yaw)]))
        return self.displacement_error_m(t, np.array(xy))

    def diagnostics(self) -> list[tuple[int, str]]:
        """(level, message) of every estimator status published."""
        return [(int.from_bytes(s.level, 'little') if isinstance(s.level, bytes) else s.level,
                 s.message)
                for _, d in self.topics.get('/diagnostics', []) for s in d.status]


def replay_robot(name: str, tmp: Path, seed: int = 0) -> RobotRun:
    """Simulate a robot profile, write its bag and params, replay it with the CLI."""
    profile = ROBOTS[name](seed)
    result = simulate(profile.scenario)
    write_sim_bag(result, tmp / 'in', tmp / 'params.yaml', profile=profile)
    assert replay_main([str(tmp / 'in'), '--params-file', str(tmp / 'params.yaml'),
                        '--output', str(tmp / 'out')]) == 0
    topics: dict[str, list] = {}
    for m in read_messages(tmp / 'in', _INPUTS):
        topics.setdefault(m.topic, []).append((header_stamp_ns(m.msg), m.msg))
    for m in read_messages(tmp / 'out'):
        topics.setdefault(m.topic, []).append((m.log_time_ns, m.msg))
    return RobotRun(result, topics)


@pytest.fixture(scope='module')
def skid_steer(tmp_path_factory) -> RobotRun:
    return replay_robot('skid_steer_30hz', tmp_path_factory.mktemp('skid'))


@pytest.fixture(scope='module')
def fifty_hz(tmp_path_factory) -> RobotRun:
    return replay_robot('fifty_hz', tmp_path_factory.mktemp('fifty'))


@pytest.fixture(scope='module')
def diff_drive(tmp_path_factory) -> RobotRun:
    return replay_robot('diff_drive_gravity_free', tmp_path_factory.mktemp('diff'))


def test_skid_steer_robot_is_built_as_described(skid_steer):
    """The profile is the issue's robot: moving at its first sample, 395 s, 30 Hz IMU at rest
    noise ~0.05 m/s^2 / 0.02 rad/s, 10 Hz wheel odometry, one 10 s stop after 236 s."""
    r = skid_steer.result
    assert r.speed_mps[0] > 0.5 and r.imu_t_s[-1] == pytest.approx(395.0)
    assert 1.0 / np.median(np.diff(r.imu_t_s)) == pytest.approx(30.0)
    assert len(skid_steer.topics['/wheel/odometry']) == pytest.approx(3950, abs=2)
    still = r.speed_mps < 1e-3
    assert np.count_nonzero(still) / 30.0 == pytest.approx(10.0, abs=1.0)
    assert 236.0 < r.imu_t_s[still][0] < 242.0
    noise = r.f_ib_imu[still] - r.f_ib_imu_true[still] - r.accel_bias_imu[still]
    assert noise.std(axis=0).max() == pytest.approx(0.05, rel=0.3)


@pytest.mark.parametrize('robot', ['skid_steer', 'fifty_hz'])
def test_rep145_robots_publish_odometry_and_known_slip(robot, request):
    """No NaN; odometry over >= 90 % of the log after its first 5 s and within 2 s of the
    first message; a known slip over >= 80 % of the moving time."""
    run = request.getfixturevalue(robot)
    assert run.all_finite()
    assert run.odometry_coverage() >= 0.9
    first_s = (run.stamps('/slip_estimator/odometry')[0] - run.stamps('/imu/data')[0]) / _NS
    assert first_s <= 2.0
    assert run.known_slip_share() >= 0.8


def test_fifty_hz_robot_slip_is_honest(fifty_hz):
    """Its known slips are within max(3 sigma, 0.1) of the truth (measured 99 %; 91 % before
    the held slip carried its own sigma)."""
    assert fifty_hz.honest_slip_share() >= 0.85


def test_skid_steer_slip_is_honest(skid_steer):
    """The issue's 'honest sigma': known slips within max(3 sigma, 0.1) of the truth. Measured
    90 % (seeds 1-4: 74-91 %): until the first stop, an INS this coarse (its speed over a
    measurement span scatters by more than 0.15 of the rim speed) has zero slip as the
    assumed baseline, so an excursion within the chain's spread of it is not held for the
    drive (74 % before, when a false s = 0.6 was held for 200 s; seeds 1-4: 44-85 %)."""
    assert skid_steer.honest_slip_share() >= 0.8


def test_fifty_hz_robot_position(fifty_hz):
    """Stands 1.2 s, then drives two minutes: the end position is better than its own wheel
    odometry's (measured 1.2 m against 39.6 m published and 15.3 m with the ideal track
    multiplier; 0.9 m before heading and gyro z bias became consider states of the
    body-frame velocity updates)."""
    assert fifty_hz.estimate_error_m() < 2.0
    assert fifty_hz.estimate_error_m() < fifty_hz.wheel_odometry_error_m(1.5)


def test_skid_steer_final_position_within_6_m(skid_steer):
    """The issue's check: <= 6 m against GNSS and better than the robot's own wheel odometry,
    published (geometric track) and with a hand-tuned track multiplier (here the ideal 1.7:
    4.4 m). The wheel yaw-rate aid observes the gyro z bias (compared with the gyro averaged
    over the wheel interval) and the body-frame velocity updates no longer pull heading and z
    bias. Measured 3.05 m: this consumer IMU cannot resolve body-side slip, the slip model
    holds the wheels' speed and the published position advances as wheels + gyro where its
    INS is coarse (core/odometry_guard.py); 2.6 m before, from offsetting along-track
    errors, and 6.4-6.7 m with the better heading alone."""
    error = skid_steer.estimate_error_m()
    assert error <= 6.0
    assert error < skid_steer.wheel_odometry_error_m()
    assert error < skid_steer.wheel_odometry_error_m(1.7)


def test_gravity_free_imu_is_named_and_odometry_comes_from_the_wheels(diff_drive):
    """Positions-only joint states and an IMU without gravity: an ERROR status naming the
    gravity-free IMU and what to fix; odometry from the wheels over the whole log, finite and
    close to the truth; no slip estimate of a moving robot (unknown, not garbage)."""
    run = diff_drive
    errors = [text for level, text in run.diagnostics() if level == 2]
    assert any('gravity removed' in text and 'publish the raw accelerometer' in text
               for text in errors)
    assert run.all_finite()
    assert run.odometry_coverage() >= 0.9
    assert run.estimate_error_m() < 0.1 * 35.0  # wheel dead reckoning over ~35 m
    assert all(m.vector.z <= 0 for _, m in run.topics.get('/slip_estimator/slip_ratio', []))


@pytest.mark.parametrize('rate_imu_hz, rate_wheel_hz', [
    (20.0, 10.0), (50.0, 10.0), (100.0, 10.0), (250.0, 10.0), (1000.0, 10.0),
    (250.0, 5.0), (250.0, 50.0), (250.0, 100.0), (20.0, 100.0), (1000.0, 5.0)])
def test_rate_sweep(rate_imu_hz, rate_wheel_hz):
    """A consumer IMU at 20-1000 Hz and wheels at 5-100 Hz on a short drive (2 s at rest):
    odometry over >= 90 % of the drive after 5 s, known slip over >= 80 % of the moving
    time, no NaN."""
    r = simulate(rate_sweep_scenario(rate_imu_hz, rate_wheel_hz))
    p = sim_params(r)
    every = max(1, int(rate_imu_hz // 20))
    est, out, odo = run_core(p, from_simulation(r, p), odometry_every=every)
    t0 = r.stamps_ns(r.imu_t_s)[0]
    assert np.isfinite(odo).all()
    assert all(math.isfinite(o.slip_ratio) or o.slip_class == -1 for o in out)
    edges = np.arange(t0 + 5 * _NS, r.stamps_ns(r.imu_t_s)[-1] + 1, _NS // 2)
    assert np.mean(np.histogram(odo[:, 0], bins=edges)[0] > 0) >= 0.9
    known = {o.stamp_ns for o in out if o.slip_class >= 0}
    moving = r.stamps_ns(r.wheel_t_s)[r.slip_class > 0]
    assert np.mean([t in known for t in moving.tolist()]) >= 0.8


def test_skid_steer_arcs_with_a_tactical_imu_keep_the_speed():
    """The skid-steer drive with a tactical IMU: its 0.25-0.4 rad/s arcs at 0.6-1.1 m/s are
    arcs, not scrubbing turns (the turn detector weighs the yaw rate x effective track against
    the rim speed), so the lateral constraint and the slip model stay on and the forward
    speed holds (measured RMS 0.18 m/s; 2.1 m/s when every turn above 0.25 rad/s counted as
    scrubbing)."""
    from slip_estimator.sim import ImuErrorConfig

    cfg = ROBOTS['skid_steer_30hz'](0).scenario.replace(imu=ImuErrorConfig.tactical())
    r = simulate(cfg)
    p = sim_params(r)
    est, _, odo = run_core(p, from_simulation(r, p), odometry_every=3)
    v_true = np.interp(odo[:, 0], r.stamps_ns(r.imu_t_s), r.speed_mps)
    assert np.sqrt(np.mean((odo[:, 1] - v_true) ** 2)) < 0.3
    assert est.health().values['effective_track_ratio'] == pytest.approx(1.7, rel=0.1)


def test_simulate_cli_writes_a_robot_bag_and_its_params(tmp_path, capsys):
    """``slip-estimator simulate --robot NAME`` writes that robot's bag and the parameters its
    user would declare (wheel input, the IMU noise left to the messages)."""
    from slip_estimator.core.params import Params
    from slip_estimator.paramfile import load_params
    from slip_estimator.sim.bag import simulate_main

    assert simulate_main(['--robot', 'diff_drive_gravity_free', '-o', str(tmp_path / 'bag'),
                          '--params-out', str(tmp_path / 'p.yaml')]) == 0
    assert 'diff_drive_gravity_free' in capsys.readouterr().out
    p = load_params(tmp_path / 'p.yaml')
    assert p.wheel_input == 'joint_states' and len(p.wheel_joint_names) == 2
    assert p.gyro_noise_density_rps_rthz == Params().gyro_noise_density_rps_rthz
    joints = next(m.msg for m in read_messages(tmp_path / 'bag', {'/joint_states'}))
    assert len(joints.position) == 2 and len(joints.velocity) == 0
