"""Wheel/IMU lag from the yaw rate and the wheel differential: closed-form signals."""
import numpy as np
import pytest

from slip_estimator.core.timing import WheelTimingMonitor, best_lag


def turning_signals(lag_s: float, seconds: float = 40.0, seed: int = 0):
    """Gyro yaw rate (250 Hz, FRD: left turn negative) and the wheel differential (10 Hz)
    of the same random turning, the wheel stamps ``lag_s`` late."""
    rng = np.random.default_rng(seed)
    t_imu = np.arange(0.0, seconds, 0.004)
    knots = np.arange(0.0, seconds + 2.0, 1.0)
    yaw_rate = np.interp(t_imu, knots, rng.normal(0.0, 0.3, len(knots)))  # rad/s, CCW
    t_wheel = np.arange(1.0, seconds - 1.0, 0.1)
    diff = 0.7 * np.interp(t_wheel - lag_s, t_imu, yaw_rate) + rng.normal(0.0, 0.01,
                                                                          len(t_wheel))
    return t_imu, -yaw_rate + rng.normal(0.0, 0.005, len(t_imu)), t_wheel, diff


@pytest.mark.parametrize('lag_s', [0.0, 0.085, 0.2, -0.1])
def test_best_lag_recovers_a_known_lag(lag_s):
    t_imu, w_z, t_wheel, diff = turning_signals(lag_s)
    lag, corr = best_lag(t_imu, -w_z, t_wheel, diff)
    assert lag == pytest.approx(lag_s, abs=0.01) and corr > 0.95


def test_monitor_estimates_online_and_ignores_straight_driving():
    t_imu, w_z, t_wheel, diff = turning_signals(0.15, seconds=60.0)
    m = WheelTimingMonitor()
    straight = WheelTimingMonitor()
    j = 0
    for t, w in zip(t_imu, w_z):
        while j < len(t_wheel) and t_wheel[j] <= t:
            m.add_wheel(int(t_wheel[j] * 1e9), diff[j])
            straight.add_wheel(int(t_wheel[j] * 1e9), 0.01 * np.sin(t_wheel[j]))
            j += 1
        m.add_imu(int(t * 1e9), w)
        straight.add_imu(int(t * 1e9), 0.001 * np.sin(t))
    assert m.lag_s == pytest.approx(0.15, abs=0.01) and m.correlation > 0.95
    assert np.isnan(straight.lag_s)
