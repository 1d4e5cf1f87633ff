"""The one sensor-stream path (slip_estimator.streams): records in arrival order, wheel sides
from joint names, one feeding loop."""
from __future__ import annotations

import numpy as np
import pytest

from slip_estimator.core.types import ImuSample, WheelSample
from slip_estimator.streams import (
    SensorData,
    concatenate,
    feed,
    from_simulation,
    records,
    wheel_side,
)


def _data(imu_ns, wheel_ns, rim, sides=('left', 'right', 'left', 'right')) -> SensorData:
    n = len(imu_ns)
    return SensorData(np.asarray(imu_ns, dtype=np.int64), np.zeros((n, 3)), np.zeros((n, 3)),
                      np.asarray(wheel_ns, dtype=np.int64), np.asarray(rim, dtype=float),
                      sides)


def test_wheel_side_from_joint_names():
    assert wheel_side('front_LEFT_wheel_joint') == 'left'
    assert wheel_side('RightRear') == 'right'
    assert wheel_side('wheel') is None and wheel_side('left_right') is None


def test_records_arrive_in_stamp_order_imu_first_at_equal_stamps():
    """A wheel sample goes before the first IMU sample stamped after it; at equal stamps the IMU
    goes first; wheel samples after the last IMU sample are not fed."""
    data = _data([10, 20, 30], [5, 20, 25, 30, 40], np.ones((5, 4)))
    order = [(type(r).__name__, r.stamp_ns) for r in records(data)]
    assert order == [('WheelSample', 5), ('ImuSample', 10), ('ImuSample', 20),
                     ('WheelSample', 20), ('WheelSample', 25), ('ImuSample', 30)]


def test_wheel_sides_reduce_by_joint_name_not_by_column():
    """The side means follow the declared sides, whatever the column order."""
    rim = np.array([[1.0, 2.0, 3.0, 4.0]])
    data = _data([10], [5], rim, sides=('right', 'left', 'right', 'left'))
    (w,) = data.wheel_samples()
    assert (w.rim_speed_mps, w.rim_speed_left_mps, w.rim_speed_right_mps) == (2.5, 3.0, 2.0)
    (w,) = _data([10], [5], rim, sides=(None,) * 4).wheel_samples()
    assert w.rim_speed_mps == 2.5 and w.rim_speed_left_mps is None \
        and w.rim_speed_right_mps is None


def test_feed_calls_back_after_every_imu_sample_and_returns_the_estimates():
    class Echo:
        def add_imu(self, s: ImuSample) -> list:
            return [('imu', s.stamp_ns)]

        def add_wheel(self, s: WheelSample) -> list:
            return [('wheel', s.stamp_ns)]

    data = _data([10, 20], [15], np.ones((1, 4)))
    seen: list[int] = []
    out = feed(Echo(), records(data), lambda s: seen.append(s.stamp_ns))
    assert out == [('imu', 10), ('wheel', 15), ('imu', 20)] and seen == [10, 20]
    assert feed(Echo(), records(data), keep_estimates=False) == []


def test_simulated_drive_as_the_node_sees_it():
    """A simulated drive: body-frame IMU, rim speed = radius x wheel rate, sides from the
    simulator's joint names; chained drives keep their stamps."""
    from slip_estimator.sim import short_scenario, simulate
    from slip_estimator.sim.bag import sim_params

    result = simulate(short_scenario(0).replace(duration_s=12.0))
    params = sim_params(result)
    data = from_simulation(result, params)
    assert data.wheel_sides == tuple(wheel_side(n) for n in params.wheel_joint_names)
    assert set(data.wheel_sides) == {'left', 'right'}
    np.testing.assert_allclose(data.rim_mps, result.wheel_rate_rps * params.wheel_radius)
    # At rest and level the body-frame specific force is -g along z (FRD).
    assert np.mean(data.f_ib_b[:100, 2]) == pytest.approx(-9.8, abs=0.05)
    both = concatenate([data, data.shifted(10**11)])
    assert both.n_imu == 2 * data.n_imu and np.all(np.diff(both.imu_ns) > 0)
