"""The multi-scale step test alone: a step is found with its onset, a walk of its own spread is
not, and the spread it learns is the walk's."""
import numpy as np

from slip_estimator.core.slip_model.step_test import StepTest

_DT_NS = 100_000_000  # 10 Hz


def test_a_step_alarms_at_once_with_the_onset_before_it():
    test = StepTest(1e-4)
    alarms = []
    for k in range(100):
        rho = 0.0 if k < 50 else -0.3  # the body slowed by 0.3 m/s at sample 50
        onset = test.add(k * _DT_NS, rho, 0.0, 0.05, 3.5)
        if onset is not None:
            alarms.append((k, onset))
    k, onset = alarms[0]
    assert 50 <= k <= 53  # within the 0.5-s smoothing
    # Both scales see it: the onset is bounded by the longest (a slow transition began
    # earlier), and lies before the step.
    assert onset == k * _DT_NS - 2_500_000_000 and onset <= 50 * _DT_NS


def test_a_random_walk_within_its_spread_does_not_alarm_and_its_spread_is_learned():
    rng = np.random.default_rng(0)
    sigma_rts = 0.02  # m/s per sqrt(s)
    walk = np.cumsum(rng.normal(0.0, sigma_rts * np.sqrt(0.1), 6000))
    test = StepTest(sigma_rts ** 2)
    alarms = sum(test.add(k * _DT_NS, float(r), 0.0, 0.05, 3.5) is not None
                 for k, r in enumerate(walk))
    # Two scales at 3.5 sigma: about 1e-3 false alarms per sample for a Gaussian statistic.
    assert alarms <= 15
    # The 2.5-s change of a 0.5-s mean of the walk: about sigma^2 * (2.5 - 0.5 / 3).
    assert 0.8 < np.sqrt(test.spread_var[1] / (sigma_rts ** 2 * (2.5 - 0.5 / 3))) < 1.2


def test_the_aid_acceleration_is_taken_out_of_the_change():
    """A ramp of the residual that the aid's own corrections explain is no step."""
    test = StepTest(1e-4)
    alarms = [test.add(k * _DT_NS, -0.2 * k * 0.1, 0.2, 0.1, 3.5) for k in range(60)]
    assert all(a is None for a in alarms)
    test = StepTest(1e-4)  # the same ramp without that acceleration is a change
    assert any(test.add(k * _DT_NS, -0.2 * k * 0.1, 0.0, 0.1, 3.5) is not None
               for k in range(60))


def test_a_floor_on_the_spread_keeps_a_step_within_it_quiet():
    """A 0.3 m/s step alarms against the learned prior (0.01 m/s per sqrt(s)), but not
    against a floor of 0.2 m/s at both scales (the filter knows its free INS drifts that
    much: a consumer IMU's tilt); the floor also bounds the robust clipping of the learning."""
    def alarms(floor):
        test = StepTest(1e-4)
        n = sum(test.add(k * _DT_NS, 0.0 if k < 50 else -0.3, 0.0, 0.05, 3.5, floor)
                is not None for k in range(100))
        return n, test
    assert alarms(())[0] > 0
    n, test = alarms((0.04, 0.04))
    assert n == 0 and test.spread_var[1] > 2.5e-4  # the step was learned from, not clipped
