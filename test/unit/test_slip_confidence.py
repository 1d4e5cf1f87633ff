"""The published slip's 1-sigma and P(medium+) (core/slip_confidence.py): closed-form cases,
the re-examination record, and that nothing of it reaches the filter or the class."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_estimator.core.estimator import SlipEstimator
from slip_estimator.core.outputs import MEDIUM_CLASS_WIDTH, RESOLVED_P, slip_estimate
from slip_estimator.core.params import Params
from slip_estimator.core.slip import p_beyond_medium_bound, slip_ratio_std
from slip_estimator.core.slip_confidence import (Confidence, ReadingRecord, mixture_std,
                                                 p_medium_mixture, resolution_var_mps2)
from slip_estimator.core.types import WheelSample


def _phi(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def test_a_change_below_the_threshold_is_uniform_within_it():
    """+-0.3 m/s uniform: variance 0.3^2 / 3 = 0.03."""
    assert resolution_var_mps2(0.3) == pytest.approx(0.03)
    assert resolution_var_mps2(0.0) == 0.0


def test_p_medium_is_the_mixture_of_the_reading_and_the_ground():
    """s = 0.4 +- 0.1 is beyond 0.2 with Phi(2) = 0.97725; the ground 0.1 read as well with
    Phi(-1) = 0.15866; wrong with 0.25: 0.75 * 0.97725 + 0.25 * 0.15866."""
    assert p_medium_mixture(0.4, 0.1, 0.0, 0.1) == pytest.approx(_phi(2.0))
    assert p_medium_mixture(0.4, 0.1, 1.0, 0.1) == pytest.approx(_phi(-1.0))
    assert p_medium_mixture(0.4, 0.1, 0.25, 0.1) == pytest.approx(
        0.75 * _phi(2.0) + 0.25 * _phi(-1.0))
    # One-sided: a skid reading counts its own side; a reading that says nothing, 1/2.
    assert p_medium_mixture(-0.4, 0.1, 0.0, 0.0) == pytest.approx(_phi(2.0))
    assert p_medium_mixture(0.1, 100.0, 0.0, 0.0) == pytest.approx(0.5, abs=1e-3)
    assert math.isnan(p_medium_mixture(float('nan'), 0.1, 0.5, 0.0))


def test_mixture_std_is_the_mixture_s_second_moment():
    """0.4 with 0.75, 0.1 with 0.25, each +- 0.1: variance 0.01 + 0.75 * 0.25 * 0.3^2; no
    doubt: the reading's; capped at 1."""
    assert mixture_std(0.4, 0.1, 0.25, 0.1) == pytest.approx(
        math.sqrt(0.01 + 0.1875 * 0.09))
    assert mixture_std(0.4, 0.1, 0.0, 0.1) == pytest.approx(0.1)
    assert mixture_std(1.0, 0.9, 0.5, -1.0) == 1.0


def test_reading_record_counts_disagreeing_re_examinations_and_the_chain():
    """From rest the first hold is the ground's (no reading to doubt). An alarm whose
    measurement finds the hold before it disagreed: eps = (1 + 1) / (1 + 5). A new hold away
    from the baseline rests on one reading (eps = 2 / 7); while the next is measured, on
    two: 1 - (1 - eps)^2; a return to the baseline or a stop ends the chain."""
    rec = ReadingRecord()
    rec.observe(None, None, True)  # at rest
    rec.observe(None, None, False)  # measuring from rest
    assert rec.wrong_probability(None, None) == pytest.approx(0.2)  # the prior, one reading
    rec.observe(0.1, 0.1, False)
    assert rec.wrong_probability(0.1, 0.1) == 0.0 and rec.n_reexamined == 0
    rec.observe(None, 0.1, False)  # an alarm
    rec.observe(0.1, 0.1, False)  # the measurement kept the hold: disagreed
    assert (rec.n_reexamined, rec.n_disagreed) == (1, 1)
    assert rec.eps == pytest.approx(2.0 / 6.0)
    rec.observe(None, 0.1, False)
    rec.observe(0.5, 0.1, False)  # a change
    eps = 2.0 / 7.0
    assert rec.eps == pytest.approx(eps) and rec.chained == 1
    c = rec.confidence(0.5, 0.1, 0.3)
    assert c[:3] == pytest.approx((0.03, eps, 0.1))
    assert (c.s_held, c.p_wrong_departed) == (0.5, pytest.approx(1.0 - (1.0 - eps) ** 2))
    rec.observe(None, 0.1, False)
    assert rec.wrong_probability(None, 0.1) == pytest.approx(1.0 - (1.0 - eps) ** 2)
    rec.observe(0.7, 0.1, False)
    assert rec.chained == 2
    rec.observe(None, 0.1, False)
    rec.observe(0.1, 0.1, False)  # back on the baseline
    assert rec.chained == 0 and rec.wrong_probability(0.1, 0.1) == 0.0
    rec.observe(None, 0.1, False)
    rec.observe(0.6, 0.1, False)
    rec.observe(None, 0.1, True)  # a stop
    assert rec.chained == 0 and rec.n_reexamined == 5


def test_a_reading_whose_published_sigma_is_wider_than_the_medium_class_must_resolve_under_it():
    """Body 0.7 m/s +- 0.01, rim 1.0 (s = 0.3; the filter's 1-sigma about 0.01 resolves
    medium). Wrong with 0.9 against the ground's 0.0 (a reading across 0.2 from a low hold):
    published 1-sigma sqrt(sd^2 + 0.09 * 0.3^2) = 0.09, within the medium class's 0.2: the
    class stays medium. With an unseen change of 1 m/s on top (1 / sqrt(3) = 0.58, the
    published 1-sigma 0.58, wider than the class): beyond 0.2 with Phi(0.1 / 0.58) = 0.57,
    below RESOLVED_P: low, unresolved. A reading of 0.6 (body 0.4) with an unseen change of
    3 m/s: its published 1-sigma at the cap of 1 (the slip unknown), beyond 0.2 with
    Phi(0.4) = 0.66, yet low, unresolved. A resolved medium hold (0.3) keeps the class
    medium."""
    p, wheel = Params(), WheelSample(7, 1.0)
    narrow = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.05,
                           confidence=Confidence(0.0, 0.1, 0.0, 0.05, 0.9))
    assert narrow.slip_ratio_std < MEDIUM_CLASS_WIDTH
    assert (narrow.slip_class, narrow.resolved) == (2, True)
    wide_c = Confidence(resolution_var_mps2(1.0), 0.1, 0.0, 0.05, 0.9)
    wide = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.05,
                         confidence=wide_c)
    assert wide.slip_ratio_std > MEDIUM_CLASS_WIDTH
    assert p_beyond_medium_bound(0.3, wide.slip_ratio_std) < RESOLVED_P
    assert (wide.slip_class, wide.resolved, wide.slip_ratio) == (1, False, pytest.approx(0.3))
    unknown = slip_estimate(wheel, 0.4, 0.0, 1e-4, p, False, 1.0, held_slip=0.05,
                            confidence=Confidence(resolution_var_mps2(3.0), 0.1, 0.0, 0.05, 0.9))
    assert unknown.slip_ratio_std == 1.0 and p_beyond_medium_bound(0.6, 1.0) > RESOLVED_P
    assert (unknown.slip_class, unknown.resolved) == (1, False)
    held = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.3,
                         confidence=wide_c._replace(s_held=0.3))
    assert held.slip_ratio_std > MEDIUM_CLASS_WIDTH and (held.slip_class, held.resolved) == \
        (2, True)


def test_published_sigma_and_p_add_to_the_reading_without_moving_its_class():
    """Body 0.7 m/s +- 0.01, rim 1.0 (s = 0.3): the published 1-sigma propagates the filter's
    variance plus the unseen change (0.1 m/s: 0.01^2 + 0.1^2 / 3) through eq. 1 (sigma), then
    the doubt: wrong with 0.3, the ground's 0.05: sqrt(sigma^2 + 0.3 * 0.7 * 0.25^2);
    P(medium+) = 0.7 Phi((0.3 - 0.2) / sigma) + 0.3 Phi((0.05 - 0.2) / sigma). The class
    stays medium, resolved, as without."""
    p, wheel = Params(), WheelSample(7, 1.0)
    var_w = p.wheel_speed_std_mps ** 2
    plain = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.3)
    c = Confidence(resolution_var_mps2(0.1), 0.3, 0.05)
    est = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.3, confidence=c)
    sd = slip_ratio_std(0.7, 1.0, 1e-4 + 0.1 ** 2 / 3.0, var_w)
    assert sd > plain.slip_ratio_std
    assert est.slip_ratio_std == pytest.approx(math.sqrt(sd ** 2 + 0.3 * 0.7 * 0.25 ** 2))
    assert est.p_medium_or_worse == pytest.approx(
        0.7 * _phi(0.1 / sd) + 0.3 * _phi(-0.15 / sd))
    assert (est.slip_class, est.resolved, est.slip_ratio) == \
        (plain.slip_class, plain.resolved, plain.slip_ratio) == (2, True, pytest.approx(0.3))
    # Without a confidence the published P is the reading's one-sided probability.
    assert plain.p_medium_or_worse == pytest.approx(
        p_beyond_medium_bound(0.3, plain.slip_ratio_std))
    still = slip_estimate(WheelSample(7, 0.0), 0.0, 0.0, 1e-4, p, True, 1.0, confidence=c)
    assert (still.slip_ratio_std, still.p_medium_or_worse) == (0.0, 0.0)


def test_a_reading_off_the_hold_across_0_2_rests_on_one_reading_more():
    """Hold on the baseline 0.1 after re-examinations that mostly disagreed (eps = 0.9): a
    reading s = 0.3 (body 0.7 m/s, rim 1.0) is a change no alarm saw, wrong with 0.9 and then
    the ground's 0.1: P(medium+) = 0.1 Phi(0.1 / sd) + 0.9 Phi(-0.1 / sd), below 0.8 (the
    reading alone: Phi(0.1 / sd), sd about 0.01: 1.0). A reading on the hold's side of 0.2
    keeps the hold's doubt (none on the baseline). The class and ratio stay the reading's."""
    rec = ReadingRecord()
    rec.observe(None, None, True)
    rec.observe(None, None, False)
    rec.observe(0.1, 0.1, False)
    rec.n_reexamined, rec.n_disagreed = 5, 8  # as counted: eps = (8 + 1) / (5 + 5)
    assert rec.eps == pytest.approx(0.9)
    c = rec.confidence(0.1, 0.1, 0.0)
    assert (c.wrong_at(0.15), c.wrong_at(0.3), c.wrong_at(-0.3)) == \
        (0.0, pytest.approx(0.9), pytest.approx(0.9))
    p, wheel = Params(), WheelSample(7, 1.0)
    plain = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.1)
    est = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.1, confidence=c)
    sd = slip_ratio_std(0.7, 1.0, 1e-4, p.wheel_speed_std_mps ** 2)
    assert plain.p_medium_or_worse > 0.99
    assert est.p_medium_or_worse == pytest.approx(
        0.1 * _phi(0.1 / sd) + 0.9 * _phi(-0.1 / sd)) and est.p_medium_or_worse < 0.8
    assert (est.slip_class, est.slip_ratio) == (plain.slip_class, plain.slip_ratio)
    low = slip_estimate(wheel, 0.85, 0.0, 1e-4, p, False, 1.0, held_slip=0.1, confidence=c)
    assert low.p_medium_or_worse == pytest.approx(
        p_beyond_medium_bound(low.slip_ratio, low.slip_ratio_std))


def test_a_doubted_hold_resolves_medium_only_by_the_published_probability():
    """A hold of 0.30 (body 0.7 m/s +- 0.01, rim 1.0) chained after a rejected run-ahead
    (doubt 0.5, the ground's baseline 0.05): P(medium+) = 0.5 Phi(0.1 / sd) + 0.5
    Phi(-0.15 / sd), about 0.5, below RESOLVED_P: published low, unresolved, its ratio the
    reading's. Undoubted, the same hold is medium."""
    rec = ReadingRecord()
    rec.observe(None, None, True)
    rec.observe(None, None, False)
    rec.observe(0.05, 0.05, False)
    rec.observe(None, 0.05, False)  # an alarm, then the change settles
    rec.observe(0.3, 0.05, False)
    p, wheel = Params(), WheelSample(7, 1.0)
    plain_c = rec.confidence(0.3, 0.05, 0.0)
    doubted_c = rec.confidence(0.3, 0.05, 0.0, doubt=0.5)
    assert doubted_c.doubted and not plain_c.doubted
    assert doubted_c.p_wrong == pytest.approx(1.0 - (1.0 - plain_c.p_wrong) * 0.5)
    plain = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.3,
                          confidence=plain_c)
    est = slip_estimate(wheel, 0.7, 0.0, 1e-4, p, False, 1.0, held_slip=0.3,
                        confidence=doubted_c)
    assert (plain.slip_class, plain.resolved) == (2, True)
    assert est.p_medium_or_worse < RESOLVED_P
    assert (est.slip_class, est.resolved, est.slip_ratio) == (1, False, plain.slip_ratio)


class _Plain(SlipEstimator):
    """The estimator publishing the filter's reading only."""

    def _reset_filter(self):
        super()._reset_filter()
        self.wheel_aid.confidence = lambda rim_speed_mps, turning: Confidence()


def test_the_confidence_changes_what_is_published_about_the_slip_only():
    """A simulated drive with and without the confidence: the same odometry and the same
    slip ratios; a wider published 1-sigma; the same classes except readings published low
    and unresolved where the published 1-sigma grew wider than the medium class."""
    from slip_estimator.effects import run_core
    from slip_estimator.sim import short_scenario, simulate
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.streams import from_simulation

    r = simulate(short_scenario(0))
    params = sim_params(r)
    data = from_simulation(r, params)
    _, out, odo = run_core(params, data)
    _, out0, odo0 = run_core(params, data, estimator=_Plain)
    assert np.array_equal(odo, odo0)
    for a, b in zip(out, out0):
        assert a.slip_class == b.slip_class or (
            (a.slip_class, a.resolved) == (1, False) and b.slip_class >= 2
            and a.slip_ratio_std > MEDIUM_CLASS_WIDTH)
    assert np.array_equal([o.slip_ratio for o in out], [o.slip_ratio for o in out0],
                          equal_nan=True)
    moving = [(a.slip_ratio_std, b.slip_ratio_std) for a, b in zip(out, out0)
              if a.slip_class > 0]
    assert moving and all(a >= b for a, b in moving) and any(a > b for a, b in moving)
