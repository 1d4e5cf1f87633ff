"""The node's callback-duration percentiles: the ring buffer and its order statistics."""
import numpy as np
import pytest

from slip_estimator.ros.spin import CallbackDurations


@pytest.mark.parametrize('window, count', [(5, 1), (5, 2), (5, 3), (100, 37), (1000, 2500)])
def test_summary_is_numpy_percentile_over_the_last_window(window, count):
    durations_s = np.random.default_rng(count).exponential(1e-4, count)
    d = CallbackDurations(window)
    for x in durations_s:
        d.add(float(x))
    kept_ms = durations_s[-window:] * 1e3
    p50, p99 = np.percentile(kept_ms, (50.0, 99.0))
    assert d.summary_ms() == [f'{p50:.3f}', f'{p99:.3f}', f'{kept_ms.max():.3f}',
                              str(min(window, count))]


def test_summary_before_the_first_callback_is_unknown():
    assert CallbackDurations(10).summary_ms() == ['unknown'] * 3 + ['0']
