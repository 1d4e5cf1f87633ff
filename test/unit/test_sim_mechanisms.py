"""Tests of the simulator's real-IMU error mechanisms (slip_estimator.sim.imu_grades /
sensors / truth): each is off by default, changes only its own term when switched on, and
has the size or frequency its closed form gives."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slip_estimator.core.alignment import level
from slip_estimator.core.frames import dcm_to_rpy
from slip_estimator.sim.drives import no_slip, patch_scenario, short_scenario, straight_scenario
from slip_estimator.sim.imu_grades import ImuErrorConfig, VibrationConfig
from slip_estimator.sim.robots import ROBOTS
from slip_estimator.sim.rover import simulate
from slip_estimator.sim.scenario import ScenarioConfig, Segment, TerrainConfig
from slip_estimator.sim.sensors import gauss_markov
from slip_estimator.validation.sim_vs_real import allan_deviation, peak_frequency_hz

FLAT = TerrainConfig(undulation_amplitude_m=0.0)


def _drive(imu: ImuErrorConfig, segments=None, rate_imu_hz: float = 250.0,
           terrain: TerrainConfig = FLAT, noise_seed: int = 5) -> ScenarioConfig:
    """A flat drive that starts moving (straight at 0.6 m/s unless ``segments``)."""
    segs = segments or (Segment(40.0, 0.6, label='cruise'),)
    return ScenarioConfig(tuple(segs), truth_seed=4, noise_seed=noise_seed,
                          rate_imu_hz=rate_imu_hz, rate_truth_hz=10.0, start_moving=True,
                          imu=imu, terrain=terrain)


def _ideal_with(**fields) -> ImuErrorConfig:
    return dataclasses.replace(ImuErrorConfig.ideal(), **fields)


def _vib_with(**fields) -> ImuErrorConfig:
    return _ideal_with(vibration=dataclasses.replace(VibrationConfig.off(), **fields))


# --- off by default -----------------------------------------------------------------------------

def test_every_new_mechanism_is_off_in_the_existing_grades() -> None:
    for imu in (ImuErrorConfig(), ImuErrorConfig.tactical(), ImuErrorConfig.industrial_mems(),
                ImuErrorConfig.consumer_mems(), ImuErrorConfig.ideal()):
        assert imu.accel_bias_instability_mps2 == imu.gyro_bias_instability_rps == 0.0
        assert imu.gyro_g_sensitivity_rps_per_mps2 == 0.0
        assert imu.vibration.resonance_hz == () and imu.vibration.gyro_rectified_rps_per_mps == 0
    assert TerrainConfig().rocking_harmonics == ()
    assert patch_scenario(0, 60.0, rough=True).imu.vibration.gyro_rectified_rps_per_mps == 0.0
    for name in ('skid_steer_30hz', 'fifty_hz', 'diff_drive_gravity_free'):
        cfg = ROBOTS[name](0).scenario
        assert cfg.imu.gyro_g_sensitivity_rps_per_mps2 == 0.0
        assert cfg.terrain.rocking_harmonics == ()


@pytest.mark.parametrize('imu', [
    _ideal_with(gyro_bias_instability_rps=1e-3, accel_bias_instability_mps2=1e-2),
    _ideal_with(gyro_g_sensitivity_rps_per_mps2=1e-4),
    _vib_with(gyro_rectified_rps_per_mps=1e-3),
    _vib_with(resonance_hz=(70.0,), accel_resonance_mps2_per_mps=(1.0,),
              gyro_resonance_rps_per_mps=(0.1,))])
def test_a_mechanism_switched_on_adds_only_its_own_term(imu: ImuErrorConfig) -> None:
    """On top of the tactical grade, the samples with the mechanism on differ from those with
    it off by exactly the mechanism's term: the other errors' draws are untouched."""
    base = ImuErrorConfig.tactical()
    extra = {f.name: getattr(imu, f.name) for f in dataclasses.fields(imu)
             if f.name not in ('vibration',) and getattr(imu, f.name) != getattr(
                 ImuErrorConfig.ideal(), f.name)}
    vib = dataclasses.replace(base.vibration, **{
        k: getattr(imu.vibration, k) for k in ('resonance_hz', 'accel_resonance_mps2_per_mps',
                                               'gyro_resonance_rps_per_mps',
                                               'gyro_rectified_rps_per_mps')})
    on = simulate(_drive(dataclasses.replace(base, vibration=vib, **extra)))
    off = simulate(_drive(base))
    alone = simulate(_drive(imu))  # the mechanism on an ideal IMU: its term alone
    np.testing.assert_allclose(on.f_ib_imu - off.f_ib_imu, alone.f_ib_imu - alone.f_ib_imu_true,
                               atol=1e-9)
    if imu.gyro_g_sensitivity_rps_per_mps2 == 0.0:  # g-sensitivity also sees the vibration
        np.testing.assert_allclose(on.omega_ib_imu - off.omega_ib_imu,
                                   alone.omega_ib_imu - alone.omega_ib_imu_true, atol=1e-12)
    assert np.max(np.abs(on.omega_ib_imu - off.omega_ib_imu)) > 1e-5


# --- scale factor and misalignment ----------------------------------------------------------------

def test_scale_factor_and_misalignment_are_one_linear_map_of_the_true_rate() -> None:
    """Measured = M true exactly (no other error): M fitted by least squares over a drive with
    turns reproduces every sample; its diagonal is 1 + k (k ~ the scale-factor sigma) and
    its off-diagonal entries the misalignment; with both sigmas zero M is the identity."""
    segs = (Segment(10.0, 0.5, 0.3), Segment(10.0, 0.5, -0.4), Segment(10.0, 0.0, 0.6))
    terrain = TerrainConfig(undulation_amplitude_m=0.2, undulation_wavelength_m=8.0)
    sigma = 0.01
    r = simulate(_drive(_ideal_with(gyro_scale_factor_sigma=sigma,
                                    gyro_misalignment_sigma_rad=sigma,
                                    accel_scale_factor_sigma=sigma), segs, terrain=terrain))
    for true, meas, mis in ((r.omega_ib_imu_true, r.omega_ib_imu, True),
                            (r.f_ib_imu_true, r.f_ib_imu, False)):
        M = np.linalg.lstsq(true, meas, rcond=None)[0].T
        np.testing.assert_allclose(true @ M.T, meas, atol=1e-10)
        k = np.diag(M) - 1.0
        assert np.all(np.abs(k) > 1e-4) and np.all(np.abs(k) < 5 * sigma)
        off = M[~np.eye(3, dtype=bool)]
        if mis:
            assert np.all(np.abs(off) < 5 * sigma) and np.std(off) > 0.2 * sigma
        else:
            assert np.max(np.abs(off)) < 1e-12
    # a steady in-place turn: the yaw gyro reads (1 + k_z) times the true rate, sample by sample
    turn = simulate(_drive(_ideal_with(gyro_scale_factor_sigma=sigma),
                           (Segment(20.0, 0.0, 0.5),)))
    steady = turn.imu_t_s > 3.0
    ratio = turn.omega_ib_imu[steady, 2] / turn.omega_ib_imu_true[steady, 2]
    assert np.ptp(ratio) < 1e-12 and 1e-4 < abs(ratio[0] - 1.0) < 5 * sigma
    ideal = simulate(_drive(ImuErrorConfig.ideal(), segs, terrain=terrain))
    np.testing.assert_array_equal(ideal.omega_ib_imu, ideal.omega_ib_imu_true)


# --- bias instability (Gauss-Markov) -----------------------------------------------------------

def _gm_allan_closed_form(sigma: float, T: float, tau: float) -> float:
    """Allan deviation of a first-order Gauss-Markov process (IEEE Std 952, q_c = 2 sigma^2/T)."""
    q = 2.0 * sigma * sigma / T
    return math.sqrt(q * T * T / tau * (1.0 - T / (2.0 * tau) * (
        3.0 - 4.0 * math.exp(-tau / T) + math.exp(-2.0 * tau / T))))


def test_gauss_markov_has_its_variance_allan_deviation_and_integral() -> None:
    sigma, T, dt = 0.3, 10.0, 0.1
    x = gauss_markov(np.random.default_rng(0), 200_000, dt, T, sigma, axes=2)
    assert np.std(x) == pytest.approx(sigma, rel=0.1)
    for tau in (3.0, 10.0, 30.0):
        adev = np.mean([allan_deviation(x[:, j], dt, tau) for j in range(2)])
        assert adev == pytest.approx(_gm_allan_closed_form(sigma, T, tau), rel=0.08)
    # the integral over L: variance 2 sigma^2 T (L - T (1 - exp(-L/T))) (the tilt it makes)
    L = 50.0
    y = gauss_markov(np.random.default_rng(1), int(L / dt), dt, T, sigma, axes=600)
    var = np.var(y.sum(axis=0) * dt)
    assert var == pytest.approx(2 * sigma**2 * T * (L - T * (1 - math.exp(-L / T))), rel=0.2)


def test_bias_instability_flattens_the_allan_deviation_at_rest() -> None:
    """At rest, white noise alone falls as tau^-1/2; a Gauss-Markov bias of sigma_b, T keeps
    the Allan deviation near its closed form at tau ~ T."""
    white = 1e-3  # rad/s/sqrt(Hz)
    sigma_b, T = 2e-3, 5.0
    segs = (Segment(300.0, label='stationary'),)
    plain = _ideal_with(gyro_noise_density_rps_rthz=white)
    rests = [simulate(_drive(imu, segs, rate_imu_hz=50.0)) for imu in (
        plain, dataclasses.replace(plain, gyro_bias_instability_rps=sigma_b,
                                   bias_correlation_time_s=T))]
    adev = [np.mean([allan_deviation(r.omega_ib_imu[:, j], 0.02, T) for j in range(3)])
            for r in rests]
    assert adev[0] == pytest.approx(white / math.sqrt(T), rel=0.15)
    expected = math.hypot(white / math.sqrt(T), _gm_allan_closed_form(sigma_b, T, T))
    assert adev[1] == pytest.approx(expected, rel=0.2) and adev[1] > 2 * adev[0]
    # the true bias carries it
    assert np.std(rests[1].gyro_bias_imu) == pytest.approx(sigma_b, rel=0.35)


# --- g-sensitivity ------------------------------------------------------------------------------

def test_g_sensitivity_is_a_linear_map_of_the_sensed_acceleration() -> None:
    """gyro error = G (f_true + f_vibration): exact over a drive with vibration; the rest error
    is G times gravity, of the size sigma g."""
    sens = 1e-3
    vib = dataclasses.replace(VibrationConfig(), gyro_harmonic_rps_per_mps=(0.0, 0.0, 0.0),
                              gyro_broadband_rps_per_mps=0.0)  # accelerometer vibration only
    imu = dataclasses.replace(_ideal_with(gyro_g_sensitivity_rps_per_mps2=sens), vibration=vib)
    segs = (Segment(20.0, 0.6, 0.2), Segment(20.0, 0.3, -0.3))
    r = simulate(_drive(imu, segs))
    f_sensed = r.f_ib_imu  # ideal accelerometer: true + vibration
    err = r.omega_ib_imu - r.omega_ib_imu_true
    G = np.linalg.lstsq(f_sensed, err, rcond=None)[0].T
    np.testing.assert_allclose(f_sensed @ G.T, err, atol=1e-12)
    assert 0.2 * sens < np.std(G) < 3 * sens
    assert np.linalg.norm(err[0]) > 0.2 * sens * 9.8


# --- aliasing -----------------------------------------------------------------------------------

@pytest.mark.parametrize('rate_hz, folded_hz', [(30.0, 10.0), (50.0, 20.0), (250.0, 70.0)])
def test_a_resonance_folds_to_its_alias_frequency(rate_hz: float, folded_hz: float) -> None:
    """A 70-Hz resonance sampled at the IMU instants without an anti-alias filter appears at
    |70 - k rate|: 10 Hz at 30 Hz, 20 Hz at 50 Hz, 70 Hz (unfolded) at 250 Hz."""
    imu = _vib_with(resonance_hz=(70.0,), accel_resonance_mps2_per_mps=(1.0,),
                    gyro_resonance_rps_per_mps=(0.05,))
    r = simulate(_drive(imu, rate_imu_hz=rate_hz))
    steady = r.imu_t_s > 1.0
    for err in (r.omega_ib_imu - r.omega_ib_imu_true, r.f_ib_imu - r.f_ib_imu_true):
        peak = peak_frequency_hz(err[steady], 1.0 / rate_hz)
        assert peak == pytest.approx(folded_hz, abs=0.1)
    # amplitude: a sinusoid of amplitude a v along a unit direction, total RMS a v / sqrt(2)
    rms = np.sqrt(np.mean(np.sum((r.f_ib_imu - r.f_ib_imu_true)[steady] ** 2, axis=1)))
    assert rms == pytest.approx(1.0 * 0.6 / math.sqrt(2.0), rel=0.02)


# --- rectified gyro error (tilt wander) -----------------------------------------------------------

def test_the_rectified_gyro_error_scales_with_speed_and_is_zero_at_rest() -> None:
    sigma = 2e-3
    segs = (Segment(12.0, label='stationary'), Segment(200.0, 0.6, label='cruise'))
    cfg = _drive(_vib_with(gyro_rectified_rps_per_mps=sigma, rectified_correlation_time_s=5.0),
                 segs).replace(start_moving=False)
    r = simulate(cfg)
    err = r.omega_ib_imu - r.omega_ib_imu_true
    assert np.all(err[r.imu_t_s < 10.0] == 0.0)
    cruise = r.imu_t_s > 20.0
    assert np.std(err[cruise]) == pytest.approx(sigma * 0.6, rel=0.25)
    # correlated over seconds: one-second means keep most of the scatter (white would not)
    n = 250
    means = err[cruise][: (cruise.sum() // n) * n].reshape(-1, n, 3).mean(axis=1)
    assert np.std(means) > 0.8 * np.std(err[cruise])


def test_the_rectified_gyro_error_makes_the_tilt_wander_across_a_drive() -> None:
    """The tilt closure of a test17run-shaped drive (ideal IMU otherwise): ~0 without the
    mechanism, and of the closed-form size sqrt(2 sigma^2 T L) with it."""
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.streams import from_simulation
    from slip_estimator.validation.imu_floor import tilt_closure_between
    from slip_estimator.validation.sim_vs_real import motion_interval

    sigma, T, v = 2e-3, 5.0, 0.73
    wander = []
    for imu in (ImuErrorConfig.ideal(),
                _vib_with(gyro_rectified_rps_per_mps=sigma, rectified_correlation_time_s=T)):
        diffs = []
        for seed in range(3):
            r = simulate(straight_scenario(seed).replace(imu=imu, terrain=FLAT))
            data = from_simulation(r, sim_params(r))
            c = tilt_closure_between(data, *motion_interval(data))
            diffs += [c['pitch_diff_deg'], c['roll_diff_deg']]
        wander.append(float(np.sqrt(np.mean(np.square(diffs)))))
    expected = math.degrees(math.sqrt(2.0 * (sigma * v) ** 2 * T * 52.0))
    assert wander[0] < 0.01
    assert 0.4 * expected < wander[1] < 2.0 * expected


# --- rocking: real attitude motion ----------------------------------------------------------------

def test_rocking_is_real_attitude_motion_the_accelerometer_sees() -> None:
    """One rocking harmonic of amplitude a per m/s at speed v on flat ground: the tilt about the
    path has RMS a v / sqrt(2), at m times the wheel rotation rate, and a perfect
    accelerometer levels to the same roll and pitch (gravity turns with the body)."""
    a, m = 0.02, 2.0
    terrain = dataclasses.replace(FLAT, rocking_harmonics=(m,), rocking_rad_per_mps=(a,))
    r = simulate(_drive(ImuErrorConfig.ideal(), terrain=terrain))
    steady = r.imu_t_s > 2.0
    v = float(np.mean(r.speed_mps[steady]))  # the body speed: the rim's less the low slip
    assert np.ptp(r.speed_mps[steady]) < 1e-9
    rpy = np.array([dcm_to_rpy(C) for C in r.C_base_o[steady]])
    tilt = np.hypot(rpy[:, 0], rpy[:, 1])
    assert np.sqrt(np.mean(tilt**2)) == pytest.approx(a * v / math.sqrt(2.0), rel=0.02)
    wheel_hz = v / (2.0 * math.pi * r.config.rover.wheel_radius_m)
    assert peak_frequency_hz(rpy[:, :2], 0.004) == pytest.approx(m * wheel_hz, abs=0.05)
    # f in imu_link (x fwd, y right, z down) = FRD: level gives FRD roll/pitch in NED, which
    # for base_link FLU in ENU is (roll, -pitch)
    lv = np.array([level(f) for f in r.f_ib_imu[steady][::25]])
    np.testing.assert_allclose(lv[:, 0], rpy[::25, 0], atol=2e-3)
    np.testing.assert_allclose(lv[:, 1], -rpy[::25, 1], atol=2e-3)
    flat = simulate(_drive(ImuErrorConfig.ideal()))
    assert np.max(np.abs([dcm_to_rpy(C)[:2] for C in flat.C_base_o])) < 1e-9



def test_surge_is_fore_aft_motion_the_imu_sees_and_the_rims_do_not() -> None:
    """One surge harmonic of amplitude b per m/s at speed v on flat ground: base_link's
    displacement along the path from the same drive without it has zero mean and RMS
    b v / sqrt(2), the accelerometer senses its acceleration (forward, RMS b v (m w)^2 /
    sqrt(2), w the wheel rotation rate), the truth velocity is still the derivative of the
    truth position, and the rims, the body speed and the slip truth are the unsurged ones."""
    b, m = 0.003, 2.0
    plain = simulate(_drive(ImuErrorConfig.ideal()))
    surged = simulate(_drive(ImuErrorConfig.ideal(), terrain=dataclasses.replace(
        FLAT, surge_harmonics=(m,), surge_m_per_mps=(b,))))
    steady = surged.imu_t_s > 2.0
    v = float(np.mean(surged.speed_mps[steady]))
    dx = np.einsum('ni,ni->n', surged.p_ob_o - plain.p_ob_o, plain.C_base_o[:, :, 0])[steady]
    assert abs(float(np.mean(dx))) < 0.02 * b * v
    assert np.sqrt(np.mean(dx**2)) == pytest.approx(b * v / math.sqrt(2.0), rel=0.02)
    w = m * v / surged.config.rover.wheel_radius_m
    df = (surged.f_ib_imu - plain.f_ib_imu)[steady]
    assert np.sqrt(np.mean(df[:, 0]**2)) == pytest.approx(b * v * w * w / math.sqrt(2.0),
                                                          rel=0.02)
    assert np.max(np.abs(df[:, 1:])) < 1e-5  # the planet rate's Coriolis on the surge only
    dt = 1.0 / surged.config.rate_imu_hz
    v_fd = (surged.p_ob_o[2:] - surged.p_ob_o[:-2]) / (2 * dt)
    np.testing.assert_allclose(v_fd, surged.v_ob_o[1:-1], atol=2e-3)
    np.testing.assert_array_equal(surged.rim_speed_true_mps, plain.rim_speed_true_mps)
    np.testing.assert_array_equal(surged.speed_mps, plain.speed_mps)
    np.testing.assert_array_equal(surged.slip_true, plain.slip_true)

# --- ground without slip -------------------------------------------------------------------------

@pytest.mark.parametrize('cfg', [short_scenario(2), patch_scenario(1, 120.0, rough=True),
                                 ROBOTS['skid_steer_30hz_no_slip'](0).scenario])
def test_no_slip_ground_shows_no_slip_while_moving(cfg: ScenarioConfig) -> None:
    r = simulate(no_slip(cfg))
    moving = r.slip_class > 0
    assert moving.mean() > 0.4
    np.testing.assert_allclose(r.slip_true[moving], 0.0, atol=1e-9)
    assert np.all(r.slip_class[moving] == 1)
    assert np.ptp(r.yaw_rate_true_rps) > 0.2  # the turns are kept


def test_the_measured_grades_switch_the_mechanisms_on() -> None:
    p = ImuErrorConfig.pathfinder_measured()
    c = ImuErrorConfig.consumer_mems_vibrating()
    for imu in (p, c):
        assert imu.gyro_misalignment_sigma_rad > 0 and imu.gyro_g_sensitivity_rps_per_mps2 > 0
        assert imu.gyro_bias_instability_rps > 0 and imu.accel_bias_instability_mps2 > 0
    assert c.vibration.resonance_hz == (70.0,) and c.vibration.gyro_rectified_rps_per_mps > 0
    robot = ROBOTS['skid_steer_30hz_vibrating'](0).scenario
    assert robot.rate_imu_hz == 30.0 and robot.terrain.rocking_harmonics


def test_the_simulate_command_offers_the_no_slip_and_measured_drives() -> None:
    from slip_estimator.sim.bag import SCENARIOS

    for name in ('no_slip', 'rough_no_slip', 'measured_no_slip'):
        r = simulate(SCENARIOS[name](0).replace(duration_s=120.0))
        moving = r.slip_class > 0
        assert moving.mean() > 0.4
        np.testing.assert_allclose(r.slip_true[moving], 0.0, atol=1e-9)
    measured = SCENARIOS['measured'](0)
    assert measured.imu == ImuErrorConfig.pathfinder_measured()
    assert measured.terrain.rocking_harmonics == TerrainConfig.pathfinder_measured(
    ).rocking_harmonics
    assert measured.terrain.hills == patch_scenario(0).terrain.hills
    assert np.ptp(simulate(measured.replace(duration_s=120.0)).slip_true) > 0.3


def test_rocking_about_a_pivot_swings_the_imu_with_its_closed_form_acceleration() -> None:
    """Rocking of one harmonic about an axis ``d`` below base_link: the accelerometer senses
    the swing, RMS d a v (m w_wheel)^2 / sqrt(2) more than rocking about base_link, and the
    truth velocity is still the derivative of the truth position."""
    a, m, d = 0.02, 2.0, 0.3
    rock = dataclasses.replace(FLAT, rocking_harmonics=(m,), rocking_rad_per_mps=(a,))
    about_base = simulate(_drive(ImuErrorConfig.ideal(), terrain=rock))
    about_pivot = simulate(_drive(ImuErrorConfig.ideal(), terrain=dataclasses.replace(
        rock, rocking_pivot_depth_m=d)))
    steady = about_pivot.imu_t_s > 2.0
    v = float(np.mean(about_pivot.speed_mps[steady]))
    w = m * v / about_pivot.config.rover.wheel_radius_m
    df = (about_pivot.f_ib_imu - about_base.f_ib_imu)[steady]
    assert np.sqrt(np.mean(np.sum(df**2, axis=1))) == pytest.approx(
        d * a * v * w * w / math.sqrt(2.0), rel=0.05)
    dt = 1.0 / about_pivot.config.rate_imu_hz
    v_fd = (about_pivot.p_ob_o[2:] - about_pivot.p_ob_o[:-2]) / (2 * dt)
    np.testing.assert_allclose(v_fd, about_pivot.v_ob_o[1:-1], atol=2e-3)
    assert np.max(np.abs(about_pivot.p_ob_o - about_base.p_ob_o)) > 0.5 * d * a * v
