"""The simulator's motion-bound IMU errors (issue 27 deliverable 4): the differenced broadband
and the accelerometer's low-frequency Gauss-Markov error, against their closed forms."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slip_estimator.sim.imu_grades import ImuErrorConfig, VibrationConfig
from slip_estimator.sim.rover import simulate
from slip_estimator.sim.scenario import ScenarioConfig, Segment, TerrainConfig
from slip_estimator.sim.sensors import differenced_white

FLAT = TerrainConfig(undulation_amplitude_m=0.0)
SPEED_MPS = 0.6


def _vib_drive(cruise_s: float = 200.0, **fields) -> ScenarioConfig:
    """An ideal IMU with only the named vibration fields, 12 s at rest then a flat cruise."""
    imu = dataclasses.replace(ImuErrorConfig.ideal(),
                              vibration=dataclasses.replace(VibrationConfig.off(), **fields))
    segs = (Segment(12.0, label='stationary'), Segment(cruise_s, SPEED_MPS, label='cruise'))
    return ScenarioConfig(segs, truth_seed=4, noise_seed=5, rate_imu_hz=250.0,
                          rate_truth_hz=10.0, imu=imu, terrain=FLAT)


def test_differenced_white_has_its_variance_correlation_and_a_bounded_sum() -> None:
    sigma, n = 0.7, 400_000
    x = differenced_white(np.random.default_rng(0), n, sigma, axes=2)
    assert np.var(x) == pytest.approx(sigma**2, rel=0.02)
    lag1 = np.mean(x[1:] * x[:-1]) / np.var(x)
    lag2 = np.mean(x[2:] * x[:-2]) / np.var(x)
    assert lag1 == pytest.approx(-0.5, abs=0.01)
    assert abs(lag2) < 0.01
    # the running sum is sigma (w_k - w_-1) / sqrt(2): variance sigma^2 at any length
    y = differenced_white(np.random.default_rng(1), 1000, sigma, axes=2000)
    assert np.var(y.sum(axis=0)) == pytest.approx(sigma**2, rel=0.1)


def test_the_differenced_broadband_shakes_the_samples_but_is_no_velocity_random_walk() -> None:
    sigma = 1.2
    r = simulate(_vib_drive(accel_broadband_differenced_mps2_per_mps=sigma))
    err = r.f_ib_imu - r.f_ib_imu_true
    assert np.all(err[r.imu_t_s < 10.0] == 0.0)
    cruise = r.imu_t_s > 20.0
    assert np.std(err[cruise]) == pytest.approx(sigma * SPEED_MPS, rel=0.05)
    # its velocity error over the whole cruise is a few samples' noise times dt; the white
    # broadband of the same scatter would be sqrt(n) times that
    dt = 1.0 / 250.0
    dv = np.abs(err[cruise].sum(axis=0) * dt)
    white_dv = sigma * SPEED_MPS * dt * math.sqrt(cruise.sum())
    assert np.all(dv < 5.0 * sigma * SPEED_MPS * dt)
    assert np.all(dv < 0.05 * white_dv)
    assert np.all(r.omega_ib_imu == r.omega_ib_imu_true)


def test_the_lowband_accel_error_is_a_speed_scaled_gauss_markov_process() -> None:
    sigma, T, L = 0.05, 1.0, 1.5
    r = simulate(_vib_drive(accel_lowband_mps2_per_mps=sigma, accel_lowband_correlation_s=T))
    err = r.f_ib_imu - r.f_ib_imu_true
    assert np.all(err[r.imu_t_s < 10.0] == 0.0)
    cruise = err[r.imu_t_s > 20.0]
    s = sigma * SPEED_MPS
    assert np.std(cruise) == pytest.approx(s, rel=0.15)
    # correlation exp(-lag / T) at 0.5 s
    k = 125
    rho = np.mean(cruise[k:] * cruise[:-k]) / np.mean(cruise * cruise)
    assert rho == pytest.approx(math.exp(-0.5 / T), abs=0.1)
    # the speed change it integrates over L: 2 s^2 T^2 (L / T - 1 + exp(-L / T))
    n = int(L * 250)
    m = len(cruise) // n
    dv = cruise[:m * n].reshape(m, n, 3).sum(axis=1) / 250.0
    expected = 2 * s * s * T * T * (L / T - 1.0 + math.exp(-L / T))
    assert np.mean(dv * dv) == pytest.approx(expected, rel=0.25)


def test_a_motion_bound_term_switched_on_leaves_the_other_draws_alone() -> None:
    base = ImuErrorConfig.tactical()
    fields = {'accel_broadband_differenced_mps2_per_mps': 0.5,
              'gyro_broadband_differenced_rps_per_mps': 0.01, 'accel_lowband_mps2_per_mps': 0.05}
    on_imu = dataclasses.replace(base, vibration=dataclasses.replace(base.vibration, **fields))
    on = simulate(_vib_drive(60.0).replace(imu=on_imu))
    off = simulate(_vib_drive(60.0).replace(imu=base))
    alone = simulate(_vib_drive(60.0, **fields))
    np.testing.assert_allclose(on.f_ib_imu - off.f_ib_imu,
                               alone.f_ib_imu - alone.f_ib_imu_true, atol=1e-9)
    np.testing.assert_allclose(on.omega_ib_imu - off.omega_ib_imu,
                               alone.omega_ib_imu - alone.omega_ib_imu_true, atol=1e-12)


def test_the_motion_bound_grade_keeps_the_scatter_without_white_broadband() -> None:
    white = VibrationConfig.pathfinder_measured()
    bound = VibrationConfig.pathfinder_measured(motion_bound=True)
    assert white.accel_broadband_differenced_mps2_per_mps == 0.0  # the default is unchanged
    assert white.accel_lowband_mps2_per_mps == 0.0
    assert bound.accel_broadband_mps2_per_mps == bound.gyro_broadband_rps_per_mps == 0.0
    assert bound.accel_broadband_differenced_mps2_per_mps == white.accel_broadband_mps2_per_mps
    assert bound.gyro_broadband_differenced_rps_per_mps == white.gyro_broadband_rps_per_mps
    assert ImuErrorConfig.pathfinder_measured(True).vibration == bound
    assert bound.scaled(2.0).accel_lowband_mps2_per_mps == 2.0 * bound.accel_lowband_mps2_per_mps
    with pytest.raises(ValueError):
        VibrationConfig(accel_lowband_correlation_s=0.0)


def test_the_accuracy_command_offers_every_simulate_scenario(capsys) -> None:
    from slip_estimator.accuracy import accuracy_main
    from slip_estimator.sim.bag import SCENARIOS

    assert SCENARIOS['measured_motion_bound'](0).imu == ImuErrorConfig.pathfinder_measured(True)
    assert SCENARIOS['measured'](0).imu == ImuErrorConfig.pathfinder_measured()
    assert accuracy_main(['--families', 'measured,no_such_family', '--seeds', '0']) == 2
    err = capsys.readouterr().err
    assert "'no_such_family'" in err and 'measured_motion_bound_no_slip' in err
