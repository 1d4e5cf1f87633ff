"""Import of the real Pathfinder logs (read from ../shared/data/pathfinder, never copied here).

Checks the converted bags: topics, rates, monotonic stamps, overlapping time bases, the IMU
mounting (+g on base_link z at rest after ``imu_to_base_rpy``), forward-positive wheels while
GNSS shows forward motion, and the params file.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import mat_or_skip as _mat

LOGS = ('test17run', 's5t1')


@pytest.fixture(scope='module', params=LOGS)
def imported(request, tmp_path_factory):
    """(name, log, facts, params, bag path, messages by topic) of one imported log."""
    from slip_estimator.bagio import read_messages
    from slip_estimator.pathfinder import import_pathfinder

    name = request.param
    out = tmp_path_factory.mktemp(name)
    bag, params_path = out / 'bag', out / 'params.yaml'
    log, facts, params = import_pathfinder(_mat(name), bag, params_path)
    topics: dict[str, list] = {}
    for m in read_messages(bag):
        topics.setdefault(m.topic, []).append(m)
    return name, log, facts, params, params_path, topics


def _stamps_s(msgs: list) -> np.ndarray:
    return np.array([m.msg.header.stamp.sec + 1e-9 * m.msg.header.stamp.nanosec for m in msgs])


def test_topics_and_types(imported) -> None:
    _, _, _, _, _, topics = imported
    assert set(topics) == {'/imu/data', '/joint_states', '/gnss/fix'}
    assert topics['/imu/data'][0].msgtype == 'sensor_msgs/msg/Imu'
    assert topics['/joint_states'][0].msgtype == 'sensor_msgs/msg/JointState'
    assert topics['/gnss/fix'][0].msgtype == 'sensor_msgs/msg/NavSatFix'
    assert topics['/imu/data'][0].msg.header.frame_id == 'imu_link'
    assert list(topics['/joint_states'][0].msg.name) == [
        'front_left_wheel_joint', 'front_right_wheel_joint', 'rear_left_wheel_joint',
        'rear_right_wheel_joint']


def test_rates_and_monotonic_stamps(imported) -> None:
    _, _, _, _, _, topics = imported
    for topic, rate in (('/imu/data', 250.0), ('/joint_states', 10.0), ('/gnss/fix', 10.0)):
        t = _stamps_s(topics[topic])
        assert np.all(np.diff(t) > 0), f'{topic} stamps not strictly increasing'
        measured = (len(t) - 1) / (t[-1] - t[0])
        assert measured == pytest.approx(rate, rel=0.05), topic
        # Log time = header stamp (recorded timestamps kept).
        log_ns = np.array([m.log_time_ns for m in topics[topic]])
        assert np.all(np.abs(log_ns * 1e-9 - t) < 1e-6)


def test_time_bases_overlap(imported) -> None:
    name, _, _, _, _, topics = imported
    ti, tw, tg = (_stamps_s(topics[k]) for k in ('/imu/data', '/joint_states', '/gnss/fix'))
    for t in (tw, tg):
        overlap = min(ti[-1], t[-1]) - max(ti[0], t[0])
        assert overlap > 0.95 * (ti[-1] - ti[0]), name
    assert abs(tg[0] - ti[0]) < 1.0     # GPS time of week converted to Unix, leap seconds off
    if name == 'test17run':
        # 1566691200 + TOW - 18: the first GNSS epoch (TOW 79777.6) is 0.14 s before the IMU.
        assert tg[0] == pytest.approx(1566691200 + 79777.6 - 18, abs=1e-3)
        assert np.sum(np.diff(tg) > 0.15) >= 10     # gaps kept, aligned by time


def test_imu_at_rest_gives_plus_g_on_base_z(imported) -> None:
    from slip_estimator.core.frames import rpy_to_dcm

    _, _, facts, params, _, topics = imported
    t0 = topics['/imu/data'][0].log_time_ns * 1e-9
    rest = [m.msg for m in topics['/imu/data']
            if m.log_time_ns * 1e-9 < t0 + facts.motion_start_s - 1.0]
    f_imu = np.array([[m.linear_acceleration.x, m.linear_acceleration.y,
                       m.linear_acceleration.z] for m in rest]).mean(axis=0)
    assert f_imu[2] == pytest.approx(-9.80, abs=0.05)          # z down, specific force up
    f_base = rpy_to_dcm(*params.imu_to_base_rpy) @ f_imu
    assert f_base[2] == pytest.approx(9.80, abs=0.05)          # REP-145: +g on FLU z
    assert np.linalg.norm(f_base) == pytest.approx(9.81, abs=0.03)


def test_gyro_z_down_in_left_turns(imported) -> None:
    name, log, _, _, _, _ = imported
    if name != 's5t1':
        pytest.skip('test17run has no turns')
    diff = (log.wheel_rate_rps[:, 1] + log.wheel_rate_rps[:, 3]
            - log.wheel_rate_rps[:, 0] - log.wheel_rate_rps[:, 2])
    left = log.wheel_t_s[diff > 2.0]            # right wheels clearly faster: left turn
    gz = np.interp(left, log.imu_t_s, log.omega_ib_imu[:, 2])
    assert np.mean(gz) < -0.1                    # FRD: counter-clockwise is negative about z


def test_wheels_forward_positive_while_gnss_moves_forward(imported) -> None:
    from slip_estimator.pathfinder import gnss_enu, rim_speed_mps

    _, log, facts, params, _, topics = imported
    rates = np.array([m.msg.velocity for m in topics['/joint_states']])
    moving = rates.mean(axis=1) * 0.12 > 0.3
    assert moving.sum() > 100
    assert np.all(np.median(rates[moving], axis=0) > 2.0)    # all four wheels forward positive
    # GNSS displacement during the first drive points along the initial heading.
    enu = gnss_enu(log)
    t0 = log.imu_t_s[0] + facts.motion_start_s
    i0, i1 = np.searchsorted(log.gnss_t_s, [t0, t0 + 3.0])
    d = enu[i1, :2] - enu[i0, :2]
    course = math.degrees(math.atan2(d[0], d[1])) % 360.0
    diff = (course - params.initial_heading_deg + 180.0) % 360.0 - 180.0
    assert abs(diff) < 10.0
    assert np.linalg.norm(d) > 1.0
    assert rim_speed_mps(log)[np.searchsorted(log.wheel_t_s, t0 + 1.5)] > 0.3


def test_params_file(imported) -> None:
    from slip_estimator.paramfile import load_params

    name, log, _, params, params_path, _ = imported
    p = load_params(params_path)
    assert p == params
    assert p.wheel_radius == 0.12 and p.track_width == 0.685
    assert p.wheel_input == 'joint_states'
    assert p.imu_to_base_rpy == pytest.approx([math.pi, 0.0, 0.0])
    assert p.initial_latitude_deg == pytest.approx(math.degrees(log.gnss_llh[0, 0]))
    expected = {'test17run': 2.0, 's5t1': 315.0}[name]     # README: ~2 and ~313 deg
    assert abs((p.initial_heading_deg - expected + 180) % 360 - 180) < 5.0
    assert p.gyro_noise_density_rps_rthz == pytest.approx(math.radians(0.1) / 60.0)
    assert p.accel_noise_density_mps2_rthz == pytest.approx(0.008 / 60.0)


def test_facts_test17run_effective_radius(imported) -> None:
    name, _, facts, _, _, _ = imported
    if name != 'test17run':
        pytest.skip('effective radius only from RTK-grade GNSS')
    # GNSS speed / (0.12 m * wheel rate) on the straight RTK drive: r_eff ~ 0.116 m.
    assert 0.94 < facts.gnss_over_wheel_speed < 0.99
    assert 0.0 < facts.wheel_lag_s < 0.3
