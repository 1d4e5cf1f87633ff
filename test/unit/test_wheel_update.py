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
from slip_estimator.core.odometry_guard import OdometryGuard, decide
from slip_estimator.core.params import Params
from slip_estimator.core.planet import EARTH
from slip_estimator.core.slip_model.wheel_aid import WheelAid
from slip_estimator.core.state import VEL, NavState
from slip_estimator.core.supervisor import Supervisor
from slip_estimator.core.types import SlipEstimate, WheelSample
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


def test_the_end_of_a_fallback_of_a_measuring_span_forgets_the_cross_track_correlations():
    """Heading north, fallen back 3 s before (a coarse INS, 0.5 m/s of error at 1 m/s); the
    fused position's error correlated 0.9 with the speed's, north (along track) and east
    (across). The next sample, on a fine INS, ends the fallback: the east (cross-track)
    position keeps its variance but no correlation with any other error (the aid's next speed
    updates would otherwise move it sideways for an error the published track, on the wheels,
    never had); the north one keeps its correlation (the published track shares the along-track
    error of the rim speed the INS was aided with). A sample that ends no fallback leaves both."""
    def correlated() -> WheelUpdate:
        wu = driving_north(1.0)
        P = wu.filter.P
        P[6, 3] = P[3, 6] = 0.9 * math.sqrt(P[6, 6] * P[3, 3])
        P[7, 4] = P[4, 7] = 0.9 * math.sqrt(P[7, 7] * P[4, 4])
        return wu
    wu = correlated()
    coarse = SlipEstimate(-3_000 * MS, 1.0, 0.1, 4, 0.0, 0.1, 1.0)
    wu.odometry_guard.wheel(decide(coarse, 0.5 ** 2, False, 3.5))
    assert wu.odometry_guard.fallback
    east_var = wu.filter.P[7, 7]
    assert wu.evaluate(WheelSample(200 * MS, 1.0)) is not None
    assert not wu.odometry_guard.fallback
    P = wu.filter.P
    assert P[7, 7] == pytest.approx(east_var, rel=1e-9)
    np.testing.assert_allclose(np.delete(P[7], 7), 0.0, atol=1e-12 * math.sqrt(P[7, 7]))
    assert P[6, 3] > 0.5 * math.sqrt(P[6, 6] * P[3, 3])
    kept = correlated()
    kept.evaluate(WheelSample(200 * MS, 1.0))
    assert kept.filter.P[7, 4] > 0.5 * math.sqrt(kept.filter.P[7, 7] * kept.filter.P[4, 4])
