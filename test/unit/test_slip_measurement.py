"""One slip measurement alone, on closed-form speed sequences: when the body has settled and
what was measured from each kind of start (rest, a body-side alarm, a wheel-side change)."""
from __future__ import annotations

import numpy as np
import pytest

from slip_estimator.core.slip_model.aided_record import Anchor
from slip_estimator.core.slip_model.measurement import SlipMeasurement

DT_S = 0.1
MEASURE_S = 0.5
SIGMA = 2.0  # slip_continuity_sigma


def feed(m: SlipMeasurement, w_mps, v_mps, v_free_mps=None, noise_var=0.0) -> float | None:
    """Feed 10-Hz samples until the measurement settles; return its settling time (s)."""
    v_free_mps = v_mps if v_free_mps is None else v_free_mps
    for k, (w, v, vf) in enumerate(zip(w_mps, v_mps, v_free_mps)):
        if m.add(int(round(k * DT_S * 1e9)), float(w), float(v), float(vf), noise_var):
            return k * DT_S
    return None


def test_a_measurement_waits_until_the_body_has_settled():
    # Entering sand at a held wheel rate: the body slows 0.5 -> 0.3 m/s over 1.2 s (s = 0.4).
    t = np.arange(0.0, 4.0, DT_S)
    w = np.full_like(t, 0.5)
    v = 0.5 - 0.2 * np.clip(t / 1.2, 0.0, 1.0)
    m = SlipMeasurement(MEASURE_S)
    m.start(None)
    t_settled = feed(m, w, v)
    assert t_settled is not None and t_settled >= 1.2  # not before the body stopped slowing
    assert m.slip(None, SIGMA, 0.0, 0.0, 2.5) == pytest.approx(0.4, abs=0.01)


def test_a_body_that_never_settles_is_measured_after_the_timeout():
    t = np.arange(0.0, 10.0, DT_S)
    m = SlipMeasurement(MEASURE_S)
    m.start(None)
    assert feed(m, np.full_like(t, 1.0), 1.0 - 0.3 * t) == pytest.approx(5 * MEASURE_S)


@pytest.mark.parametrize('body', [True, False])
def test_a_body_side_reading_still_moving_at_the_timeout_is_drift(body):
    """After a body-side alarm a free INS that keeps accelerating (0.3 m/s^2: a 1.7-degree
    tilt error) at a steady rim is drifting, not slipping; one that settles is not; and a
    start from rest that times out is measured as before (no hold to keep)."""
    t = np.arange(0.0, 10.0, DT_S)
    m = SlipMeasurement(MEASURE_S)
    m.start(Anchor(1.0, 1.0, True) if body else None)
    assert feed(m, np.full_like(t, 1.0), 1.0 - 0.3 * t) == pytest.approx(5 * MEASURE_S,
                                                                         abs=1.5 * DT_S)
    assert m.drifting() is body
    m.start(Anchor(1.0, 1.0, True))
    assert feed(m, np.full_like(t, 1.0), 1.0 - 0.3 * np.clip(t, 0.0, 1.0)) is not None
    assert not m.drifting()


def test_after_a_body_side_alarm_the_free_ins_mean_speed_is_the_measurement():
    # The alarm re-anchored the velocity; the rest of the transition runs through.
    t = np.arange(0.0, 3.0, DT_S)
    v = 0.35 - 0.05 * np.clip(t / 0.5, 0.0, 1.0)
    m = SlipMeasurement(MEASURE_S)
    m.start(Anchor(0.5, 0.5, True))
    assert feed(m, np.full_like(t, 0.5), v) is not None
    assert m.slip(0.0, SIGMA, 0.0, 0.0, 2.5) == pytest.approx(0.4, abs=0.02)


def test_after_a_body_side_alarm_the_settled_rest_spans_the_measuring_time():
    # The alarm came mid-transition: 0.6 s more of slowing, then 0.5 s of settled speed.
    t = np.arange(0.0, 3.0, DT_S)
    v = 0.8 - 0.5 * np.clip(t, 0.0, 0.6)
    m = SlipMeasurement(MEASURE_S)
    m.start(Anchor(1.0, 1.0, True))
    assert feed(m, np.full_like(t, 1.0), v) >= 0.6 + MEASURE_S - DT_S / 2


@pytest.mark.parametrize('v_change_mps, w_after_mps, expected', [
    (0.004, 0.625, 0.2),    # wheels spun up, the body kept its speed (within the INS spread)
    (0.125, 0.625, 0.0),    # a commanded rate the body followed
    (0.010, 0.510, 0.0),    # a small commanded change: closer to the rim's own change
    (-0.1, 0.5, 0.2),       # the rim held, the body slowed beyond the spread
])
def test_a_wheel_side_change_is_continuity_from_before_the_rim_moved(v_change_mps, w_after_mps,
                                                                     expected):
    t = np.arange(0.0, 1.0, DT_S)
    w = np.full_like(t, w_after_mps)
    v_free = np.full_like(t, -3.0 + v_change_mps)  # the free INS: only its change counts
    m = SlipMeasurement(MEASURE_S)
    m.start(Anchor(0.5, -3.0, False, 0.0, -0.5e9))  # held speed 0.5 m/s at zero slip
    assert feed(m, w, np.full_like(t, 0.4), v_free) is not None
    noise_var = 0.01 ** 2  # 2 sigma = 0.02 m/s
    assert m.slip(0.0, SIGMA, noise_var, 0.0, 2.5) == pytest.approx(expected, abs=1e-9)


def test_the_free_ins_change_is_taken_with_the_aids_acceleration_at_the_anchor():
    # The free speed drifts by minus the aid's learned acceleration: no change is measured.
    t = np.arange(0.0, 1.0, DT_S)
    aid_accel = 0.1
    t_anchor_s = -0.5
    v_free = -3.0 - aid_accel * (t - t_anchor_s)
    m = SlipMeasurement(MEASURE_S)
    m.start(Anchor(0.5, -3.0, False, aid_accel, t_anchor_s * 1e9))
    feed(m, np.full_like(t, 0.5), np.full_like(t, 0.5), v_free)
    assert m.slip(0.0, SIGMA, 1e-6, 0.0, 2.5) == pytest.approx(0.0, abs=1e-6)
