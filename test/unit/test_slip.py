"""Slip ratio closed-form cases (paper eq. 1) and classification."""
import math

import pytest

from slip_estimator.core.slip import (p_beyond_medium_bound, p_medium_or_worse, slip_class,
                                      slip_ratio, slip_ratio_std)


@pytest.mark.parametrize('v, w, expected', [
    (0.5, 0.5, 0.0),        # rolling without slip
    (0.35, 0.5, 0.3),       # driving slip: 1 - v/(r w)
    (0.0, 0.5, 1.0),        # wheels spin, body stopped
    (0.5, 0.4, -0.2),       # skid: r w / v - 1
    (0.5, 0.0, -1.0),       # wheels locked, body slides
    (-0.35, -0.5, 0.3),     # reversing mirrors forward driving
    (-0.2, 0.5, 1.0),       # body moves against its wheels: clamped extreme
])
def test_slip_ratio_closed_form(v, w, expected):
    assert slip_ratio(v, w) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize('s, moving, cls', [
    (0.0, False, 0), (0.0, True, 1), (0.2, True, 1), (0.2000001, True, 2), (-0.39, True, 2),
    (0.4, True, 2), (0.55, True, 3), (-0.7, True, 3), (0.71, True, 4), (1.0, True, 4),
])
def test_slip_class_boundaries(s, moving, cls):
    assert slip_class(s, moving) == cls


@pytest.mark.parametrize('v, w', [(0.35, 0.5), (0.6, 0.5)])
def test_slip_std_matches_finite_difference_propagation(v, w):
    var_v, var_w = 0.01 ** 2, 0.02 ** 2
    e = 1e-7
    ds_dv = (slip_ratio(v + e, w) - slip_ratio(v - e, w)) / (2 * e)
    ds_dw = (slip_ratio(v, w + e) - slip_ratio(v, w - e)) / (2 * e)
    expected = math.sqrt(ds_dv ** 2 * var_v + ds_dw ** 2 * var_w)
    assert slip_ratio_std(v, w, var_v, var_w) == pytest.approx(expected, rel=1e-5)


def test_p_medium_or_worse_closed_form():
    """P(|S| > 0.2), S ~ N(s, sigma^2): both tails of the normal, in closed form."""
    tail = lambda z: 0.5 * math.erfc(z / math.sqrt(2.0))  # P(Z > z)
    assert p_medium_or_worse(0.0, 0.1) == pytest.approx(2.0 * tail(2.0))  # 0.0455
    assert p_medium_or_worse(0.3, 0.1) == pytest.approx(1.0 - tail(1.0) + tail(5.0))
    assert p_medium_or_worse(-0.3, 0.1) == pytest.approx(p_medium_or_worse(0.3, 0.1))
    assert p_medium_or_worse(0.2, 0.05) == pytest.approx(0.5 + tail(8.0))
    assert p_medium_or_worse(0.9, 0.01) == pytest.approx(1.0)
    assert p_medium_or_worse(0.25, 0.0) == 1.0 and p_medium_or_worse(0.15, 0.0) == 0.0
    assert math.isnan(p_medium_or_worse(float('nan'), 0.1))
    assert math.isnan(p_medium_or_worse(0.3, float('nan')))


def test_p_beyond_medium_bound_is_one_sided():
    """P(sign(s) S > 0.2): Phi((|s| - 0.2) / sigma); 1/2 at the bound and as sigma grows
    (where the two-sided P(medium+) tends to 1)."""
    tail = lambda z: 0.5 * math.erfc(z / math.sqrt(2.0))
    assert p_beyond_medium_bound(0.3, 0.1) == pytest.approx(1.0 - tail(1.0))
    assert p_beyond_medium_bound(-0.3, 0.1) == pytest.approx(1.0 - tail(1.0))
    assert p_beyond_medium_bound(0.2, 0.05) == pytest.approx(0.5)
    assert p_beyond_medium_bound(0.3, 100.0) == pytest.approx(0.5, abs=1e-3)
    assert p_medium_or_worse(0.3, 100.0) == pytest.approx(1.0, abs=1e-2)
    assert p_beyond_medium_bound(0.1, 0.0) == 0.0 and p_beyond_medium_bound(0.25, 0.0) == 1.0
