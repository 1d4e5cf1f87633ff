"""Slip accuracy on simulated drives through the core (the product's acceptance figures).

The drives are wheel-rate controlled (the motor controllers hold the commanded wheel rate and
the terrain's slip changes the body speed, which only the IMU sees) or mix that with wheels
spinning up at an unchanged body speed; the IMU has noise, biases and speed-dependent
vibration. The paper's method without the wheel aid is shown to miss the levels, so the tests
can fail.
"""
import numpy as np
import pytest

from helpers import score_sim_drive

from slip_estimator.effects import run_core as run_core_data
from slip_estimator.streams import from_simulation
from slip_estimator.sim import mixed_scenario, short_scenario, simulate
from slip_estimator.sim.bag import sim_params


def _at_rest_alarms(seed: int) -> int:
    """Slip warnings (class >= 2) while body and wheels have been still for a second."""
    r = simulate(short_scenario(seed))
    p = sim_params(r)
    _, out, _ = run_core_data(p, from_simulation(r, p))
    still = (np.abs(r.wheel_speed_true_mps) < 1e-3) & \
        (np.abs(r.rim_speed_true_mps).max(axis=1) < 1e-3)
    t0 = r.stamps_ns(r.wheel_t_s)[0]
    alarms = 0
    for o in out:
        t = (o.stamp_ns - t0) * 1e-9
        window = (r.wheel_t_s >= t - 1.0) & (r.wheel_t_s <= t)
        if window.sum() >= 9 and still[window].all() and o.slip_class >= 2:
            alarms += 1
    return alarms


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_slip_accuracy_on_wheel_rate_controlled_drives(seed):
    """Measured on these drives: balanced 0.93-0.95, F1 0.88-0.89, medium/high/extreme recall
    >= 0.94 (the earlier hold mode: balanced 0.71, F1 0.70)."""
    res, speed_rmse = score_sim_drive(seed)
    assert res.coverage >= 0.95
    assert res.balanced_accuracy >= 0.90, res.recall
    assert min(res.recall[2:]) >= 0.90, res.recall
    assert res.significant_f1 >= 0.85
    assert speed_rmse < 0.05


@pytest.mark.parametrize('seed', [0, 2])
def test_slip_accuracy_on_mixed_drives(seed):
    """Body-side and wheel-side slip on one drive (earlier hold mode: balanced 0.38-0.58)."""
    res, _ = score_sim_drive(seed, scenario=mixed_scenario)
    assert res.coverage >= 0.95
    assert res.balanced_accuracy >= 0.90 and res.significant_f1 >= 0.90, res.recall


def test_no_slip_alarm_at_rest():
    assert _at_rest_alarms(0) == 0


def test_the_papers_method_alone_drifts_on_the_same_drive():
    """Without the wheel aid the forward velocity drifts between stops (vibration, gyro noise)
    and the medium/high classes are lost: the reason for the wheel aid."""
    res, speed_rmse = score_sim_drive(0, wheel_aid='off')
    assert res.balanced_accuracy < 0.8 and speed_rmse > 0.05



def test_a_patch_entered_after_hills_is_measured_in_full():
    """Until the step test fires, the wheel aid pulls the INS towards the old slip and the
    filter explains the pull as tilt and accelerometer bias; at the alarm that is taken back.
    Left in, the free INS measured these two patches (0.49, then 0.74, at 428-442 s of a
    seeded patch drive) at 0.28 and 0.37."""
    from slip_estimator.sim.drives import patch_scenario
    r = simulate(patch_scenario(1))
    p = sim_params(r)
    _, out, _ = run_core_data(p, from_simulation(r, p))
    t0 = r.stamps_ns(r.wheel_t_s)[0]
    t = np.array([(o.stamp_ns - t0) * 1e-9 for o in out])
    slip = np.array([o.slip_ratio for o in out])
    for (a, b), s_true in (((430.0, 435.0), 0.49), ((437.0, 442.0), 0.74)):
        assert np.median(slip[(t > a) & (t < b)]) == pytest.approx(s_true, abs=0.1)
