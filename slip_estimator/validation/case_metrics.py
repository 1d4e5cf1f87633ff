"""The figures of one evaluated validation case (:func:`study.run_case`): slip classes, the
odometry's forward speed against GNSS, trajectory and net displacement, and the slip read on
low-slip ground. Each takes the loaded run and its evaluation and returns (or adds to) plain
dicts of floats and arrays for the study's JSON."""
from __future__ import annotations

from typing import Any

import numpy as np

from slip_estimator.validation.configs import NS


def slip_class_metrics(s: Any) -> dict[str, float]:
    """The slip classification figures of an ``metrics.SlipResult``."""
    m = dict(balanced_accuracy=s.balanced_accuracy,
             balanced_accuracy_strict=s.balanced_accuracy_strict, coverage=s.coverage,
             sig_precision=s.significant_precision, sig_recall=s.significant_recall,
             sig_f1=s.significant_f1, slip_mae=s.slip_mae)
    for c in range(5):
        m[f'n_truth_{c}'] = float(s.n_truth[c] + s.n_unknown[c])
    m['recall_medium'], m['recall_high'] = float(s.recall[2]), float(s.recall[3])
    return m


def speed_metrics(run: Any, ev: Any, t0_ns: int, m: dict[str, float],
                   series: dict[str, np.ndarray]) -> None:
    """Forward speed of the odometry output against the GNSS speed at the same instants:
    independent of the wheel timing, so configurations with and without the latency model
    are compared on equal terms. Adds to ``m`` and ``series``."""
    from slip_estimator.metrics import evaluate_speed
    from slip_estimator.truth import gnss_velocity_enu

    tg = ev.truth_stamp_ns * 1e-9
    to = run.est_odom_stamp_ns * 1e-9
    v_g = np.linalg.norm(gnss_velocity_enu(tg, ev.truth_p_m, to), axis=1)
    v_o = run.est_odom_v_mps[:, 0]
    # Driving only: at rest the norm of the GNSS velocity is its jitter, not a speed.
    drv = v_g > 0.1
    sp = evaluate_speed(run.est_odom_stamp_ns[drv], v_o[drv], run.est_odom_stamp_ns[drv],
                        v_g[drv])
    m['v_rmse'] = sp.rmse
    m['v_mean_err'] = sp.mean
    m['v_err_max'] = sp.max_abs
    series.update(odom_t=(run.est_odom_stamp_ns - t0_ns) * 1e-9, odom_v=v_o,
                  gnss_v=v_g, odom_p=run.est_odom_p_m[:, :2], odom_q=run.est_odom_q_wxyz,
                  truth_p=ev.truth_p_m[:, :2], truth_t=(ev.truth_stamp_ns - t0_ns) * 1e-9)


def trajectory_metrics(run: Any, ev: Any) -> dict[str, float]:
    """Position, drift and heading figures, and the net displacement (start to end) of the
    estimate and of the GNSS: a coarse check that single-point GNSS supports (its error is a
    few metres against tens of metres)."""
    tr = ev.trajectory
    m = dict(pos_final_m=tr.final_error_m, pos_rms_m=tr.rms_error_m,
             distance_m=tr.distance_m, drift_pct=tr.drift_percent,
             heading_rms_deg=tr.heading_rms_deg, heading_final_deg=tr.heading_final_deg)
    if run.est_odom_p_m is not None and ev.truth_p_m is not None:
        te = run.est_odom_stamp_ns
        inside = (ev.truth_stamp_ns >= te[0]) & (ev.truth_stamp_ns <= te[-1])
        tp = ev.truth_p_m[inside]
        m['net_disp_est_m'] = float(np.linalg.norm(run.est_odom_p_m[-1, :2]
                                                   - run.est_odom_p_m[0, :2]))
        m['net_disp_gnss_m'] = float(np.linalg.norm(tp[-1, :2] - tp[0, :2]))
        m['path_len_est_m'] = float(np.sum(np.linalg.norm(
            np.diff(run.est_odom_p_m[:, :2], axis=0), axis=1)))
    return m


def low_slip_metrics(run: Any, gt: Any, t0_ns: int, m: dict[str, float],
                      series: dict[str, np.ndarray]) -> None:
    """The reported slip where the truth says low slip (its bias) and while driving; adds
    to ``m`` and ``series``."""
    from slip_estimator.metrics import match_nearest

    idx = match_nearest(gt.stamp_ns, run.est_slip_stamp_ns, int(0.05 * NS))
    es = np.where(idx >= 0, run.est_slip[np.maximum(idx, 0)], np.nan)
    low = (gt.slip_class == 1) & np.isfinite(es) & np.isfinite(gt.s)
    m['low_est_mean'] = float(np.mean(es[low])) if low.any() else float('nan')
    m['low_truth_mean'] = float(np.mean(gt.s[low])) if low.any() else float('nan')
    m['low_bias'] = float(np.mean(es[low] - gt.s[low])) if low.any() else float('nan')
    drive = np.isfinite(es) & (np.abs(gt.v_rim_mps) > 0.1)
    m['drive_est_mean'] = float(np.mean(es[drive])) if drive.any() else float('nan')
    series.update(slip_t=(gt.stamp_ns - t0_ns) * 1e-9, slip_est=es, slip_truth=gt.s)
