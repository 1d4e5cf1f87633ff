"""Initial alignment: closed-form levelling in motion, and a simulated drive joined while the
rover is already moving (no stationary window at all)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slip_estimator.core.alignment import gravity_specific_force, level
from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.effects import run_core
from slip_estimator.streams import from_simulation
from slip_estimator.sim import short_scenario, simulate
from slip_estimator.sim.bag import sim_params


def test_levelling_in_motion_removes_the_wheel_derived_acceleration():
    """FRD body rolled 3 deg and pitched -4 deg, accelerating 0.4 m/s^2 while turning right at
    0.3 rad/s at 0.8 m/s: the specific force is a - g; less the wheel-derived acceleration and
    the centripetal term it levels exactly, and without them it would be off by degrees."""
    roll, pitch = math.radians(3.0), math.radians(-4.0)
    C_b_n = rpy_to_dcm(roll, pitch, 0.7)
    g_b = C_b_n.T @ np.array([0.0, 0.0, 9.81])
    a_b = np.array([0.4, 0.3 * 0.8, 0.0])
    f_b = a_b - g_b
    assert level(gravity_specific_force(f_b, 0.8, 0.4, 0.3)) == pytest.approx((roll, pitch),
                                                                               abs=1e-12)
    naive = level(f_b)
    assert abs(naive[1] - pitch) > math.radians(2.0)


def _joined_in_motion(t_join_s: float):
    r = simulate(short_scenario(0))
    p = sim_params(r)
    d = from_simulation(r, p)
    t0 = d.imu_ns[0] + int(t_join_s * 1e9)
    keep_imu, keep_wheel = d.imu_ns >= t0, d.wheel_ns >= t0
    joined = dataclasses.replace(d, imu_ns=d.imu_ns[keep_imu], f_ib_b=d.f_ib_b[keep_imu],
                                 omega_ib_b=d.omega_ib_b[keep_imu],
                                 wheel_ns=d.wheel_ns[keep_wheel], rim_mps=d.rim_mps[keep_wheel])
    return r, p, joined, t0


def test_a_drive_joined_while_moving_gives_odometry_and_slip():
    """Joined at 22 s (cruising at 0.5 m/s): odometry within 2 s of the first message, slip
    known after ``recovery_s`` plus a measurement, no NaN. Without a stop the velocity is
    anchored on the rim speed at zero slip, so until the first stop the speed carries the
    slip of the ground it started on (measured: +0.03-0.04 m/s at s = 0.05, 0.07 m/s RMS over
    the next 20 s with an uphill patch, against 0.02 for a start from rest); after the first
    stop's ZUPT it is as good as a start from rest."""
    r, p, data, t0 = _joined_in_motion(22.0)
    est, out, odo = run_core(p, data, odometry_every=5)
    assert odo[0, 0] - t0 <= 2e9
    v_true = np.interp(odo[:, 0], r.stamps_ns(r.imu_t_s), r.v_ob_b[:, 0])
    later = (odo[:, 0] > t0 + 10e9) & (odo[:, 0] < t0 + 30e9)
    assert np.sqrt(np.mean((odo[later, 1] - v_true[later]) ** 2)) < 0.1
    after_stop = (odo[:, 0] > t0 + 35e9) & (odo[:, 0] < t0 + 44e9)  # the stop: 54-59 s
    assert np.sqrt(np.mean((odo[after_stop, 1] - v_true[after_stop]) ** 2)) < 0.05
    assert all(np.isfinite(o.slip_ratio) or o.slip_class == -1 for o in out)
    known = [o for o in out if o.stamp_ns > t0 + int((p.recovery_s + 2.0) * 1e9)]
    assert np.mean([o.slip_class >= 0 for o in known]) > 0.95
    assert 'aligned in motion' in est.health().values.get('events', '') or est.aligned


def test_in_motion_attitude_error_is_within_a_degree():
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.core.types import ImuSample, WheelSample

    r, p, d, t0 = _joined_in_motion(22.0)
    est = SlipEstimator(p)
    j = 0
    for i, stamp in enumerate(d.imu_ns.tolist()):
        while j < len(d.wheel_ns) and d.wheel_ns[j] < stamp:
            x = d.rim_mps[j]
            est.add_wheel(WheelSample(int(d.wheel_ns[j]), float(x.mean()),
                                      float(x[[0, 2]].mean()), float(x[[1, 3]].mean())))
            j += 1
        est.add_imu(ImuSample(stamp, d.f_ib_b[i], d.omega_ib_b[i]))
        if est.aligned:
            break
    assert (stamp - t0) * 1e-9 <= p.motion_alignment_after_s + 0.1
    k = np.argmin(abs(r.stamps_ns(r.imu_t_s) - stamp))
    C_true = r.C_base_o[k]  # base_link FLU in odom ENU
    C_est = est.state.C_b_n  # FRD in NED
    # compare the down axis seen in body axes: the tilt, whatever the heading
    down_true_flu = C_true.T @ np.array([0.0, 0.0, -1.0])
    down_est_frd = C_est.T @ np.array([0.0, 0.0, 1.0])
    down_est_flu = down_est_frd * np.array([1.0, -1.0, -1.0])
    angle = math.degrees(math.acos(np.clip(down_true_flu @ down_est_flu, -1.0, 1.0)))
    assert angle < 1.0


@pytest.mark.parametrize('scale, rotate_deg, expected', [
    (1.0, 0.0, None),
    (0.0, 0.0, 'gravity removed'),
    (1.0 / 9.81, 0.0, 'acceleration in g'),
    (1.0, 90.0, 'imu_to_base_rpy'),
])
def test_non_rep145_imus_are_named_and_not_aligned_on(scale, rotate_deg, expected):
    """The same drive with the IMU's gravity removed, in g, or mounted 90 deg off its declared
    rotation: named at start in the health message (ERROR); no INS estimate and no slip, the
    pose from the wheels alone (degraded mode)."""
    r = simulate(short_scenario(0))
    p = sim_params(r)
    d = from_simulation(r, p)
    f = d.f_ib_b * scale if scale else d.f_ib_b - np.median(d.f_ib_b[:500], axis=0)
    f = f @ rpy_to_dcm(math.radians(rotate_deg), 0.0, 0.0).T
    cut = d.imu_ns < d.imu_ns[0] + int(20e9)
    d = dataclasses.replace(d, imu_ns=d.imu_ns[cut], f_ib_b=f[cut], omega_ib_b=d.omega_ib_b[cut])
    est, out, odo = run_core(p, d)
    health = est.health()
    if expected is None:
        assert est.aligned and health.level < 2
    else:
        assert not est.aligned
        assert health.level == 2 and expected in health.message
        assert 'odometry from the wheels' in health.message
        assert all(o.slip_class <= 0 for o in out)
        pose = est.odometry()
        travelled = float(np.sum(np.diff(r.imu_t_s[r.imu_t_s < 20.0]) *
                                 r.speed_mps[r.imu_t_s < 20.0][1:]))
        assert np.linalg.norm(pose.p_ob_o) == pytest.approx(travelled, rel=0.2)
        assert np.isfinite(pose.p_ob_o).all() and np.isfinite(pose.pose_covariance).all()


@pytest.mark.parametrize('rate_imu_hz, rate_wheel_hz', [(50.0, 10.0), (100.0, 50.0)])
def test_other_imu_rates_align_and_estimate(rate_imu_hz, rate_wheel_hz):
    """Windows are in seconds: at 50 and 100 Hz the stationarity window holds 0.5 s of the
    IMU's own samples, the static alignment happens in the first stop and slip is read."""
    cfg = short_scenario(0).replace(rate_imu_hz=rate_imu_hz, rate_wheel_hz=rate_wheel_hz,
                                    rate_truth_hz=rate_wheel_hz)
    r = simulate(cfg)
    p = sim_params(r)
    est, out, odo = run_core(p, from_simulation(r, p))
    assert est.stationary.window_samples == round(p.stationary_window_s * rate_imu_hz)
    assert (odo[0, 0] - r.stamps_ns(r.imu_t_s)[0]) * 1e-9 < 5.0
    moving = [o for o in out if o.slip_class > 0]
    assert len(moving) > 0.5 * rate_wheel_hz * 40


def test_a_noisy_consumer_imu_still_finds_its_stops():
    """Rest noise above the configured stationarity limits (accel 4x, gyro 12x the tactical
    IMU: ~0.06 m/s^2 and 0.02 rad/s at 250 Hz, like the consumer IMUs users bring): the
    detector learns the IMU's own spread while the wheels are stopped, so the ZUPT and ZARU
    fire at the stops; with the limits fixed they never would."""

    base = short_scenario(0)
    imu = dataclasses.replace(base.imu, accel_noise_density_mps2_rthz=4.0e-3,
                              gyro_noise_density_rps_rthz=1.2e-3)
    r = simulate(base.replace(imu=imu))
    p = sim_params(r)
    est, out, odo = run_core(p, from_simulation(r, p))
    assert est.stationary.rest_std is not None
    assert est.stationary.thresholds()[1] > p.stationary_gyro_std_rps
    assert est.counters['zupt'] > 50 and est.counters['zaru'] > 50


def test_consumer_imu_at_30_hz_joined_while_moving():
    """A consumer MEMS IMU at 30 Hz (wheels 10 Hz) on a drive that is already moving when the
    node starts and never stops afterwards: odometry from the first 2 s, slip known for most
    of the drive, no NaN. (The accuracy such an IMU supports is not asserted here.)"""
    from slip_estimator.sim import ImuErrorConfig

    base = short_scenario(0)
    cfg = base.replace(segments=base.segments[:7], imu=ImuErrorConfig.consumer_mems(),
                       rate_imu_hz=30.0, rate_wheel_hz=10.0, rate_truth_hz=10.0)
    cfg = cfg.replace(gnss=dataclasses.replace(cfg.gnss, rate_hz=10.0))
    r = simulate(cfg)
    p = sim_params(r)
    d = from_simulation(r, p)
    t0 = d.imu_ns[0] + int(22e9)
    ki, kw = d.imu_ns >= t0, d.wheel_ns >= t0
    d = dataclasses.replace(d, imu_ns=d.imu_ns[ki], f_ib_b=d.f_ib_b[ki],
                            omega_ib_b=d.omega_ib_b[ki], wheel_ns=d.wheel_ns[kw],
                            rim_mps=d.rim_mps[kw])
    est, out, odo = run_core(p, d, odometry_every=1)
    assert odo[0, 0] - t0 <= 2e9
    assert np.isfinite(odo).all()
    assert est.stationary.window_samples == round(p.stationary_window_s * 30.0)
    known = [o.slip_class >= 0 for o in out if o.stamp_ns > t0 + int(6e9)]
    assert np.mean(known) > 0.9


@pytest.mark.parametrize('factor', [1.0, 1.6])
def test_skid_steer_effective_track_width_is_estimated(factor):
    """The simulated skid-steer turns need yaw rate x track x factor of wheel differential
    (times the slip gain of the turning ground): the estimate finds the ratio the true rims
    and yaw rates give (least squares over the turning samples) and reports it."""
    from slip_estimator.sim.scenario import WHEEL_IS_LEFT

    base = short_scenario(0)
    cfg = base.replace(rover=dataclasses.replace(base.rover, effective_track_factor=factor))
    r = simulate(cfg)
    p = sim_params(r)
    est, _, _ = run_core(p, from_simulation(r, p))
    left = np.array(WHEEL_IS_LEFT)
    rims = r.rim_speed_true_mps
    diff = rims[:, ~left].mean(axis=1) - rims[:, left].mean(axis=1)
    w = r.yaw_rate_true_rps
    turning = np.abs(w) > 0.1
    truth = float(diff[turning] @ w[turning] / (w[turning] @ w[turning])) / p.track_width
    assert truth == pytest.approx(factor, rel=0.15)
    ratio = est.health().values['effective_track_ratio']
    assert ratio == pytest.approx(truth, rel=0.05)


def test_without_wheels_the_ins_runs_and_slip_is_stale_with_the_reason():
    """No wheel data at all: the filter aligns at rest on the IMU alone, runs as an INS with
    ZUPT/ZARU, publishes odometry, and reports slip 'unknown' once per wheel timeout, naming
    the reason in the health message."""
    r = simulate(short_scenario(0))
    p = sim_params(r)
    d = from_simulation(r, p)
    d = dataclasses.replace(d, wheel_ns=d.wheel_ns[:0], rim_mps=d.rim_mps[:0])
    est, out, odo = run_core(p, d)
    assert est.aligned and len(odo) > 0 and np.isfinite(odo).all()
    assert est.counters['zupt'] > 0
    assert out and all(o.slip_class == -1 for o in out)
    duration_s = (d.imu_ns[-1] - d.imu_ns[0]) * 1e-9
    assert len(out) == pytest.approx(duration_s / p.wheel_timeout_s, rel=0.3)
    assert 'no wheel data' in est.health().message


def test_node_publishes_wheel_odometry_for_a_gravity_free_imu():
    """Through the node logic: an IMU with gravity removed gets an ERROR diagnostic naming it,
    and odometry (from the wheels) is still published, finite."""
    from helpers import synthetic_messages, synthetic_params

    from slip_estimator.ros.adapter import SlipEstimatorAdapter

    adapter = SlipEstimatorAdapter(synthetic_params())
    published = []
    for topic, msg, _ in synthetic_messages(stationary_s=3.0, drive_s=10.0):
        if topic == '/imu/data':
            msg.linear_acceleration.z -= 9.80665  # a driver that removes gravity
            published += adapter.on_imu(msg)
        else:
            published += adapter.on_joint_states(msg)
    odometry = [m for t, m in published if t.endswith('/odometry')]
    assert len(odometry) > 100
    end = odometry[-1].pose.pose.position
    assert math.hypot(end.x, end.y) > 1.0  # (heading north: along ENU y)
    diags = [m for t, m in published if t == '/diagnostics']
    assert any(s.level in (2, b'\x02') and 'gravity removed' in s.message
               for d in diags for s in d.status)


def test_turn_detector_tells_an_arc_from_a_scrubbing_turn():
    """0.4 rad/s at 0.9 m/s on a skid-steer robot with a 0.94 m effective track is an arc
    (the inner side still rolls at 0.71 m/s); at 0.2 m/s it scrubs; without wheel data the
    yaw rate alone decides, and below the threshold nothing is a turn."""
    from slip_estimator.core.detectors import TurnDetector

    turn = TurnDetector(0.25)
    w_b, C = np.array([0.0, 0.0, 0.4]), np.eye(3)
    assert not turn.is_turning(w_b, C, 0.9, 0.94)
    assert turn.is_turning(w_b, C, 0.2, 0.94)
    assert turn.is_turning(w_b, C, 0.0, 0.94)
    assert turn.is_turning(w_b, C)
    assert not turn.is_turning(np.array([0.0, 0.0, 0.2]), C, 0.0, 0.94)


def test_track_width_needs_a_differential_that_follows_the_yaw_rate():
    """A differential proportional to the yaw rate gives the ratio; one that does not follow
    it (correlation < 0.8) leaves the declared width."""
    from slip_estimator.core.track_width import TrackWidthEstimator

    rng = np.random.default_rng(0)
    w = rng.choice([-0.4, 0.4], 200) + rng.normal(0.0, 0.05, 200)
    good, bad = TrackWidthEstimator(0.5), TrackWidthEstimator(0.5)
    for wi in w:
        good.add(wi, 0.85 * wi + rng.normal(0.0, 0.02))
        bad.add(wi, rng.normal(0.0, 0.3))
    assert good.width_m == pytest.approx(0.85, rel=0.02) and good.correlation > 0.95
    assert bad.width_m == 0.5 and abs(bad.correlation) < 0.8


def test_tilt_from_an_imu_orientation_through_the_mounting():
    """The IMU's quaternion (imu_link in a z-up world) through a sideways mounting gives the
    body's roll and pitch (FRD in NED); a zero quaternion gives none."""
    from slip_estimator.core.alignment import tilt_from_orientation
    from slip_estimator.core.frames import C_ENU_NED, C_FLU_FRD, imu_to_body_dcm

    roll, pitch = math.radians(4.0), math.radians(-7.0)
    C_b_n = rpy_to_dcm(roll, pitch, 1.2)  # FRD body in NED
    C_base_enu = C_ENU_NED @ C_b_n @ C_FLU_FRD
    mount = [0.0, 0.0, math.pi / 2]
    C_imu_b = imu_to_body_dcm(mount)  # imu -> FRD
    C_imu_enu = C_base_enu @ C_FLU_FRD @ C_imu_b
    from slip_estimator.sim.kinematics import dcm_to_quat_wxyz

    q = tuple(dcm_to_quat_wxyz(C_imu_enu[None])[0])
    assert tilt_from_orientation(q, C_imu_b) == pytest.approx((roll, pitch), abs=1e-9)
    assert tilt_from_orientation((0.0, 0.0, 0.0, 0.0), C_imu_b) is None


def test_in_motion_start_takes_roll_and_pitch_from_the_imu_orientation():
    """Joined at 22 s: with the IMU's own orientation (here the truth) the filter starts from
    it; an orientation 20 deg off the wheel-corrected levelling (a driver's leftover identity
    quaternion on a tilted robot) is not used."""
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.core.frames import C_ENU_NED, C_FLU_FRD
    from slip_estimator.core.types import ImuSample, WheelSample

    r, p, d, t0 = _joined_in_motion(22.0)
    t_truth = r.stamps_ns(r.imu_t_s)

    def tilt_true(stamp):
        C = C_ENU_NED @ r.C_base_o[np.argmin(abs(t_truth - stamp))] @ C_FLU_FRD
        return math.atan2(C[2, 1], C[2, 2]), -math.asin(C[2, 0])

    for offset, expect_message in ((0.0, True), (math.radians(20.0), False)):
        est = SlipEstimator(p)
        j = 0
        for i, stamp in enumerate(d.imu_ns.tolist()):
            while j < len(d.wheel_ns) and d.wheel_ns[j] < stamp:
                x = d.rim_mps[j]
                est.add_wheel(WheelSample(int(d.wheel_ns[j]), float(x.mean())))
                j += 1
            roll, pitch = tilt_true(stamp)
            est.add_imu(ImuSample(stamp, d.f_ib_b[i], d.omega_ib_b[i], (roll + offset, pitch)))
            if est.aligned:
                break
        C = est.state.C_b_n
        got = math.atan2(C[2, 1], C[2, 2]), -math.asin(C[2, 0])
        if expect_message:
            assert got == pytest.approx(tilt_true(stamp), abs=1e-9)
        else:
            assert abs(got[0] - roll) < math.radians(1.0)


@pytest.mark.parametrize('configured', [False, True])
def test_noise_model_from_the_imu_messages_when_not_configured(configured):
    """IMU samples that declare their noise (message covariances) at 50 Hz: the stationarity
    limits never sit below it, and the filter's noise densities come from it unless the
    parameters configure them."""
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.core.params import Params
    from slip_estimator.core.types import ImuSample

    p = Params(gyro_noise_density_rps_rthz=1e-3) if configured else Params()
    est = SlipEstimator(p)
    for k in range(30):
        est.add_imu(ImuSample(1_000_000_000 + k * 20_000_000, np.array([0.0, 0.0, -9.8]),
                              np.zeros(3), noise_var=(0.0025, 4e-4)))
    assert est.stationary.thresholds() == pytest.approx((1.5 * 0.05, 1.5 * 0.02))
    if configured:
        assert est.params.gyro_noise_density_rps_rthz == 1e-3
        assert est.params.accel_noise_density_mps2_rthz == \
            Params().accel_noise_density_mps2_rthz
    else:
        assert est.params.gyro_noise_density_rps_rthz == pytest.approx(math.sqrt(4e-4 * 0.02))
        assert est.params.accel_noise_density_mps2_rthz == pytest.approx(
            math.sqrt(0.0025 * 0.02))


@pytest.mark.parametrize('grade', ['tactical', 'consumer'])
def test_noise_model_measured_at_rest_when_not_configured(grade):
    """No covariances in the messages and no noise densities in the parameters: the spread
    the IMU shows at rest (wheels stopped) becomes the filter's noise model where it is above
    the defaults (a consumer IMU's: about its true densities), never below them (a tactical
    IMU keeps the defaults)."""
    import dataclasses as dc

    from slip_estimator.core.params import Params
    from slip_estimator.sim import ImuErrorConfig

    imu = ImuErrorConfig.consumer_mems() if grade == 'consumer' else ImuErrorConfig.tactical()
    r = simulate(short_scenario(0).replace(imu=imu))
    defaults = Params()
    p = dc.replace(sim_params(r),
                   accel_noise_density_mps2_rthz=defaults.accel_noise_density_mps2_rthz,
                   gyro_noise_density_rps_rthz=defaults.gyro_noise_density_rps_rthz)
    est, _, _ = run_core(p, from_simulation(r, p))
    assert est.stationary.rest_std is not None
    if grade == 'tactical':
        assert est.params.accel_noise_density_mps2_rthz == \
            defaults.accel_noise_density_mps2_rthz
        assert est.params.gyro_noise_density_rps_rthz == defaults.gyro_noise_density_rps_rthz
    else:
        assert est.params.accel_noise_density_mps2_rthz == pytest.approx(
            imu.accel_noise_density_mps2_rthz, rel=0.3)
        assert est.params.gyro_noise_density_rps_rthz == pytest.approx(
            imu.gyro_noise_density_rps_rthz, rel=0.3)
