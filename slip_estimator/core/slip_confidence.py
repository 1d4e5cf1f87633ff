"""What the published slip's 1-sigma and its probability of medium-or-worse slip add to the
filter's reading: the planner's contract (issue 27, deliverable 3). Nothing here feeds back
into the filter; the class uses the published 1-sigma only where it is wider than the medium
class (:func:`~slip_estimator.core.outputs._resolved`; standard library only).

Two things the filter's velocity covariance does not know, both measured online:

* **The change the step test cannot see.** While a slip is held, the aid pulls the INS onto the
  hold, and a slip change smaller than the body-side threshold ``h`` (the slip model's
  :meth:`~slip_estimator.core.slip_model.model.SlipModel.body_change_mps`: the learned 1-s
  spread of the free residual times ``slip_change_sigma``, or the wheel-side threshold) leaves no
  alarm. The body speed is then known only to within ``+-h``: uniform, variance ``h^2 / 3``
  (:func:`resolution_var_mps2`). Where the IMU is coarse (vibration, a consumer IMU) ``h`` is
  wide and so is the published sigma.
* **A reading may be wrong.** Every held slip away from the ground's baseline rests on the
  readings chained since the last anchor (a stop, a return to the baseline); each is a change
  the free INS read. The slip model re-examines every alarm with a measurement; the share of
  re-examinations that disagreed (the measurement found the hold before the alarm: the alarm
  was INS error) estimates how often this IMU's change readings are INS error,
  ``eps = (n_disagreed + 1) / (n + 5)`` (a prior of one in five, worth five re-examinations).
  A hold resting on ``k`` chained readings is right only if each is:
  ``eps_k = 1 - (1 - eps)^k``; where it is wrong the slip is the ground's baseline ``s_b``,
  read no better than the reading itself (the same 1-sigma: a doubt about the reading must
  not make it more certain). The published slip is that mixture: P(medium+) is
  ``(1 - eps_k) P(s, sigma) + eps_k P(s_b, sigma)`` (:func:`p_medium_mixture`), the 1-sigma
  the mixture's, ``sqrt(sigma^2 + eps_k (1 - eps_k) (s - s_b)^2)`` (:func:`mixture_std`;
  :class:`ReadingRecord` keeps the count). A reading on the other side of 0.2 than the hold
  (the filter's speed moved off the hold with no alarm: a change no re-examination confirmed)
  rests on one reading more (:meth:`Confidence.wrong_at`): on a hold on the baseline, ``eps``
  itself. Before, a 30-Hz consumer IMU published P(medium+) >= 0.8 for low truth on a hold on
  the baseline where its drive had learned eps = 0.91-0.92 (skid_steer_30hz seed 2, 3
  samples; skid_steer_30hz_vibrating seed 3, 23 samples; none truly medium+).

P(medium+) is one-sided: the probability that the slip lies beyond 0.2 on the reading's side
(:func:`~slip_estimator.core.slip.p_beyond_medium_bound`). The Gaussian in slip is a
linearisation about the reading; its far tail (a skid where the reading says the body is
slower than its wheels) is an artefact of a wide sigma, and two-sided the probability tends to
0.84 for a reading that says nothing (a rim speed of a few cm/s at a start or a stop).

Measured with ``slip-estimator accuracy`` (truth within the published 2-sigma; the share truly
medium or worse of the samples published with P(medium+) >= 0.8), per simulated family, on
seeds not tuned on: before / after in the commit that added this module.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from slip_estimator.core.slip import MEDIUM_LOWER_BOUND, p_beyond_medium_bound

EPS_PRIOR_DISAGREED = 1.0
"""Prior re-examinations that disagreed (of ``EPS_PRIOR_N``): a reading is wrong one time in
five until the drive has measured its own rate (measured on seeds 0-3 of every simulated
family: 0-14 % of the changed holds read the wrong side of 0.2 on the nominal, patch and rough
drives, 43-44 % on the 50-Hz and the 30-Hz consumer robot profiles)."""
EPS_PRIOR_N = 5.0
"""Prior re-examinations (their weight against the drive's own)."""


class Confidence(NamedTuple):
    """What the published slip of one wheel sample adds to the filter's reading."""

    resolution_var_mps2: float = 0.0
    """body-speed variance of the slip change the step test cannot see, m^2/s^2"""
    p_wrong: float = 0.0
    """probability that the reading is wrong"""
    s_alt: float = 0.0
    """the slip where it is: the ground's baseline (zero, the wheels', before one)"""
    s_held: float | None = None
    """the slip model's hold (None while it measures or at rest)"""
    p_wrong_departed: float = 0.0
    """probability that a reading departed from the hold is wrong: one reading more"""
    doubted: bool = False
    """the hold rests on a decision of the slip model's that the IMU cannot make (chained after
    a rejected run-ahead): it resolves medium or worse only by the published P(medium+)
    (:func:`~slip_estimator.core.outputs.slip_estimate`)"""

    def wrong_at(self, s: float) -> float:
        """Probability that the published reading ``s`` is wrong: :attr:`p_wrong_departed`
        where it lies on the other side of 0.2 than the hold (medium or worse against a low
        hold, or the reverse: a change no alarm saw and no re-examination confirmed), else
        :attr:`p_wrong`."""
        if self.s_held is None or \
                (abs(s) > MEDIUM_LOWER_BOUND) == (abs(self.s_held) > MEDIUM_LOWER_BOUND):
            return self.p_wrong
        return self.p_wrong_departed


def resolution_var_mps2(change_mps: float) -> float:
    """Body-speed variance of a slip change below the step test's threshold ``change_mps``
    (m/s): uniform within ``+-change_mps``, ``change_mps^2 / 3``, m^2/s^2."""
    return change_mps * change_mps / 3.0


def mixture_std(s: float, s_std: float, eps: float, s_alt: float) -> float:
    """1-sigma of the mixture of :func:`p_medium_mixture` (``s`` with probability
    ``1 - eps``, ``s_alt`` with ``eps``, each +- ``s_std``), at most 1:
    ``sqrt(s_std^2 + eps (1 - eps) (s - s_alt)^2)``."""
    d = s - s_alt
    return min(1.0, math.sqrt(s_std * s_std + max(eps * (1.0 - eps), 0.0) * d * d))


def p_medium_mixture(s: float, s_std: float, eps: float, s_alt: float) -> float:
    """P(medium+) of a reading ``s`` (1-sigma ``s_std``) that is wrong with probability
    ``eps``, in which case the slip is ``s_alt`` (read as well): the mixture
    ``(1 - eps) P(s) + eps P(s_alt)`` of one-sided probabilities
    (:func:`~slip_estimator.core.slip.p_beyond_medium_bound`); NaN when ``s`` or ``s_std`` is."""
    if not (math.isfinite(s) and math.isfinite(s_std)):
        return float('nan')
    p = p_beyond_medium_bound(s, s_std)
    if eps <= 0.0:
        return p
    return (1.0 - eps) * p + eps * p_beyond_medium_bound(s_alt, s_std)


class ReadingRecord:
    """The slip model's re-examinations and the chain of readings the hold rests on, observed
    per wheel sample from the hold it publishes (see the module docstring)."""

    def __init__(self) -> None:
        self.n_reexamined = 0
        self.n_disagreed = 0
        self.chained = 0  # readings chained since the last anchor (a stop, the baseline)
        self._before: float | None = None  # the hold before the running measurement
        self._held: float | None = None

    def observe(self, held_slip: float | None, baseline: float | None, at_rest: bool) -> None:
        """One wheel sample: the slip model's hold (None while it measures or at rest), the
        ground's baseline (None before a stop measured it) and whether the model is at rest."""
        if at_rest:
            self.chained, self._before, self._held = 0, None, None
            return
        if held_slip is None:
            if self._held is not None:
                self._before = self._held  # an alarm: a measurement re-examines the hold
            self._held = None
            return
        if self._held is None:  # a measurement settled
            if self._before is None:  # from rest, a start in motion or a recovery
                self.chained = 0
            else:
                self.n_reexamined += 1
                self.n_disagreed += held_slip == self._before
                self.chained = 0 if held_slip == baseline else self.chained + 1
            self._before = None
        self._held = held_slip

    @property
    def eps(self) -> float:
        """Probability that one reading is wrong: the share of re-examinations that
        disagreed, with the prior of the module docstring."""
        return (self.n_disagreed + EPS_PRIOR_DISAGREED) / (self.n_reexamined + EPS_PRIOR_N)

    def confidence(self, held_slip: float | None, baseline: float | None,
                   change_mps: float, doubt: float = 0.0) -> Confidence:
        """The :class:`Confidence` of a sample published with the hold ``held_slip``, the
        ``baseline`` and the step test's threshold ``change_mps`` (call after
        :meth:`observe`); ``doubt``: the probability that the hold is the ground's baseline
        by a decision of the slip model's own (chained after a rejected run-ahead), on top of
        its readings' (:attr:`Confidence.doubted`)."""
        def wrong(departed: bool) -> float:
            p = self.wrong_probability(held_slip, baseline, departed)
            return 1.0 - (1.0 - p) * (1.0 - doubt)
        return Confidence(resolution_var_mps2(change_mps), wrong(False),
                          0.0 if baseline is None else baseline, held_slip, wrong(True),
                          doubt > 0.0)

    def wrong_probability(self, held_slip: float | None, baseline: float | None,
                          departed: bool = False) -> float:
        """Probability that the published reading is wrong: 0 on the baseline; otherwise
        ``1 - (1 - eps)^k`` for the ``k`` readings it rests on (at least the one running);
        ``departed``: a reading away from the hold is one reading more."""
        on_baseline = held_slip is not None and held_slip == baseline
        if on_baseline and not departed:
            return 0.0
        k = 0 if on_baseline else max(
            self.chained + (1 if held_slip is None and self._before is not None else 0), 1)
        return 1.0 - (1.0 - self.eps) ** (k + departed)
