"""The wheel-sample update driven alone (slip_estimator.core.wheel_update): a real filter,
history, wheel aid and updater, no estimator around them; closed-form expectations."""
import math

import numpy as np
import pytest

from slip_estimator.core.detectors import ImuRate, StationaryDetector
from slip_estimator.core.diagnosis import ResidualMonitor
from slip_estimator.core.filter import ErrorStateFilter
from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.core.history import ForwardSpeedHistory
from slip_estimator.core.measurements import ForwardSpeed
from slip_estimator.core.odometry_guard import OdometryGuard
from slip_estimator.core.params import Params
from slip_estimator.core.planet import EARTH
from slip_estimator.core.slip_model.wheel_aid import WheelAid
from slip_estimator.core.state import VEL, NavState
from slip_estimator.core.supervisor import Supervisor
from slip_estimator.core.types import WheelSample
from slip_estimator.core.updater import Updater
from slip_estimator.core.wheel_update import WheelUpdate

MS = 1_000_000
P0 = np.diag([1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-4, 1e-16, 1e-16, 1e-2,
              1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8])


def driving_north(v_fwd_mps: float = 1.0) -> WheelUpdate:
    """A level body heading north at ``v_fwd_mps``, its history recorded 0-400 ms."""
    p = Params()
    st = NavState(rpy_to_dcm(0.0, 0.0, 0.0), np.array([v_fwd_mps, 0.0, 0.0]),
                  np.array([math.radians(39.6), math.radians(-79.9), 310.0]), np.zeros(3),
                  np.zeros(3))
    flt = ErrorStateFilter(p, EARTH)
    flt.start(st, P0.copy(), 9.8)
    history = ForwardSpeedHistory((0.0, 0.0, 0.0))
    for k in range(5):
        history.record(k * 100 * MS, flt.state, [0.0, 0.0, 0.0], 0.1)
    supervisor, monitor = Supervisor(p), ResidualMonitor()
    updater = Updater(p, EARTH, np.zeros(3), supervisor.counters, monitor)
    return WheelUpdate(flt, history, StationaryDetector.for_params(p), ImuRate(), WheelAid(p),
                       OdometryGuard(), updater=updater, supervisor=supervisor,
                       monitor=monitor, forward=ForwardSpeed(EARTH, np.zeros(3)),
                       wheel_latency_ns=0)


def test_a_wheel_sample_the_history_does_not_hold_is_late_and_leaves_the_filter_alone():
    wu = driving_north()
    P_before = wu.filter.P.copy()
    assert wu.evaluate(WheelSample(900 * MS, 1.0)) is None
    assert wu.counters['wheel_late'] == 1 and wu.counters['slip_estimates'] == 0
    assert np.array_equal(wu.filter.P, P_before)


def test_while_recovering_the_rim_speed_re_anchors_the_speed_and_the_slip_is_unknown():
    """The scalar Kalman update of the forward speed towards the rim speed, R = the aid's
    variance plus 10 % of the rim speed (zero slip assumed); a repair: the free speed moves
    with the recorded one."""
    wu = driving_north(1.0)
    wu.supervisor.start_recovery(0)
    p_fwd = float(wu.filter.P[VEL, VEL][0, 0])
    r = wu.params.slip_model.wheel_aid_std_mps ** 2 + (0.1 * 1.2) ** 2
    est = wu.evaluate(WheelSample(200 * MS, 1.2))
    assert est.slip_class < 0 and wu.counters['slip_unknown'] == 1
    dv = p_fwd / (p_fwd + r) * 0.2
    assert float(wu.filter.state.v_eb_n[0]) == pytest.approx(1.0 + dv, rel=1e-6)
    assert wu.history.at(200 * MS).v_fwd_mps == pytest.approx(1.0 + dv, rel=1e-6)
    wu.history.record(500 * MS, wu.filter.state, [0.0, 0.0, 0.0], 0.1)
    assert wu.history.at(500 * MS).v_free_mps == pytest.approx(1.0 + dv, rel=1e-6)


def test_an_unknown_slip_is_counted():
    wu = driving_north()
    est = wu.unknown(7, 0.5)
    assert (est.stamp_ns, est.slip_class) == (7, -1) and wu.counters['slip_unknown'] == 1
