"""The residual monitor names the effect its residual statistics point to."""
import numpy as np

from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.effects import Effects, run_core, with_effects
from slip_estimator.streams import from_simulation
from slip_estimator.sim import short_scenario, simulate
from slip_estimator.sim.bag import sim_params


def feed(monitor, channel, mean_sigma, n=100, seed=0):
    rng = np.random.default_rng(seed)
    for z in rng.normal(mean_sigma, 1.0, n):
        monitor.add(channel, np.array([z * 0.1]), np.array([[0.01]]))


def test_consistent_residuals_raise_no_suspect():
    m = ResidualMonitor()
    for c in ('zupt', 'zaru', 'nhc_lateral', 'nhc_vertical', 'wheel'):
        feed(m, c, 0.0)
    assert m.suspects() == []
    assert abs(m.mean_square['nhc_lateral'] - 1.0) < 0.5


def test_biased_lateral_residual_points_to_imu_yaw_mounting():
    m = ResidualMonitor()
    feed(m, 'nhc_lateral', 2.5)
    (text,) = m.suspects()
    assert 'yaw mounting' in text


def test_inflated_zero_rate_residuals_point_to_the_gyro_noise_model():
    m = ResidualMonitor()
    rng = np.random.default_rng(1)
    for z in rng.normal(0.0, 4.0, 100):
        m.add('zaru', np.array([z]), np.array([[1.0]]))
    assert any('zero-rate' in t for t in m.suspects())


def test_constant_held_slip_points_to_the_wheel_radius():
    m = ResidualMonitor()
    for _ in range(10):
        m.add_held_slip(0.04)
    assert m.suspects() == []  # loose soil slips a few per cent everywhere: not reported
    for _ in range(20):
        m.add_held_slip(0.15)
    m.add_held_slip(0.5)  # a real slip episode is not ordinary driving: ignored
    (text,) = m.suspects()
    assert 'wheel radius' in text and '+0.1' in text  # EMA of 0.04s then 0.15s


def test_undeclared_wheel_radius_error_is_reported_by_the_estimator():
    """The radius is declared 10 % too large, so the rim speeds read 10 % high: every ordinary
    segment then shows about 0.1 more slip and the health message names the radius."""
    r = simulate(short_scenario(0))
    p = sim_params(r)
    est, _, _ = run_core(p, with_effects(from_simulation(r, p), Effects(wheel_radius_error=0.1)))
    assert est.monitor.held_slip_count >= 2
    assert est.monitor.held_slip_mean > 0.1
    assert 'wheel radius' in est.health().message


def test_body_yawing_unlike_its_wheels_is_named_beyond_three_declared_sigma():
    """The wheel yaw-rate aid's running innovation mean beyond 3 sigma of the declared
    unexplained yaw rate names differential slip (and the sign: left positive)."""
    m = ResidualMonitor()
    m.add_yaw_disagreement(0.012, 0.005)
    assert m.suspects() == []
    m.add_yaw_disagreement(0.02, 0.005)
    (text,) = m.suspects()
    assert 'one side slipping more' in text and '+1.15 deg/s' in text
    assert m.values()['unexplained_yaw_rate_rps'] == 0.02
