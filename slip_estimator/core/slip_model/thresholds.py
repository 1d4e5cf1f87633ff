"""The slip model's change thresholds, from the parameters, the step test's learned spread and
the filter's prediction of its free INS (:attr:`~.records.ModelSample.reading_var_mps2`).
Speeds in m/s, variances in m^2/s^2. Only the standard library is used."""
from __future__ import annotations

import math
from collections.abc import Sequence

from slip_estimator.core.params import Params
from slip_estimator.core.slip_model.chain import coarse_ins

TURN_THRESHOLD_FACTOR = 1.5
"""The INS is worse in turns (lever arm, skid): the body-side threshold is raised by this."""


def spread_var_mps2(learned_var_mps2: list[float],
                    reading_var_mps2: Sequence[float]) -> list[float]:
    """Variance of the free residual's change at each step-test scale, m^2/s^2: the one
    learned online (``learned_var_mps2``, :attr:`~.step_test.StepTest.spread_var`), or the
    filter's own prediction of the free INS over that scale (``reading_var_mps2``) if larger
    (a tilt the filter knows it does not know is a drift the step test must not take for slip,
    before it has learned it)."""
    if not reading_var_mps2:
        return learned_var_mps2
    return [max(a, b) for a, b in zip(learned_var_mps2, reading_var_mps2)]


def predicted_coarse(reading_var_mps2: Sequence[float], w_mps: float) -> bool:
    """The filter predicts its free INS over the shortest step-test scale
    (``reading_var_mps2[0]``) too coarse to place a slip within the low class at rim speed
    ``w_mps`` (:func:`~.chain.coarse_ins`)."""
    return bool(reading_var_mps2) and coarse_ins(reading_var_mps2[0], w_mps)


def wheel_change_mps(p: Params, w_mps: float) -> float:
    """Aid innovation that signals a wheel-side slip change at rim speed ``w_mps``, m/s."""
    return max(p.slip_change_fraction * abs(w_mps), 2.0 * p.wheel_aid_std_mps)


def body_change_sigmas(p: Params, turning: bool) -> float:
    """The step test's ``k``: ``slip_change_sigma``, raised while turning."""
    return p.slip_change_sigma * (TURN_THRESHOLD_FACTOR if turning else 1.0)


def body_change_mps(p: Params, spread_var: list[float], w_mps: float,
                    turning: bool = False) -> float:
    """CUSUM threshold h of a body-side change at rim speed ``w_mps``, m/s: the wheel-side
    threshold, or ``slip_change_sigma`` times the 1-s spread of the free residual
    (``spread_var[0]``, :func:`spread_var_mps2`) if larger (raised while turning)."""
    h = max(wheel_change_mps(p, w_mps), p.slip_change_sigma * math.sqrt(spread_var[0]))
    return h * (TURN_THRESHOLD_FACTOR if turning else 1.0)
