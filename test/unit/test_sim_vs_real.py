"""Tests of slip_estimator.validation.sim_vs_real (the same IMU statistics on real logs and
simulated drives) and its page: closed-form statistics, each mechanism moving its statistic
the expected way, the real log read through the same function as imu_floor's tilt closure."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers import mat_or_skip

from slip_estimator.sim.drives import straight_scenario
from slip_estimator.sim.imu_grades import ImuErrorConfig
from slip_estimator.sim.scenario import TerrainConfig
from slip_estimator.validation import sim_vs_real as svr
from slip_estimator.validation.sim_vs_real_page import COMMAND, ROWS, main, render


def test_allan_deviation_of_white_noise_falls_as_one_over_root_m() -> None:
    x = np.random.default_rng(0).normal(0.0, 2.0, 400_000)
    for m in (1, 10, 100):
        assert svr.allan_deviation(x, 0.01, m * 0.01) == pytest.approx(2.0 / math.sqrt(m),
                                                                       rel=0.05)
    assert math.isnan(svr.allan_deviation(x[:20], 0.01, 0.1))


def test_peak_frequency_and_band_std_of_known_sinusoids() -> None:
    dt = 0.004
    t = np.arange(0.0, 40.0, dt)
    x = np.column_stack([3.0 * np.sin(2 * np.pi * 2.0 * t), 0.5 * np.sin(2 * np.pi * 20.0 * t)])
    assert svr.peak_frequency_hz(x, dt) == pytest.approx(2.0, abs=0.03)
    np.testing.assert_allclose(svr.band_std(x, dt, 8.0), [0.0, 0.5 / math.sqrt(2)], atol=1e-3)
    np.testing.assert_allclose(svr.band_std(x, dt, 0.0, 8.0), [3.0 / math.sqrt(2), 0.0],
                               atol=1e-3)



def test_forward_residual_of_a_surge_is_its_acceleration_in_band() -> None:
    """A perfect IMU on flat ground: the IMU's forward speed departs from the rims' only by the
    chassis surge, one harmonic at m w (w = v / r), acceleration amplitude a = b v (m w)^2. Its
    one-sided PSD averaged over the 1-4 Hz band is (a H)^2 / 2 / 3 Hz, H the gain of the 0.1-s
    means and the central difference at that frequency; below 1 Hz there is nothing."""
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.streams import from_simulation

    b, m = 0.0027, 3.0
    terrain = TerrainConfig(undulation_amplitude_m=0.0, surge_harmonics=(m,),
                            surge_m_per_mps=(b,))
    r = simulate(straight_scenario(0).replace(imu=ImuErrorConfig.ideal(), terrain=terrain,
                                              rate_truth_hz=10.0))
    low, band = svr.forward_residual_asd(from_simulation(r, sim_params(r)))
    v = float(np.median(r.speed_mps[r.speed_mps > 0.5]))
    w = m * v / r.config.rover.wheel_radius_m
    x = w / 2 * 0.02  # half the phase step of the 0.02-s grid
    gain = math.sin(5 * x) / (5 * math.sin(x)) * math.sin(2 * x) / (2 * x)
    assert band == pytest.approx(b * v * w * w * gain / math.sqrt(2 * 3.0), rel=0.03)
    assert low < 0.01 * band

@pytest.fixture(scope='module')
def grades() -> dict[str, dict[str, float]]:
    """Summaries over two seeds of the test17run-shaped drive for the grades compared."""
    base = ImuErrorConfig.tactical()
    rect = dataclasses.replace(base, vibration=dataclasses.replace(
        base.vibration, gyro_rectified_rps_per_mps=3e-3))
    cases = {'default': (base, None), 'measured': (ImuErrorConfig.pathfinder_measured(),
                                                   TerrainConfig.pathfinder_measured()),
             'rectified': (rect, None),
             'rough': (base, TerrainConfig(undulation_amplitude_m=0.2,
                                           undulation_wavelength_m=10.0))}
    out = {}
    for name, (imu, terrain) in cases.items():
        def make(seed: int, imu=imu, terrain=terrain):
            cfg = straight_scenario(seed).replace(imu=imu, rate_truth_hz=10.0)
            return cfg if terrain is None else cfg.replace(terrain=terrain)
        out[name] = svr.sim_stats(name, make, (0, 1)).summary
    return out


def test_each_mechanism_moves_its_statistic(grades) -> None:
    d, m = grades['default'], grades['measured']
    # the measured vibration: an order of magnitude more scatter while driving, none at rest
    assert m['gyro_drive_std_rps'] > 8 * d['gyro_drive_std_rps']
    assert m['accel_drive_std_mps2'] > 5 * d['accel_drive_std_mps2']
    assert m['accel_rest_std_mps2'] == pytest.approx(d['accel_rest_std_mps2'], rel=0.2)
    # the rocking at 1-2x the wheel rate (0.97 Hz at 0.73 m/s) is where the gyro peaks; the
    # default's peak is its 12th harmonic
    wheel_hz = 0.73 / (2 * math.pi * 0.12)
    assert 0.8 * wheel_hz < m['gyro_drive_peak_hz'] < 2.2 * wheel_hz
    assert d['gyro_drive_peak_hz'] == pytest.approx(12 * wheel_hz * 0.95, rel=0.1)
    # the measured grade's gyro is quieter at rest (its measured white noise) ...
    assert m['gyro_rest_std_rps'] < d['gyro_rest_std_rps']
    # ... yet its tilt wanders more: the broadband's angle random walk
    for key in ('pitch_wander_deg', 'roll_wander_deg'):
        assert abs(m[key]) > 1.5 * abs(d[key])
        assert abs(grades['rectified'][key]) > 2 * abs(d[key])
    assert m['arw_tilt_deg'] > 2 * d['arw_tilt_deg']
    # and the free INS reads a speed change several times worse (the real log's 0.09 m/s)
    assert m['reading_error_mps'] > 3 * d['reading_error_mps']
    # rough ground is real attitude motion: the levelled tilt spreads
    assert grades['rough']['roll_spread_deg'] > 3 * d['roll_spread_deg']
    assert grades['rough']['pitch_spread_deg'] > 3 * d['pitch_spread_deg']


def test_the_real_log_goes_through_the_same_statistics_as_imu_floor() -> None:
    from slip_estimator.pathfinder import motion_interval, pathfinder_params, read_pathfinder_mat
    from slip_estimator.streams import from_pathfinder
    from slip_estimator.validation.imu_floor import tilt_closure

    log = read_pathfinder_mat(mat_or_skip('test17run'))
    params = pathfinder_params(log)
    data = from_pathfinder(log, params)
    assert svr.motion_interval(data) == pytest.approx(motion_interval(log), abs=1e-6)
    real = svr.real_stats(mat_or_skip('test17run')).summary
    closure = tilt_closure(log, params)
    assert real['pitch_wander_deg'] == closure['pitch_diff_deg']
    assert real['roll_wander_deg'] == closure['roll_diff_deg']
    assert real['rate_hz'] == pytest.approx(250.0, rel=0.01)
    assert real['gyro_drive_std_rps'] > 10 * real['gyro_rest_std_rps']


def test_the_page_names_every_source_and_statistic_and_its_command() -> None:
    stats = svr.SourceStats('real test17run', True, ({k: 1.0 for k, *_ in ROWS},))
    sims = svr.SourceStats('sim pathfinder_measured, rocking', False,
                           tuple({k: v for k, *_ in ROWS} for v in (1.0, 3.0)))
    page = render(svr.SimVsReal((stats, sims), (0, 1), ('x.mat',)))
    assert COMMAND in page.splitlines()[2]
    table = [line for line in page.splitlines() if line.startswith('| ')]
    assert len(table) == 1 + len(ROWS)
    assert 'real test17run' in table[0] and 'sim pathfinder_measured, rocking' in table[0]
    wander = next(line for line in table if line.startswith('| tilt wander: gyro pitch'))
    assert f'{math.sqrt(5.0):.2f} rms' in wander  # RMS over runs of 1 and 3
    accel = next(line for line in table if line.startswith('| accel scatter driving'))
    assert accel.endswith('| 1.000 | 2.000 | 2.00 |')  # mean of 1 and 3; ratio to the real
    assert '| nan' not in page


def test_the_page_command_says_what_is_missing(tmp_path, capsys) -> None:
    assert main(['--data-dir', str(tmp_path), '--out', str(tmp_path / 'p.md')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('error: log not found') and err.count('\n') == 1
