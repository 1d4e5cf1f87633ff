"""Tests of the seeded rover simulator (slip_estimator.sim): truth consistency, IMU physics
(REP-145, strapdown reproduction), slip truth (paper eq. 1), determinism and the bag writer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_estimator.core.frames import C_ENU_NED, rotvec_to_dcm, rpy_to_dcm
from slip_estimator.core.planet import EARTH, earth_rate_n, gravity_n
from slip_estimator.sim.drives import default_scenario, short_scenario
from slip_estimator.sim.rover import SimResult, simulate
from slip_estimator.sim.scenario import (WHEEL_IS_LEFT, WHEEL_JOINT_NAMES, HillSpec,
                                         ImuErrorConfig, RoverConfig, Segment, TerrainConfig)
from slip_estimator.sim.truth import G_FULL, ROLLING_RESISTANCE


@pytest.fixture(scope='module')
def short() -> SimResult:
    return simulate(short_scenario(3))


def _paper_slip(v: float, rw: float) -> float:
    """Paper eq. 1, written out independently of the simulator."""
    if v < rw:
        return 1.0 - v / rw
    if v > rw:
        return rw / v - 1.0
    return 0.0


# --- determinism ----------------------------------------------------------------------------------

def test_same_seeds_give_identical_arrays(short: SimResult) -> None:
    again = simulate(short_scenario(3))
    for name in ('p_ob_o', 'q_ob_wxyz', 'f_ib_imu', 'omega_ib_imu', 'wheel_counts',
                 'slip_true', 'gnss_llh'):
        np.testing.assert_array_equal(getattr(short, name), getattr(again, name), err_msg=name)


def test_noise_seed_changes_noise_not_truth(short: SimResult) -> None:
    other = simulate(short_scenario(3, noise_seed=99))
    for name in ('p_ob_o', 'v_ob_o', 'f_ib_imu_true', 'omega_ib_imu_true', 'slip_true',
                 'rim_speed_true_mps'):
        np.testing.assert_array_equal(getattr(short, name), getattr(other, name), err_msg=name)
    assert np.max(np.abs(short.f_ib_imu - other.f_ib_imu)) > 1e-3
    assert np.max(np.abs(short.omega_ib_imu - other.omega_ib_imu)) > 1e-4
    assert not np.array_equal(short.gnss_llh, other.gnss_llh)


def test_truth_seed_changes_truth(short: SimResult) -> None:
    other = simulate(short_scenario(4, noise_seed=short.config.noise_seed))
    assert np.max(np.abs(short.p_ob_o - other.p_ob_o)) > 0.01


# --- truth kinematics -----------------------------------------------------------------------------

def test_truth_is_kinematically_consistent(short: SimResult) -> None:
    r = short
    # base_link moves along its own x axis only (no side slip modelled)
    np.testing.assert_allclose(r.v_ob_b[:, 1:], 0.0, atol=1e-9)
    np.testing.assert_allclose(r.v_ob_b[:, 0], r.speed_mps, atol=1e-9)
    # the position derivative is the velocity
    dt = 1.0 / r.config.rate_imu_hz
    v_fd = (r.p_ob_o[2:] - r.p_ob_o[:-2]) / (2.0 * dt)
    np.testing.assert_allclose(v_fd, r.v_ob_o[1:-1], atol=2e-4)
    # the quaternion is the DCM
    w, x, y, z = r.q_ob_wxyz[1234]
    C = r.C_base_o[1234]
    assert C[1, 0] - C[0, 1] == pytest.approx(4.0 * w * z, abs=1e-9)
    assert C[2, 1] - C[1, 2] == pytest.approx(4.0 * w * x, abs=1e-9)
    assert r.p_ob_o[0] == pytest.approx(np.zeros(3), abs=1e-12)


def test_rover_follows_the_terrain(short: SimResult) -> None:
    r = short
    z, normal = r.terrain.odom_height_and_normal(r.p_ob_o[:, :2])
    np.testing.assert_allclose(r.p_ob_o[:, 2], z, atol=1e-6)
    # base_link z is the surface normal: the rover sits flat on the ground (pitch and roll)
    np.testing.assert_allclose(r.C_base_o[:, :, 2], normal, atol=1e-6)
    roll = np.degrees(np.arctan2(r.C_base_o[:, 2, 1], r.C_base_o[:, 2, 2]))
    assert np.max(np.abs(roll)) > 3.0


def test_constant_velocity_on_flat_ground_closed_form() -> None:
    """Straight at constant speed on a plane: f = C^T (-g + 2 omega_ie x v), omega = C^T w_ie."""
    segs = (Segment(10.0, label='stationary'), Segment(20.0, 0.5, label='cruise',
                                                       control='body'))
    cfg = short_scenario(0).replace(segments=segs, imu=ImuErrorConfig.ideal(),
                                    rover=RoverConfig(imu_to_base_rpy_rad=(0.0, 0.0, 0.0)),
                                    terrain=TerrainConfig(undulation_amplitude_m=0.0))
    r = simulate(cfg)
    sel = r.imu_t_s > 15.0
    L = math.radians(cfg.site.latitude_deg)
    g_o = C_ENU_NED @ gravity_n(EARTH, L, cfg.site.height_m)
    w_ie = C_ENU_NED @ earth_rate_n(EARTH, L)
    v_o = r.v_ob_o[sel]
    assert np.allclose(np.linalg.norm(v_o, axis=1), 0.5)
    f_expected = np.einsum('nji,nj->ni', r.C_base_o[sel], -g_o + 2.0 * np.cross(w_ie, v_o))
    np.testing.assert_allclose(r.f_ib_imu[sel], f_expected, atol=1e-7)
    w_expected = np.einsum('nji,j->ni', r.C_base_o[sel], w_ie)
    np.testing.assert_allclose(r.omega_ib_imu[sel], w_expected, atol=1e-12)
    # the Coriolis term is really there (7e-5 m/s^2 at 0.5 m/s): resolvable at this tolerance
    assert np.max(np.abs(2.0 * np.cross(w_ie, v_o))) > 1e-5


def test_short_scenario_contents(short: SimResult) -> None:
    r = short
    assert set(np.unique(r.slip_class)) == {0, 1, 2, 3, 4}
    assert np.any(r.slip_true < -0.05), 'negative slip (skid) expected'
    stuck = (r.wheel_speed_true_mps < 0.01) & (r.rim_speed_true_mps.mean(axis=1) > 0.25)
    assert np.any(stuck) and np.all(r.slip_true[stuck] > 0.95)
    # starts stationary for >= 10 s and stops again later for >= 3 s
    moving = (r.speed_mps > 1e-9) | (np.abs(r.omega_eb_b[:, 2]) > 1e-9)
    assert r.imu_t_s[np.argmax(moving)] >= 10.0
    rest = ~moving
    edges = np.flatnonzero(np.diff(rest.astype(int)))
    runs = np.diff(r.imu_t_s[edges])[1::2]  # rest runs after the first start
    assert np.count_nonzero(runs >= 3.0) >= 2
    pitch = np.degrees(np.arcsin(-r.C_base_o[:, 2, 0]))
    assert 5.0 < np.max(np.abs(pitch)) < 16.0
    assert 0.4 < np.max(np.abs(r.omega_eb_b[:, 2])) < 0.6


def test_default_scenario_has_20s_of_every_class() -> None:
    r = simulate(default_scenario(0))
    d = r.class_durations_s()
    assert 300.0 < r.imu_t_s[-1] < 420.0
    for c in (1, 2, 3, 4):
        assert d[c] >= 20.0, (c, d)
    assert d[1] > 0.6 * sum(d[c] for c in (1, 2, 3, 4))


# --- slip truth -----------------------------------------------------------------------------------

def test_slip_truth_matches_rim_speeds_by_eq1(short: SimResult) -> None:
    r = short
    rim_mean = r.rim_speed_true_mps.mean(axis=1)
    for v, rw, s in zip(r.wheel_speed_true_mps, rim_mean, r.slip_true):
        if abs(v) < 1e-12 and abs(rw) < 1e-12:
            assert s == 0.0
            continue
        assert s == pytest.approx(_paper_slip(v, rw), abs=1e-12)
    # classes follow the paper's bounds
    moving = (np.abs(r.wheel_speed_true_mps) >= 0.02) | (np.abs(rim_mean) >= 0.02)
    bounds = np.digitize(np.abs(r.slip_true), [0.2, 0.4, 0.7], right=True) + 1
    np.testing.assert_array_equal(r.slip_class[moving], bounds[moving])
    assert np.all(r.slip_class[~moving] == 0)
    # front and rear wheels of a side turn alike; sides differ by the turn rate
    left = np.array(WHEEL_IS_LEFT)
    np.testing.assert_array_equal(r.rim_speed_true_mps[:, 0], r.rim_speed_true_mps[:, 2])
    np.testing.assert_array_equal(r.rim_speed_true_mps[:, 1], r.rim_speed_true_mps[:, 3])
    turning = np.abs(r.yaw_rate_true_rps) > 0.1
    d = r.rim_speed_true_mps[:, ~left].mean(axis=1) - r.rim_speed_true_mps[:, left].mean(axis=1)
    assert np.all(np.sign(d[turning]) == np.sign(r.yaw_rate_true_rps[turning]))


def test_slip_plateaus_hit_the_commanded_values(short: SimResult) -> None:
    # on a plateau of a segment the truth equals the commanded slip exactly
    cfg = short.config
    starts = np.cumsum([0.0] + [s.duration_s for s in cfg.segments[:-1]])
    checked = 0
    for t0, seg in zip(starts, cfg.segments):
        if seg.speed_mps == 0.0 or seg.yaw_rate_rps != 0.0:
            continue
        sel = (short.wheel_t_s > t0 + seg.speed_ramp_s + 1.0) & \
            (short.wheel_t_s < t0 + seg.duration_s)
        if np.any(sel):
            np.testing.assert_allclose(short.slip_true[sel], seg.slip, atol=1e-9)
            checked += 1
    assert checked >= 4


def test_encoders_measure_the_rim_speed(short: SimResult) -> None:
    r = short
    rim_meas = r.wheel_rate_rps * r.config.rover.wheel_radius_m
    # count differences average over the last wheel period: compare where speeds are steady
    steady = np.zeros(len(r.wheel_t_s), dtype=bool)
    steady[1:] = np.all(np.abs(np.diff(r.rim_speed_true_mps, axis=0)) < 1e-6, axis=1)
    assert np.count_nonzero(steady) > 200
    resolution = 1.0 / (r.config.rover.encoder_pulses_per_m / r.config.rate_wheel_hz)
    err = np.abs(rim_meas[steady] - r.rim_speed_true_mps[steady])
    assert np.max(err) <= resolution + 1e-9
    angle_rate = np.diff(r.wheel_angle_rad, axis=0) * r.config.rate_wheel_hz
    np.testing.assert_allclose(angle_rate, r.wheel_rate_rps[1:], atol=1e-9)


# --- IMU ------------------------------------------------------------------------------------------

def _flat_rest_config(rpy: tuple[float, float, float], imu: ImuErrorConfig):
    segs = (Segment(12.0, label='stationary'),)
    return short_scenario(0).replace(
        segments=segs, imu=imu, rover=RoverConfig(imu_to_base_rpy_rad=rpy),
        terrain=TerrainConfig(hills=(), undulation_amplitude_m=0.0))


def test_rep145_at_rest_level() -> None:
    L = math.radians(39.65)
    g = gravity_n(EARTH, L, 300.0)[2]
    w_up = EARTH.omega_ie_rps * math.sin(L)
    # z-up IMU mount: reads +g on z and the up component of the planet rate on z
    up = simulate(_flat_rest_config((0.0, 0.0, 0.0), ImuErrorConfig.ideal()))
    np.testing.assert_allclose(up.f_ib_imu, np.tile([0.0, 0.0, g], (len(up.imu_t_s), 1)),
                               atol=1e-9)
    np.testing.assert_allclose(up.omega_ib_imu[:, 2], w_up, atol=1e-12)
    assert np.linalg.norm(up.omega_ib_imu[0]) == pytest.approx(EARTH.omega_ie_rps, rel=1e-9)
    # x-fwd / y-right / z-down mount (pi, 0, 0): raw z reads -g
    down = simulate(_flat_rest_config((math.pi, 0.0, 0.0), ImuErrorConfig()))
    mean_f = down.f_ib_imu.mean(axis=0)
    assert mean_f[2] == pytest.approx(-g, abs=0.1)
    # rotated to base_link it is +g again (bias 0.02 m/s^2 1-sigma, noise averages out)
    f_base = rpy_to_dcm(math.pi, 0.0, 0.0) @ mean_f
    assert f_base[2] == pytest.approx(g, abs=0.1)
    # no vibration while the wheels stand still: the noise matches the density
    sigma = np.std(down.f_ib_imu - down.accel_bias_imu, axis=0)
    expected = 1.0e-3 * math.sqrt(250.0)
    np.testing.assert_allclose(sigma, expected, rtol=0.05)


def _strapdown_velocity(r: SimResult, t_end_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Independent flat-earth strapdown in the planet-fixed tangent plane (ENU).

    Attitude: C <- R(-omega_ie dt) C exp([omega_ib dt x]) (Rodrigues increments with the mean
    of consecutive samples); velocity: v <- v + (C f + g - 2 omega_ie x v) dt.
    """
    L = math.radians(r.config.site.latitude_deg)
    g_o = C_ENU_NED @ gravity_n(EARTH, L, r.config.site.height_m)
    w_ie = C_ENU_NED @ earth_rate_n(EARTH, L)
    C_imu_base = rpy_to_dcm(*r.config.rover.imu_to_base_rpy_rad)
    dt = 1.0 / r.config.rate_imu_hz
    f_b = r.f_ib_imu_true @ C_imu_base.T
    w_b = r.omega_ib_imu_true @ C_imu_base.T
    n = int(round(t_end_s / dt))
    C = r.C_base_o[0].copy()
    v = np.zeros(3)
    out = np.empty((n + 1, 3))
    out[0] = v
    R_ie = rotvec_to_dcm(-w_ie * dt)
    for k in range(n):
        C_new = R_ie @ C @ rotvec_to_dcm(0.5 * (w_b[k] + w_b[k + 1]) * dt)
        f_o = 0.5 * (C @ f_b[k] + C_new @ f_b[k + 1])
        v = v + (f_o + g_o - 2.0 * np.cross(w_ie, v)) * dt
        C = C_new
        out[k + 1] = v
    return out, C


@pytest.mark.parametrize('rpy, xyz', [((math.pi, 0.0, 0.0), (0.0, 0.0, 0.0)),
                                      ((0.1, -0.2, 1.3), (0.3, -0.15, 0.4))])
def test_noiseless_imu_reproduces_truth_velocity(rpy, xyz) -> None:
    cfg = short_scenario(5).replace(imu=ImuErrorConfig.ideal(),
                                    rover=RoverConfig(imu_to_base_rpy_rad=rpy,
                                                      imu_to_base_xyz_m=xyz))
    r = simulate(cfg)
    v_ins, C_end = _strapdown_velocity(r, 60.0)
    n = len(v_ins)
    # the IMU point moves with v_base + C (omega x r)
    lever = np.einsum('nij,nj->ni', r.C_base_o[:n], np.cross(r.omega_eb_b[:n], np.array(xyz)))
    err = np.linalg.norm(v_ins - (r.v_ob_o[:n] + lever), axis=1)
    assert np.max(err) < 0.01, np.max(err)
    assert np.max(np.linalg.norm(r.v_ob_o[:n], axis=1)) > 0.4  # it really drove
    # attitude too
    dC = C_end.T @ r.C_base_o[n - 1]
    assert np.linalg.norm(dC - np.eye(3)) < 1e-3


def test_core_strapdown_on_the_noiseless_imu_keeps_the_forward_speed_over_a_crest() -> None:
    """The core's strapdown (``mechanize_step``) of an IMU mounted rotated and 0.5 m off
    base_link, started from the truth every second on its noise-free samples over the rough
    drive's 281-s crest (body pitching 5-10 deg/s nose down), and the forward speed the
    history reads from it (base_link's: the IMU point's less the lever-arm term omega x l),
    keep base_link's true forward speed within what the sampling convention leaves: the core
    applies a sample over the interval before its stamp with the interval's mean attitude, the
    simulator's sample is the value at its stamp, so the specific force that holds the body up
    is rotated by half a sample of pitch, g dt/2 per rad of pitch change (1.7 mm/s per 5 deg at
    250 Hz; up to 2 mm/s per 1-s window here). The lever-arm term is up to 0.04 m/s here: a
    wrong sign or frame of it would read up to 0.08 m/s off."""
    from slip_estimator.core.frames import C_FLU_FRD, imu_to_body_dcm
    from slip_estimator.core.history import ForwardSpeedHistory
    from slip_estimator.core.mechanization import mechanize_step
    from slip_estimator.core.planet import radii_of_curvature
    from slip_estimator.core.state import NavState
    from slip_estimator.sim.drives import patch_scenario

    xyz = (0.3, -0.15, 0.4)
    cfg = patch_scenario(0, rough=True)
    cfg = cfg.replace(imu=ImuErrorConfig.ideal(), rover=RoverConfig(
        imu_to_base_rpy_rad=(0.1, -0.2, 1.3), imu_to_base_xyz_m=xyz))
    r = simulate(cfg)
    C_imu_b = imu_to_body_dcm(cfg.rover.imu_to_base_rpy_rad)
    f_b = (r.f_ib_imu_true @ C_imu_b.T).tolist()
    w_b = (r.omega_ib_imu_true @ C_imu_b.T).tolist()
    C_bn = np.einsum('ij,njk,kl->nil', C_ENU_NED, r.C_base_o, C_FLU_FRD)
    r_b = C_FLU_FRD @ np.array(xyz)  # the IMU in base_link, FRD
    w_eb_b = r.omega_eb_b @ C_FLU_FRD  # FRD
    v_n = (r.v_ob_o @ C_ENU_NED.T
           + np.einsum('nij,nj->ni', C_bn, np.cross(w_eb_b, r_b)))  # the IMU point's
    site = cfg.site
    L0 = math.radians(site.latitude_deg)
    R_N, R_E = radii_of_curvature(EARTH, L0)
    dt = 1.0 / cfg.rate_imu_hz
    n = int(round(1.0 / dt))
    pitch = np.arcsin(-C_bn[:, 2, 0])
    err, dpitch, lever = [], [], []
    for i in range(int(round(270.0 / dt)), int(round(295.0 / dt)), n):
        p = r.p_ob_o[i]
        llh = np.array([L0 + p[1] / (R_N + site.height_m),
                        math.radians(site.longitude_deg)
                        + p[0] / ((R_E + site.height_m) * math.cos(L0)), site.height_m + p[2]])
        state = NavState(C_bn[i].copy(), v_n[i].copy(), llh, np.zeros(3), np.zeros(3))
        for k in range(i + 1, i + n + 1):
            mechanize_step(state, f_b[k], w_b[k], dt, EARTH)
        history = ForwardSpeedHistory(tuple(-r_b))
        history.record(0, state, w_b[i + n], dt)
        err.append(history.newest()[1].v_fwd_mps - r.v_ob_b[i + n, 0])
        dpitch.append(pitch[i + n] - pitch[i])
        lever.append(state.C_b_n[:, 0] @ state.v_eb_n - r.v_ob_b[i + n, 0])
    err, dpitch = np.array(err), np.array(dpitch)
    assert np.min(dpitch) < math.radians(-5.0)  # the crest really pitches the body
    assert np.max(np.abs(lever)) > 0.03  # the IMU point's speed is not base_link's
    # 3 mm/s: the sampling convention's share with margin; the free INS of the rough drive
    # read 34 mm/s short over such windows (the filter's tilt, not the strapdown)
    assert np.max(np.abs(err)) < 3e-3, err


def test_imu_errors_are_present_and_sized(short: SimResult) -> None:
    r = short
    err = r.f_ib_imu - r.f_ib_imu_true
    moving = r.speed_mps > 0.3
    still = r.imu_t_s < 10.0
    # vibration makes the accelerometer much noisier while driving
    assert np.std(err[moving] - r.accel_bias_imu[moving]) > \
        3.0 * np.std(err[still] - r.accel_bias_imu[still])
    # biases are constant + random walk: nonzero and slowly varying
    assert np.all(np.abs(r.gyro_bias_imu[0]) > 0.0)
    assert np.max(np.abs(np.diff(r.accel_bias_imu, axis=0))) < 1e-4


# --- bag round trip -------------------------------------------------------------------------------

def test_bag_round_trip(tmp_path, short: SimResult) -> None:
    pytest.importorskip('rclpy')
    from slip_estimator.bagio import bag_topics, read_messages
    from slip_estimator.paramfile import load_params
    from slip_estimator.sim.bag import ALL_TOPICS, write_sim_bag

    cut = simulate(short.config.replace(duration_s=20.0))
    bag = tmp_path / 'sim'
    params_file = tmp_path / 'sim_params.yaml'
    counts = write_sim_bag(cut, bag, params_file)
    assert set(bag_topics(bag)) == set(ALL_TOPICS)
    seen: dict[str, list] = {t: [] for t in ALL_TOPICS}
    last_log = -1
    for m in read_messages(bag):
        stamp = m.msg.header.stamp.sec * 1_000_000_000 + m.msg.header.stamp.nanosec
        assert stamp == m.log_time_ns
        assert m.log_time_ns >= last_log
        last_log = m.log_time_ns
        seen[m.topic].append(m.msg)
    assert {t: len(v) for t, v in seen.items()} == counts
    assert len(seen['/imu/data']) == len(cut.imu_t_s)
    assert len(seen['/joint_states']) == len(seen['/truth/slip']) == len(cut.wheel_t_s)
    assert len(seen['/truth/odometry']) == len(cut.imu_t_s[::5])
    imu0 = seen['/imu/data'][0]
    assert imu0.header.frame_id == 'imu_link'
    assert imu0.orientation_covariance[0] == -1.0
    assert imu0.linear_acceleration.z == pytest.approx(cut.f_ib_imu[0, 2])
    assert imu0.header.stamp.sec >= 1_600_000_000
    js = seen['/joint_states'][-1]
    assert list(js.name) == list(WHEEL_JOINT_NAMES)
    np.testing.assert_allclose(js.velocity, cut.wheel_rate_rps[-1])
    slip = np.array([[m.vector.x, m.vector.y, m.vector.z] for m in seen['/truth/slip']])
    np.testing.assert_allclose(slip[:, 0], cut.slip_true)
    np.testing.assert_array_equal(slip[:, 2], cut.slip_class)
    odom = seen['/wheel/odometry'][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    truth = seen['/truth/odometry'][-1]
    assert truth.pose.pose.position.x == pytest.approx(cut.p_ob_o[::5][-1, 0])
    fix = seen['/gnss/fix'][0]
    assert fix.latitude == pytest.approx(39.65, abs=1e-5)
    assert fix.position_covariance_type == 2
    p = load_params(params_file)
    assert p.wheel_input == 'joint_states'
    assert p.imu_to_base_rpy == pytest.approx([math.pi, 0.0, 0.0])
    assert p.accel_noise_density_mps2_rthz == pytest.approx(
        cut.config.imu.accel_noise_density_mps2_rthz)


def test_simulator_core_is_ros_free() -> None:
    import subprocess
    import sys
    code = ('import sys, slip_estimator.sim as s; s.simulate(s.short_scenario(0).replace('
            'duration_s=12.0)); bad = [m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "rosbags", "sensor_msgs", "nav_msgs", "yaml")]; print(bad); '
            'sys.exit(1 if bad else 0)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def _flat(segments, **changes):
    return short_scenario(0).replace(segments=tuple(segments), imu=ImuErrorConfig.ideal(),
                                     terrain=TerrainConfig(undulation_amplitude_m=0.0),
                                     **changes)


def test_wheel_control_holds_the_rim_speed_and_slows_the_body() -> None:
    """A sand patch under wheel-rate control: the mean rim speed stays at the command, the
    body slows to r w (1 - s) over the slip ramp, and the IMU's forward specific force shows
    that deceleration (closed form: a = -r w ds/dt)."""
    segs = [Segment(10.0, label='stationary'), Segment(10.0, 0.6, slip=0.05),
            Segment(10.0, 0.6, slip=0.55, slip_ramp_s=2.0), Segment(10.0, 0.6, slip=0.05)]
    r = simulate(_flat(segs))
    rim = r.rim_speed_true_mps.mean(axis=1)
    cruise = (r.wheel_t_s > 14.0) & (r.wheel_t_s < 40.0)
    np.testing.assert_allclose(rim[cruise], 0.6, atol=1e-9)
    inside = (r.wheel_t_s > 23.0) & (r.wheel_t_s < 30.0)
    np.testing.assert_allclose(r.wheel_speed_true_mps[inside], 0.6 * 0.45, atol=1e-9)
    np.testing.assert_allclose(r.slip_true[inside], 0.55, atol=1e-9)
    a = np.gradient(r.speed_mps, r.imu_t_s)
    ramp = (r.imu_t_s > 20.0) & (r.imu_t_s < 22.0)
    assert -0.6 * 0.5 / 2.0 * 1.9 < a[ramp].min() < -0.6 * 0.5 / 2.0  # smootherstep peak 1.875x
    assert np.abs(a[(r.imu_t_s > 23.0) & (r.imu_t_s < 30.0)]).max() < 1e-6
    # the IMU (mounted level here) sees it along its forward axis
    C = rpy_to_dcm(*r.config.rover.imu_to_base_rpy_rad)
    f_base_x = (r.f_ib_imu_true @ C.T)[:, 0]
    np.testing.assert_allclose(f_base_x[ramp], a[ramp], atol=2e-3)


def test_body_runs_ahead_of_the_wheels_downhill() -> None:
    """A scripted run-ahead (not grade-driven): the body at r w / (1 + s) on any ground."""
    segs = [Segment(10.0, label='stationary'), Segment(10.0, 0.5, slip=0.0),
            Segment(10.0, 0.5, slip=-0.2)]
    r = simulate(_flat(segs))
    late = r.wheel_t_s > 22.0
    np.testing.assert_allclose(r.wheel_speed_true_mps[late], 0.5 / 0.8, atol=1e-9)
    assert np.all(r.wheel_speed_true_mps[late] > r.rim_speed_true_mps.mean(axis=1)[late])
    np.testing.assert_allclose(r.slip_true[late], -0.2, atol=1e-9)


def test_body_runs_ahead_of_held_wheels_only_as_far_as_the_grade_drives_it() -> None:
    """A grade-driven run-ahead is gravity's (truth, step 2): on level ground the held wheels hold
    the body (no slip, body at the rim speed); down a hill the slip is the scripted one
    scaled by the downhill grade beyond the rolling resistance (closed form on the truth
    pitch), fully developed where the grade exceeds G_FULL, and the body outruns its wheels."""
    segs = [Segment(10.0, label='stationary'), Segment(10.0, 0.5, slip=0.0),
            Segment(10.0, 0.5, slip=-0.2, grade_driven=True)]
    r = simulate(_flat(segs))
    late = r.wheel_t_s > 22.0
    np.testing.assert_allclose(r.slip_true[late], 0.0, atol=1e-12)
    np.testing.assert_allclose(r.wheel_speed_true_mps[late], 0.5, atol=1e-9)

    hill = TerrainConfig(hills=(HillSpec(18.0, 2.0, 4.0),), undulation_amplitude_m=0.0,
                         hill_jitter_m=0.0)
    r = simulate(_flat(segs).replace(terrain=hill))
    sin_down = np.interp(r.wheel_t_s, r.imu_t_s, -r.C_base_o[:, 2, 0])
    u = np.clip((sin_down - ROLLING_RESISTANCE) / (G_FULL - ROLLING_RESISTANCE), 0.0, 1.0)
    late = r.wheel_t_s > 22.0
    drive = u * u * u * (u * (6.0 * u - 15.0) + 10.0)  # the C2 smootherstep
    np.testing.assert_allclose(r.slip_true[late], -0.2 * drive[late], atol=2e-4)
    full = late & (sin_down > G_FULL)
    assert full.sum() > 50 and np.all(np.abs(r.slip_true[full] + 0.2) < 1e-3)
    rim = r.rim_speed_true_mps.mean(axis=1)
    np.testing.assert_allclose(rim[late], 0.5, atol=1e-9)
    np.testing.assert_allclose(r.wheel_speed_true_mps[full], 0.5 / 0.8, atol=1e-3)


def test_body_control_spins_the_wheels_up_at_an_unchanged_body_speed() -> None:
    segs = [Segment(10.0, label='stationary'), Segment(10.0, 0.5, slip=0.0, control='body'),
            Segment(10.0, 0.5, slip=0.4, control='body')]
    r = simulate(_flat(segs))
    late = r.wheel_t_s > 22.0
    np.testing.assert_allclose(r.wheel_speed_true_mps[late], 0.5, atol=1e-9)
    np.testing.assert_allclose(r.rim_speed_true_mps.mean(axis=1)[late], 0.5 / 0.6, atol=1e-9)


def test_turning_wheels_differ_by_yaw_rate_times_track() -> None:
    segs = [Segment(10.0, label='stationary'), Segment(15.0, 0.5, 0.2, slip=0.0)]
    r = simulate(_flat(segs))
    left = np.array(WHEEL_IS_LEFT)
    steady = r.wheel_t_s > 15.0
    diff = (r.rim_speed_true_mps[:, ~left].mean(axis=1) - r.rim_speed_true_mps[:, left].mean(
        axis=1))[steady]
    np.testing.assert_allclose(diff, r.yaw_rate_true_rps[steady] * r.config.rover.track_width_m,
                               rtol=1e-6)


def test_mixed_drive_has_both_mechanisms() -> None:
    from slip_estimator.sim import mixed_scenario

    cfg = mixed_scenario(0)
    controls = {s.control for s in cfg.segments if s.slip > 0.25}
    assert controls == {'wheel', 'body'}
    r = simulate(cfg)
    assert set(np.unique(r.slip_class)) == {0, 1, 2, 3, 4}


def test_patch_drive_runs_downhill_on_real_slopes() -> None:
    """A run-ahead needs a downhill pull: on rough ground too (where the undulation's slope
    rivals the hill's) the body runs ahead only where the ground is nose-down beyond the
    rolling resistance, never on level or climbing ground."""
    from slip_estimator.sim import patch_scenario

    r = simulate(patch_scenario(0, 300.0, rough=True))
    nose_down = np.degrees(np.arcsin(-r.C_base_o[:, 2, 0]))  # FLU: pitch > 0 is nose down
    neg = r.slip_true < -0.1
    assert neg.sum() > 100
    pitch_w = np.interp(r.wheel_t_s[neg], r.imu_t_s, nose_down)
    assert pitch_w.min() > math.degrees(math.asin(ROLLING_RESISTANCE))
    assert 4.0 < np.median(pitch_w) < 20.0
    assert set(np.unique(r.slip_class)) == {0, 1, 2, 3, 4}


@pytest.mark.parametrize('rate_imu_hz, rate_wheel_hz', [(50.0, 10.0), (100.0, 20.0)])
def test_other_rates(rate_imu_hz, rate_wheel_hz) -> None:
    segs = [Segment(10.0, label='stationary'), Segment(5.0, 0.5)]
    r = simulate(_flat(segs, rate_imu_hz=rate_imu_hz, rate_wheel_hz=rate_wheel_hz,
                       rate_truth_hz=rate_wheel_hz))
    assert len(r.imu_t_s) == pytest.approx(15.0 * rate_imu_hz, abs=2)
    assert len(r.wheel_t_s) == pytest.approx(15.0 * rate_wheel_hz, abs=2)
