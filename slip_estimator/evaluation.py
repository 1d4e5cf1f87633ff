"""Evaluation of slip, speed and trajectory estimates against truth (numpy only, array based).

Truth sources and what each metric rests on
-------------------------------------------
* **Simulation truth** (``/truth/slip``, ``/truth/odometry``): exact; every metric is valid.
* **GNSS truth, RTK grade** (Pathfinder test17run; mm-level at rest, 10 Hz): the forward speed
  ``v_xTR`` is the GNSS velocity (local linear fit of the ENU positions over a window,
  default 1.0 s = ~10 epochs, gaps tolerated) projected on the rover's body x axis, and
  ``s_TR`` follows from it and the wheel rim speed by the paper's eq. 30 (= eq. 1). By default
  the projection is on the GNSS track itself ('course': 3-D GNSS speed with the sign of the
  wheel rotation), so the truth does not depend on the estimate; it assumes no skid-steer crab
  (a 5 deg crab overstates v_x by 0.4 %, far below the 0.2 class step). Alternatively
  ('estimate') the GNSS velocity is projected on the body x axis of the *estimated* attitude
  (odometry orientation interpolated to the wheel time); that is exact for crab but inherits a
  diverged estimate's heading error. The result records which was used. Slip
  classification, speed RMSE, position error/drift and heading error are all meaningful.
  The wheel time offset (joint states lag the IMU/GNSS by ~0.1-0.2 s on Pathfinder) can be
  applied through ``wheel_time_offset_s``.
* **GNSS truth, single point** (s5t1; sigma ~2 m, jittery receive stamps): only coarse whole-run
  figures are valid - final position error, net displacement, trajectory shape. Per-sample
  speed and slip truth from it are noise; the functions still compute them when asked, and
  :func:`evaluate_run` flags them as invalid (``truth_quality='single_point'``).

Conventions: times are integer nanoseconds in the inputs (the ROS boundary) and seconds inside;
positions are in the odom frame (ENU axes, origin at the start); speeds in m/s; slip ratio per
eq. 1 in [-1, 1]; classes 0 none (not moving), 1 low, 2 medium, 3 high, 4 extreme, -1 unknown.
The confusion matrix has the layout of the paper's Table 2: rows = estimated class, columns =
truth class, percentages normalised per column.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from slip_estimator.core.slip import slip_class_array, slip_ratio_array
from slip_estimator.core.types import SLIP_CLASS_NAMES

N_CLASSES = len(SLIP_CLASS_NAMES)


# --------------------------------------------------------------------------------------------
# Slip maths (paper eq. 1 and 30)
# --------------------------------------------------------------------------------------------
# The slip maths is the core's (paper eq. 1; eq. 30 with GNSS truth speed), vectorised.
slip_ratio = slip_ratio_array
slip_class = slip_class_array


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


@dataclass(frozen=True)
class SlipResult:
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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (NaN -> None)."""
        return _jsonable(asdict(self))


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
class TrajectoryResult:
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

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return _jsonable(asdict(self))


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


def evaluate_slip(est_stamp_ns: np.ndarray, est_slip: np.ndarray, est_class: np.ndarray,
                  truth_stamp_ns: np.ndarray, truth_slip: np.ndarray, truth_class: np.ndarray,
                  tol_s: float = 0.05) -> SlipResult:
    """Compare an estimated slip series with a truth slip series.

    Every truth sample is matched to the nearest estimate within ``tol_s``; truth samples
    without one count as "unknown" (they lower coverage and the strict balanced accuracy).
    """
    est_stamp_ns = np.asarray(est_stamp_ns, dtype=np.int64)
    order = np.argsort(est_stamp_ns, kind='stable')
    est_stamp_ns = est_stamp_ns[order]
    est_slip = np.asarray(est_slip, dtype=float)[order]
    est_class = np.asarray(est_class, dtype=int)[order]
    truth_slip = np.asarray(truth_slip, dtype=float)
    truth_class = np.asarray(truth_class, dtype=int)
    idx = match_nearest(truth_stamp_ns, est_stamp_ns, round(tol_s * 1e9))
    matched = idx >= 0
    e_cls = np.where(matched, est_class[np.maximum(idx, 0)], -1) if len(est_class) else \
        np.full(len(truth_class), -1)
    matched_slip = np.where(matched, est_slip[np.maximum(idx, 0)], np.nan) if len(est_slip) else \
        np.full(len(truth_slip), np.nan)
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
    return SlipResult(counts, percent, n_truth, n_unknown, recall, balanced, balanced_strict,
                      coverage, float(precision), float(rec), float(f1), mae,
                      int(matched.sum()))


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


# --------------------------------------------------------------------------------------------
# GNSS truth (paper eq. 30)
# --------------------------------------------------------------------------------------------
def gnss_velocity_enu(gnss_t_s: np.ndarray, p_enu_m: np.ndarray, t_query_s: np.ndarray,
                      window_s: float = 1.0, min_fixes: int = 3) -> np.ndarray:
    """ENU velocity (m/s) at the query times by a local linear fit of the GNSS positions.

    A least-squares line through the fixes within ``+-window_s/2`` of each query time (lag-free
    for constant acceleration). On test17run the RTK position noise is ~2 mm at rest but ~1.3 cm
    while driving, so the speed noise (std of GNSS minus rim speed on the steady drive) is
    0.075 / 0.043 / 0.022 / 0.014 m/s for windows of 0.3 / 0.5 / 1 / 2 s; 1 s (slip noise
    ~0.03, well below the 0.2 class step, still resolving 1 Hz slip changes) is the default.
    Queries with fewer than ``min_fixes`` fixes, or whose fixes do not straddle the query time
    (a gap), give NaN: the record is aligned by time, never by index.
    """
    tg = np.asarray(gnss_t_s, dtype=float)
    p = np.asarray(p_enu_m, dtype=float)
    tq = np.asarray(t_query_s, dtype=float)
    out = np.full((len(tq), 3), np.nan)
    i0 = np.searchsorted(tg, tq - window_s / 2, side='left')
    i1 = np.searchsorted(tg, tq + window_s / 2, side='right')
    for k, (a, b) in enumerate(zip(i0, i1)):
        if b - a < min_fixes:
            continue
        dt = tg[a:b] - tq[k]
        if dt[0] > -0.25 * window_s or dt[-1] < 0.25 * window_s:
            continue
        A = np.column_stack([np.ones(b - a), dt])
        coef, *_ = np.linalg.lstsq(A, p[a:b], rcond=None)
        out[k] = coef[1]
    return out


def quat_wxyz_to_x_axis(q_wxyz: np.ndarray) -> np.ndarray:
    """First column of the rotation matrix of each quaternion: base_link x in odom (ENU)."""
    q = np.asarray(q_wxyz, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])


def quat_wxyz_to_yaw(q_wxyz: np.ndarray) -> np.ndarray:
    """ENU yaw (rad, counter-clockwise from east) of each quaternion."""
    ax = quat_wxyz_to_x_axis(q_wxyz)
    return np.arctan2(ax[:, 1], ax[:, 0])


@dataclass(frozen=True)
class GnssTruth:
    """Forward speed and slip truth from GNSS at the wheel sample times (paper eq. 30).

    Attributes
    ----------
    stamp_ns : wheel sample times, ns.
    v_forward_mps : truth forward speed ``v_xTR``, m/s (NaN where GNSS has a gap).
    v_rim_mps : rim speed r*omega used, m/s.
    s : truth slip ratio ``s_TR``; 0 when not moving; NaN where unknown.
    slip_class : truth class (0 not moving, 1..4, -1 unknown).
    projection : 'estimate' (body x axis of the estimated attitude) or 'course'.
    """

    stamp_ns: np.ndarray
    v_forward_mps: np.ndarray
    v_rim_mps: np.ndarray
    s: np.ndarray
    slip_class: np.ndarray
    projection: str


def gnss_slip_truth(wheel_stamp_ns: np.ndarray, v_rim_mps: np.ndarray, gnss_t_s: np.ndarray,
                    p_enu_m: np.ndarray, moving_threshold_mps: float = 0.02,
                    x_axis_enu: np.ndarray | None = None, window_s: float = 1.0,
                    wheel_time_offset_s: float = 0.0,
                    gnss_moving_threshold_mps: float = 0.1) -> GnssTruth:
    """Truth slip ``s_TR`` (eq. 30) from GNSS velocity and the wheel rim speed.

    ``x_axis_enu`` (N, 3): base_link x axis in ENU at each wheel time (from the estimated
    attitude); the GNSS velocity is projected on it. Without it the 3-D GNSS speed is
    used with the sign of the rim speed (course projection: assumes no crab). A wheel stamp
    ``t`` is compared with the GNSS velocity at ``t + wheel_time_offset_s`` (use a negative
    offset when the wheel stamps lag).

    Moving (class != 0) means rim speed above ``moving_threshold_mps`` or GNSS forward speed
    above ``gnss_moving_threshold_mps``: GNSS alone needs the higher threshold because RTK
    solutions jitter by 2-3 cm at rest (test17run 68-72 s, IMU still), i.e. ~0.1 m/s.
    """
    ts = np.asarray(wheel_stamp_ns, dtype=np.int64) * 1e-9 + wheel_time_offset_s
    v_rim = np.asarray(v_rim_mps, dtype=float)
    v_enu = gnss_velocity_enu(gnss_t_s, p_enu_m, ts, window_s)
    if x_axis_enu is not None:
        v_fwd = np.einsum('ij,ij->i', v_enu, np.asarray(x_axis_enu, dtype=float))
        projection = 'estimate'
    else:
        sign = np.where(v_rim < 0, -1.0, 1.0)
        v_fwd = sign * np.linalg.norm(v_enu, axis=1)
        projection = 'course'
    moving = (np.abs(v_rim) > moving_threshold_mps) | (np.abs(v_fwd) > gnss_moving_threshold_mps)
    s = np.where(moving, slip_ratio(v_fwd, v_rim), 0.0)
    s = np.where(np.isnan(v_fwd), np.nan, s)
    cls = np.where(np.isnan(v_fwd), -1, slip_class(s, moving))
    return GnssTruth(np.asarray(wheel_stamp_ns, dtype=np.int64), v_fwd, v_rim, s, cls,
                     projection)


# --------------------------------------------------------------------------------------------
# Whole run
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """Arrays extracted from an input bag and an estimator output bag (see report.load_run).

    Absent series are None. Times are ns; positions are odom ENU m; quaternions (w, x, y, z).
    """

    est_slip_stamp_ns: np.ndarray
    est_slip: np.ndarray
    est_slip_std: np.ndarray
    est_slip_class: np.ndarray
    est_body_speed_mps: np.ndarray
    est_wheel_speed_mps: np.ndarray
    est_odom_stamp_ns: np.ndarray | None = None
    est_odom_p_m: np.ndarray | None = None
    est_odom_q_wxyz: np.ndarray | None = None
    est_odom_v_mps: np.ndarray | None = None
    truth_slip_stamp_ns: np.ndarray | None = None
    truth_slip: np.ndarray | None = None
    truth_slip_class: np.ndarray | None = None
    truth_odom_stamp_ns: np.ndarray | None = None
    truth_odom_p_m: np.ndarray | None = None
    truth_odom_q_wxyz: np.ndarray | None = None
    truth_odom_v_mps: np.ndarray | None = None
    gnss_stamp_ns: np.ndarray | None = None
    gnss_llh: np.ndarray | None = None
    """(K, 3): latitude rad, longitude rad, ellipsoidal height m."""
    gnss_sigma_h_m: np.ndarray | None = None
    """(K,) horizontal 1-sigma from the NavSatFix covariance, m."""
    wheel_stamp_ns: np.ndarray | None = None
    wheel_rim_speed_mps: np.ndarray | None = None


@dataclass(frozen=True)
class RunEvaluation:
    """Everything :func:`evaluate_run` computed, with the truth it rests on.

    ``truth_source`` is 'simulation', 'gnss_rtk' or 'gnss_single_point'; ``valid`` lists which
    metric groups are meaningful with that truth.
    """

    truth_source: str
    slip: SlipResult | None
    speed: SpeedResult | None
    trajectory: TrajectoryResult | None
    valid: dict[str, bool]
    notes: tuple[str, ...] = field(default_factory=tuple)
    gnss_truth: GnssTruth | None = None
    truth_p_m: np.ndarray | None = None
    truth_stamp_ns: np.ndarray | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            'truth_source': self.truth_source, 'valid': dict(self.valid),
            'notes': list(self.notes),
            'gnss_projection': self.gnss_truth.projection if self.gnss_truth else None,
            'slip': self.slip.to_dict() if self.slip else None,
            'speed': self.speed.to_dict() if self.speed else None,
            'trajectory': self.trajectory.to_dict() if self.trajectory else None,
        }


def gnss_quality(sigma_h_m: np.ndarray | None, p_enu_m: np.ndarray | None = None,
                 rtk_sigma_m: float = 0.1) -> str:
    """'gnss_rtk' when the median horizontal sigma is below ``rtk_sigma_m``, else
    'gnss_single_point'."""
    if sigma_h_m is not None and np.isfinite(sigma_h_m).any() and np.nanmax(sigma_h_m) > 0:
        return 'gnss_rtk' if float(np.nanmedian(sigma_h_m)) < rtk_sigma_m else \
            'gnss_single_point'
    return 'gnss_single_point'


def _estimated_x_axis(run: RunData) -> np.ndarray | None:
    """The estimated body x axis (odom, unit vectors) at the slip stamps, interpolated from
    the estimated odometry; None without at least two odometry samples."""
    if run.est_odom_stamp_ns is None or len(run.est_odom_stamp_ns) <= 1:
        return None
    x_axes = quat_wxyz_to_x_axis(run.est_odom_q_wxyz)
    to = (run.est_odom_stamp_ns - run.est_odom_stamp_ns[0]) * 1e-9
    tw = (run.est_slip_stamp_ns - run.est_odom_stamp_ns[0]) * 1e-9
    x_axis = np.column_stack([np.interp(tw, to, x_axes[:, k]) for k in range(3)])
    return x_axis / np.linalg.norm(x_axis, axis=1, keepdims=True)


def evaluate_run(run: RunData, llh0: np.ndarray | None = None,
                 moving_threshold_mps: float = 0.02, tol_s: float = 0.05,
                 gnss_window_s: float = 1.0, wheel_time_offset_s: float = 0.0,
                 projection: str = 'course',
                 truth_source: str | None = None) -> RunEvaluation:
    """Evaluate a run against the best truth it carries (simulation truth, else GNSS).

    ``llh0`` (rad, rad, m) is the odom origin for the GNSS truth (default: the first fix);
    with ``align_origin`` the trajectory comparison is insensitive to it anyway.
    """
    from slip_estimator.core.planet import EARTH, llh_to_local_enu

    notes: list[str] = []
    gnss_truth = None
    slip = speed = traj = None
    truth_p = truth_t = None
    if run.truth_slip_stamp_ns is not None and len(run.truth_slip_stamp_ns):
        source = truth_source or 'simulation'
        slip = evaluate_slip(run.est_slip_stamp_ns, run.est_slip, run.est_slip_class,
                             run.truth_slip_stamp_ns, run.truth_slip, run.truth_slip_class, tol_s)
        if run.truth_odom_stamp_ns is not None and len(run.truth_odom_stamp_ns) > 1:
            speed = evaluate_speed(run.est_slip_stamp_ns, run.est_body_speed_mps,
                                   run.truth_odom_stamp_ns, run.truth_odom_v_mps[:, 0])
            truth_t, truth_p = run.truth_odom_stamp_ns, run.truth_odom_p_m
            if run.est_odom_stamp_ns is not None and len(run.est_odom_stamp_ns):
                traj = evaluate_trajectory(
                    run.est_odom_stamp_ns, run.est_odom_p_m, truth_t, truth_p,
                    quat_wxyz_to_yaw(run.est_odom_q_wxyz), quat_wxyz_to_yaw(
                        run.truth_odom_q_wxyz), 'odometry', align_origin=False)
        valid = {'slip': True, 'speed': speed is not None, 'trajectory': traj is not None,
                 'heading': traj is not None}
    elif run.gnss_stamp_ns is not None and len(run.gnss_stamp_ns) > 3:
        source = truth_source or gnss_quality(run.gnss_sigma_h_m)
        llh0 = run.gnss_llh[0] if llh0 is None else np.asarray(llh0, dtype=float)
        truth_p = np.array([llh_to_local_enu(EARTH, p, llh0) for p in run.gnss_llh])
        truth_t = run.gnss_stamp_ns
        tg = truth_t * 1e-9
        x_axis = _estimated_x_axis(run) if projection == 'estimate' else None
        v_rim = run.est_wheel_speed_mps
        if run.wheel_stamp_ns is not None and len(run.wheel_stamp_ns) > 1:
            idx = match_nearest(run.est_slip_stamp_ns, run.wheel_stamp_ns, int(tol_s * 1e9))
            v_rim = np.where(idx >= 0, run.wheel_rim_speed_mps[np.maximum(idx, 0)], v_rim)
            notes.append('rim speed for s_TR from the input /joint_states and the params radius')
        gnss_truth = gnss_slip_truth(run.est_slip_stamp_ns, v_rim, tg, truth_p,
                                     moving_threshold_mps, x_axis, gnss_window_s,
                                     wheel_time_offset_s)
        notes.append(f'GNSS forward speed projected on the {gnss_truth.projection} '
                     f'({"estimated body x axis" if x_axis is not None else "GNSS course"}), '
                     f'fit window {gnss_window_s} s, wheel time offset {wheel_time_offset_s} s')
        slip = evaluate_slip(run.est_slip_stamp_ns, run.est_slip, run.est_slip_class,
                             gnss_truth.stamp_ns, gnss_truth.s, gnss_truth.slip_class, tol_s)
        speed = evaluate_speed(run.est_slip_stamp_ns, run.est_body_speed_mps,
                               gnss_truth.stamp_ns, gnss_truth.v_forward_mps)
        if run.est_odom_stamp_ns is not None and len(run.est_odom_stamp_ns):
            v_enu = gnss_velocity_enu(tg, truth_p, tg, gnss_window_s)
            sp = np.linalg.norm(v_enu[:, :2], axis=1)
            course = np.where(sp > 0.1, np.arctan2(v_enu[:, 1], v_enu[:, 0]), np.nan)
            rtk = source == 'gnss_rtk'
            traj = evaluate_trajectory(
                run.est_odom_stamp_ns, run.est_odom_p_m, truth_t, truth_p,
                quat_wxyz_to_yaw(run.est_odom_q_wxyz), course, 'gnss_course',
                align_origin=True, distance_smooth_s=1.0 if rtk else 5.0)
        rtk = source == 'gnss_rtk'
        valid = {'slip': rtk, 'speed': rtk, 'trajectory': traj is not None,
                 'heading': rtk and traj is not None}
        if not rtk:
            notes.append('single-point GNSS: only the final position error and the shape of '
                         'the track are meaningful; slip/speed/heading figures are NOT valid')
        notes.append('heading truth = GNSS course while moving (> 0.1 m/s); it includes '
                     'skid-steer crab in turns')
    else:
        raise ValueError('no truth in the run: neither /truth/slip nor /gnss/fix')
    valid = follow_data(valid, notes, slip, speed)
    return RunEvaluation(source, slip, speed, traj, valid, tuple(notes), gnss_truth,
                         truth_p, truth_t)


SMALL_CLASS_SAMPLES = 30
"""A truth class with fewer matched samples than this is named in the notes: the balanced
accuracy (a mean of per-class recalls) rests on it as heavily as on a full class."""


def follow_data(valid: dict[str, bool], notes: list[str], slip: SlipResult | None,
                speed: SpeedResult | None) -> dict[str, bool]:
    """Validity that also follows the data: no slip figure is valid without a matched
    estimate/truth pair with both classes known, no speed figure without a compared sample;
    small truth classes are named in ``notes`` (appended)."""
    valid = dict(valid)
    if slip is not None and int(slip.counts.sum()) == 0:
        valid['slip'] = False
        notes.append(f'no estimate matched a truth sample with both classes known '
                     f'({slip.n_matched} matched in time): slip figures are NOT valid')
    if speed is not None and speed.n == 0:
        valid['speed'] = False
        notes.append('no estimate fell inside the speed truth: speed figures are NOT valid')
    if slip is not None and valid.get('slip'):
        small = [f'{SLIP_CLASS_NAMES[c]} {int(n)}' for c, n in enumerate(slip.n_truth)
                 if c >= 1 and 0 < n < SMALL_CLASS_SAMPLES]
        if small:
            notes.append('balanced accuracy rests on few samples in class(es): '
                         + ', '.join(small) + f' (fewer than {SMALL_CLASS_SAMPLES} each)')
    return valid


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
