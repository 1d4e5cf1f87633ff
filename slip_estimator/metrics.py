"""Slip, speed and trajectory metrics of an estimate against a truth series (numpy only).

Which truth a metric may rest on, and when it is valid, is :mod:`slip_estimator.evaluation`'s
business; the truth series from GNSS are :mod:`slip_estimator.truth`'s.

Conventions: times are integer nanoseconds in the inputs (the ROS boundary) and seconds inside;
positions are in the odom frame (ENU axes, origin at the start); speeds in m/s; slip ratio per
eq. 1 in [-1, 1]; classes 0 none (not moving), 1 low, 2 medium, 3 high, 4 extreme, -1 unknown.
The confusion matrix has the layout of the paper's Table 2: rows = estimated class, columns =
truth class, percentages normalised per column.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from slip_estimator.core.types import SLIP_CLASS_NAMES

N_CLASSES = len(SLIP_CLASS_NAMES)


# --------------------------------------------------------------------------------------------
# Result records
# --------------------------------------------------------------------------------------------
def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return None if not math.isfinite(float(x)) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x


class _Record:
    """A result record whose fields are all JSON-ready through :func:`_jsonable`."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (NaN -> None)."""
        return _jsonable(asdict(self))


@dataclass(frozen=True)
class SlipResult(_Record):
    """Slip classification and slip-ratio accuracy on matched (estimate, truth) samples.

    Attributes
    ----------
    counts : 5x5 int, ``counts[est, truth]``; estimates with class -1 are not in it.
    percent : 5x5, column-normalised percent (NaN columns when a truth class is absent).
    n_truth : samples per truth class (covered ones, = column sums of ``counts``).
    n_unknown : per truth class, samples whose estimate is unknown or missing.
    recall : per class (diagonal of ``percent`` / 100), NaN when the class is absent.
    balanced_accuracy : mean recall over classes 1-4 present among moving truth samples
        (covered samples only).
    balanced_accuracy_strict : the same with unknown/missing estimates counted as misses.
    coverage : fraction of moving truth samples (class 1-4) with a known estimate.
    significant_precision, significant_recall, significant_f1 : detection of |s| > 0.2 on
        moving, covered samples (positive = class >= 2).
    slip_mae : mean |s_est - s_truth| on moving, covered samples.
    n_matched : truth samples with an estimate within the time tolerance.
    slip_z2_mean : mean of ``z^2 = ((s_est - s_truth) / sigma)^2`` over the moving, covered
        samples with a published 1-sigma (the slip's NEES: 1 when the sigma is honest, above
        when it is over-confident); NaN without sigmas. Against a GNSS truth it includes that
        truth's own error.
    slip_within_3sigma : share of those samples with ``|z| <= 3`` (0.997 for an honest
        Gaussian sigma).
    slip_within_2sigma : the same with ``|z| <= 2`` (0.954 for an honest Gaussian sigma).
    p_medium_precision : of the moving, covered samples published with a probability of
        medium-or-worse slip of at least ``P_MEDIUM_CONFIDENT``, the share whose truth is
        medium or worse; NaN without probabilities or without such samples.
    n_p_medium_confident : how many samples that share is of.
    """

    counts: np.ndarray
    percent: np.ndarray
    n_truth: np.ndarray
    n_unknown: np.ndarray
    recall: np.ndarray
    balanced_accuracy: float
    balanced_accuracy_strict: float
    coverage: float
    significant_precision: float
    significant_recall: float
    significant_f1: float
    slip_mae: float
    n_matched: int
    slip_z2_mean: float = float('nan')
    slip_within_3sigma: float = float('nan')
    slip_within_2sigma: float = float('nan')
    p_medium_precision: float = float('nan')
    n_p_medium_confident: int = 0


@dataclass(frozen=True)
class SpeedResult:
    """Forward-speed errors ``v_est - v_truth`` (m/s) at the estimate times inside the truth."""

    errors: np.ndarray
    rmse: float
    mean: float
    max_abs: float
    n: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping without the error array."""
        return _jsonable({k: v for k, v in asdict(self).items() if k != 'errors'})


@dataclass(frozen=True)
class TrajectoryResult(_Record):
    """Position and heading errors of an estimated trajectory.

    Attributes
    ----------
    final_error_m : horizontal position error at the last common time, m.
    rms_error_m : RMS horizontal position error over the common times, m.
    final_error_3d_m, rms_error_3d_m : the same in 3-D.
    distance_m : truth distance travelled (horizontal path length of the truth, smoothed), m.
    drift_percent : ``100 * final_error_m / distance_m``.
    heading_rms_deg, heading_final_deg : heading error (est - truth), deg; NaN without headings.
    heading_truth : 'odometry' (orientation truth) or 'gnss_course' (course while moving) or ''.
    """

    final_error_m: float
    rms_error_m: float
    final_error_3d_m: float
    rms_error_3d_m: float
    distance_m: float
    drift_percent: float
    heading_rms_deg: float
    heading_final_deg: float
    heading_truth: str


# --------------------------------------------------------------------------------------------
# Matching and core metrics
# --------------------------------------------------------------------------------------------
def match_nearest(t_query_ns: np.ndarray, t_ref_ns: np.ndarray, tol_ns: int) -> np.ndarray:
    """Index into sorted ``t_ref_ns`` of the nearest sample to each query, -1 beyond ``tol_ns``."""
    t_query_ns = np.asarray(t_query_ns, dtype=np.int64)
    t_ref_ns = np.asarray(t_ref_ns, dtype=np.int64)
    if len(t_ref_ns) == 0:
        return np.full(len(t_query_ns), -1)
    j = np.clip(np.searchsorted(t_ref_ns, t_query_ns), 1, max(len(t_ref_ns) - 1, 1))
    j0 = np.clip(j - 1, 0, len(t_ref_ns) - 1)
    j1 = np.clip(j, 0, len(t_ref_ns) - 1)
    pick = np.where(np.abs(t_ref_ns[j1] - t_query_ns) < np.abs(t_ref_ns[j0] - t_query_ns), j1, j0)
    return np.where(np.abs(t_ref_ns[pick] - t_query_ns) <= tol_ns, pick, -1)


def confusion_matrix(est_class: np.ndarray, truth_class: np.ndarray) -> tuple[np.ndarray,
                                                                               np.ndarray]:
    """Counts ``[est, truth]`` and column-normalised percent (paper Table 2 layout).

    Pairs with an unknown (negative) estimated or truth class are left out.
    """
    e = np.asarray(est_class, dtype=int)
    t = np.asarray(truth_class, dtype=int)
    ok = (e >= 0) & (t >= 0)
    counts = np.zeros((N_CLASSES, N_CLASSES), dtype=int)
    np.add.at(counts, (e[ok], t[ok]), 1)
    col = counts.sum(axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        percent = 100.0 * counts / np.where(col > 0, col, np.nan)
    return counts, percent


P_MEDIUM_CONFIDENT = 0.8
"""A published probability of medium-or-worse slip from which a planner would act on it."""


def evaluate_slip(est_stamp_ns: np.ndarray, est_slip: np.ndarray, est_class: np.ndarray,
                  truth_stamp_ns: np.ndarray, truth_slip: np.ndarray, truth_class: np.ndarray,
                  tol_s: float = 0.05, est_slip_std: np.ndarray | None = None,
                  est_p_medium: np.ndarray | None = None) -> SlipResult:
    """Compare an estimated slip series (and its published 1-sigma ``est_slip_std`` and
    probability of medium-or-worse slip ``est_p_medium``, if given) with a truth slip series.

    Every truth sample is matched to the nearest estimate within ``tol_s``; truth samples
    without one count as "unknown" (they lower coverage and the strict balanced accuracy).
    """
    est_stamp_ns = np.asarray(est_stamp_ns, dtype=np.int64)
    order = np.argsort(est_stamp_ns, kind='stable')
    est_stamp_ns = est_stamp_ns[order]
    est_slip = np.asarray(est_slip, dtype=float)[order]
    est_class = np.asarray(est_class, dtype=int)[order]
    est_std = (np.full(len(est_slip), np.nan) if est_slip_std is None
               else np.asarray(est_slip_std, dtype=float)[order])
    est_p = (np.full(len(est_slip), np.nan) if est_p_medium is None
             else np.asarray(est_p_medium, dtype=float)[order])
    truth_slip = np.asarray(truth_slip, dtype=float)
    truth_class = np.asarray(truth_class, dtype=int)
    idx = match_nearest(truth_stamp_ns, est_stamp_ns, round(tol_s * 1e9))
    matched = idx >= 0

    def at_match(values: np.ndarray, fill: float) -> np.ndarray:
        """The estimate matched to each truth sample, ``fill`` where none is."""
        if not len(values):
            return np.full(len(truth_class), fill)
        return np.where(matched, values[np.maximum(idx, 0)], fill)

    e_cls = at_match(est_class, -1)
    matched_slip = at_match(est_slip, np.nan)
    valid_truth = truth_class >= 0
    counts, percent = confusion_matrix(e_cls, truth_class)
    n_truth = counts.sum(axis=0)
    n_unknown = np.array([np.sum(valid_truth & (truth_class == c) & (e_cls < 0))
                          for c in range(N_CLASSES)])
    recall = np.diag(percent) / 100.0
    moving_classes = [c for c in range(1, N_CLASSES) if n_truth[c] > 0]
    balanced = float(np.mean(recall[moving_classes])) if moving_classes else float('nan')
    strict_classes = [c for c in range(1, N_CLASSES) if n_truth[c] + n_unknown[c] > 0]
    balanced_strict = (float(np.mean([counts[c, c] / (n_truth[c] + n_unknown[c])
                                      for c in strict_classes]))
                       if strict_classes else float('nan'))
    moving = truth_class >= 1
    covered = moving & (e_cls >= 0)
    coverage = float(covered.sum() / moving.sum()) if moving.any() else float('nan')
    truth_pos = truth_class >= 2
    est_pos = e_cls >= 2
    tp = int(np.sum(covered & truth_pos & est_pos))
    fp = int(np.sum(covered & ~truth_pos & est_pos))
    fn = int(np.sum(covered & truth_pos & ~est_pos))
    precision = tp / (tp + fp) if tp + fp > 0 else float('nan')
    rec = tp / (tp + fn) if tp + fn > 0 else float('nan')
    f1 = (2 * precision * rec / (precision + rec)
          if tp > 0 else (0.0 if (fp + fn) > 0 else float('nan')))
    scored = covered & np.isfinite(matched_slip) & np.isfinite(truth_slip)
    err = np.abs(matched_slip - truth_slip)[scored]
    mae = float(err.mean()) if err.size else float('nan')
    std = at_match(est_std, np.nan)
    sigma_ok = scored & np.isfinite(std) & (std > 0.0)
    z = (matched_slip - truth_slip)[sigma_ok] / std[sigma_ok]
    z2_mean = float(np.mean(z * z)) if z.size else float('nan')
    within = float(np.mean(np.abs(z) <= 3.0)) if z.size else float('nan')
    within2 = float(np.mean(np.abs(z) <= 2.0)) if z.size else float('nan')
    confident = covered & (at_match(est_p, np.nan) >= P_MEDIUM_CONFIDENT)
    n_conf = int(confident.sum())
    p_precision = float(np.mean(truth_pos[confident])) if n_conf else float('nan')
    return SlipResult(counts, percent, n_truth, n_unknown, recall, balanced, balanced_strict,
                      coverage, float(precision), float(rec), float(f1), mae,
                      int(matched.sum()), z2_mean, within, within2, p_precision, n_conf)


def evaluate_speed(est_stamp_ns: np.ndarray, est_v_mps: np.ndarray, truth_stamp_ns: np.ndarray,
                   truth_v_mps: np.ndarray, max_gap_s: float = 0.5) -> SpeedResult:
    """Forward-speed errors: truth linearly interpolated to the estimate times.

    Estimates outside the truth span, next to a truth gap longer than ``max_gap_s`` or with a
    NaN on either side are skipped.
    """
    te = np.asarray(est_stamp_ns, dtype=np.int64)
    tt = np.asarray(truth_stamp_ns, dtype=np.int64)
    ve = np.asarray(est_v_mps, dtype=float)
    vt = np.asarray(truth_v_mps, dtype=float)
    if len(tt) < 2 or len(te) == 0:
        return SpeedResult(np.zeros(0), float('nan'), float('nan'), float('nan'), 0)
    order = np.argsort(tt)
    tt, vt = tt[order], vt[order]
    x = (te - tt[0]) * 1e-9
    xt = (tt - tt[0]) * 1e-9
    v_interp = np.interp(x, xt, vt)
    j = np.clip(np.searchsorted(xt, x), 1, len(xt) - 1)
    ok = (x >= 0) & (x <= xt[-1]) & ((xt[j] - xt[j - 1]) <= max_gap_s + 1e-6)
    err = (ve - v_interp)[ok]
    err = err[np.isfinite(err)]
    if err.size == 0:
        return SpeedResult(err, float('nan'), float('nan'), float('nan'), 0)
    return SpeedResult(err, float(np.sqrt(np.mean(err ** 2))), float(err.mean()),
                       float(np.abs(err).max()), int(err.size))


def wrap_deg(a: np.ndarray | float) -> np.ndarray:
    """Angle wrapped to (-180, 180] deg."""
    return -((-np.asarray(a, dtype=float) + 180.0) % 360.0 - 180.0)


def path_length(p_m: np.ndarray, t_s: np.ndarray | None = None, smooth_s: float = 0.0) -> float:
    """Horizontal path length of a position track, m; optionally smoothed (moving average over
    ``smooth_s``) first so that GNSS noise does not inflate it."""
    p = np.asarray(p_m, dtype=float)[:, :2]
    if smooth_s > 0 and t_s is not None and len(p) > 2:
        t = np.asarray(t_s, dtype=float)
        c = np.vstack([np.zeros((1, 2)), np.cumsum(p, axis=0)])
        i0 = np.searchsorted(t, t - smooth_s / 2)
        i1 = np.searchsorted(t, t + smooth_s / 2, side='right')
        p = (c[i1] - c[i0]) / (i1 - i0)[:, None]
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


def evaluate_trajectory(est_stamp_ns: np.ndarray, est_p_m: np.ndarray,
                        truth_stamp_ns: np.ndarray, truth_p_m: np.ndarray,
                        est_yaw_rad: np.ndarray | None = None,
                        truth_yaw_rad: np.ndarray | None = None, heading_truth: str = '',
                        align_origin: bool = True, distance_smooth_s: float = 0.0,
                        max_gap_s: float = 1.0) -> TrajectoryResult:
    """Position error (final, RMS), drift in % of distance travelled and heading error.

    The truth is linearly interpolated to the estimate times. With ``align_origin`` the truth
    is shifted so that it starts where the estimate starts (no rotation is fitted: a heading
    initialisation error is part of the error, as for a dead-reckoning system). Yaws are ENU
    yaw angles (rad, counter-clockwise from east); a NaN truth yaw (e.g. GNSS course at rest)
    is skipped.
    """
    te = np.asarray(est_stamp_ns, dtype=np.int64)
    tt = np.asarray(truth_stamp_ns, dtype=np.int64)
    pe = np.asarray(est_p_m, dtype=float)
    pt = np.asarray(truth_p_m, dtype=float)
    order = np.argsort(tt)
    tt, pt = tt[order], pt[order]
    base = tt[0]
    x, xt = (te - base) * 1e-9, (tt - base) * 1e-9
    j = np.clip(np.searchsorted(xt, x), 1, len(xt) - 1)
    ok = (x >= xt[0]) & (x <= xt[-1]) & ((xt[j] - xt[j - 1]) <= max_gap_s + 1e-6)
    nan = float('nan')
    if not ok.any():
        return TrajectoryResult(nan, nan, nan, nan, nan, nan, nan, nan, heading_truth)
    pti = np.column_stack([np.interp(x[ok], xt, pt[:, k]) for k in range(3)])
    pei = pe[ok]
    if align_origin:
        pti = pti - pti[0] + pei[0]
    d = pei - pti
    h = np.linalg.norm(d[:, :2], axis=1)
    d3 = np.linalg.norm(d, axis=1)
    span = (xt >= x[ok][0]) & (xt <= x[ok][-1])
    dist = path_length(pt[span], xt[span], distance_smooth_s)
    drift = 100.0 * h[-1] / dist if dist > 0 else nan
    h_rms = h_fin = nan
    if est_yaw_rad is not None and truth_yaw_rad is not None:
        yt = np.asarray(truth_yaw_rad, dtype=float)[order]
        # Interpolate the unwrapped truth yaw where it is defined.
        good = np.isfinite(yt)
        if good.sum() >= 2:
            yu = np.unwrap(yt[good])
            yti = np.interp(x[ok], xt[good], yu)
            xg = xt[good]
            k = np.clip(np.searchsorted(xg, x[ok]), 1, len(xg) - 1)
            near = np.minimum(np.abs(xg[k] - x[ok]), np.abs(xg[k - 1] - x[ok])) <= max_gap_s
            err = wrap_deg(np.degrees(np.asarray(est_yaw_rad, dtype=float)[ok] - yti))[near]
            err = err[np.isfinite(err)]
            if err.size:
                h_rms, h_fin = float(np.sqrt(np.mean(err ** 2))), float(err[-1])
    return TrajectoryResult(float(h[-1]), float(np.sqrt(np.mean(h ** 2))), float(d3[-1]),
                            float(np.sqrt(np.mean(d3 ** 2))), dist, drift, h_rms, h_fin,
                            heading_truth)



def format_confusion(result: SlipResult) -> str:
    """The confusion matrix as text, paper Table 2 layout (rows estimated, columns truth)."""
    head = 'est \\ truth ' + ''.join(f'{n:>10s}' for n in SLIP_CLASS_NAMES)
    lines = [head]
    for e in range(N_CLASSES):
        cells = ''.join('       n/a' if not np.isfinite(result.percent[e, t])
                        else f'{result.percent[e, t]:9.1f}%' for t in range(N_CLASSES))
        lines.append(f'{SLIP_CLASS_NAMES[e]:>12s}' + cells)
    lines.append(f'{"# data":>12s}' + ''.join(f'{n:10d}' for n in result.n_truth))
    lines.append(f'{"# unknown":>12s}' + ''.join(f'{n:10d}' for n in result.n_unknown))
    return '\n'.join(lines)
