"""Figures of ``slip-estimator evaluate`` (matplotlib, Agg backend): trajectory, slip against
truth, forward-speed error histogram, slip-class confusion matrix."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.evaluation import RunData, RunEvaluation


def write_figures(run: RunData, ev: RunEvaluation, report_dir: Path) -> list[Path]:
    """Trajectory, slip vs truth over time, speed-error histogram, confusion matrix (PNG)."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    report_dir.mkdir(parents=True, exist_ok=True)
    files = []
    for name, draw in (('trajectory', _trajectory_figure), ('slip_vs_truth', _slip_vs_truth_figure),
                       ('velocity_error_hist', _velocity_error_hist_figure),
                       ('confusion_matrix', _confusion_matrix_figure)):
        fig = draw(run, ev, plt)
        files.append(report_dir / f'{name}.png')
        fig.savefig(files[-1], dpi=120)
        plt.close(fig)
    return files


def _trajectory_figure(run: RunData, ev: RunEvaluation, plt: Any) -> Any:
    """Estimated and true trajectory in the odom frame."""
    fig, ax = plt.subplots(figsize=(7, 7))
    if ev.truth_p_m is not None:
        tp = ev.truth_p_m
        if ev.truth_source.startswith('gnss') and run.est_odom_p_m is not None:
            # Same origin alignment as the metrics.
            k = int(np.searchsorted(ev.truth_stamp_ns, run.est_odom_stamp_ns[0]))
            k = min(k, len(tp) - 1)
            tp = tp - tp[k] + run.est_odom_p_m[0]
        ax.plot(tp[:, 0], tp[:, 1], 'k.-', ms=2, lw=0.8, label=f'truth ({ev.truth_source})')
    if run.est_odom_p_m is not None:
        ax.plot(run.est_odom_p_m[:, 0], run.est_odom_p_m[:, 1], 'r-', lw=1.2, label='estimate')
        ax.plot(*run.est_odom_p_m[0, :2], 'go', label='start')
    ax.set_xlabel('east [m]')
    ax.set_ylabel('north [m]')
    ax.axis('equal')
    ax.grid(True)
    ax.legend()
    ax.set_title('Trajectory (odom frame, ENU)')
    return fig


def _slip_vs_truth_figure(run: RunData, ev: RunEvaluation, plt: Any) -> Any:
    """Slip ratio and speeds over time, estimate against truth."""
    t0 = run.est_slip_stamp_ns[0] if len(run.est_slip_stamp_ns) else 0
    fig, axs = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    te = (run.est_slip_stamp_ns - t0) * 1e-9
    if ev.gnss_truth is not None:
        tt, st = (ev.gnss_truth.stamp_ns - t0) * 1e-9, ev.gnss_truth.s
        vt, vlab = ev.gnss_truth.v_forward_mps, 'GNSS v_xTR'
    elif run.truth_slip_stamp_ns is not None:
        tt, st = (run.truth_slip_stamp_ns - t0) * 1e-9, run.truth_slip
        vt = run.truth_odom_v_mps[:, 0] if run.truth_odom_v_mps is not None else None
        vlab = 'truth v_x'
    else:
        tt = st = vt = None
    if tt is not None:
        axs[0].plot(tt, st, 'k-', lw=0.8, label='truth')
    axs[0].plot(te, run.est_slip, 'r.', ms=2, label='estimate')
    for b in (0.2, 0.4, 0.7):
        for sgn in (1, -1):
            axs[0].axhline(sgn * b, color='0.7', lw=0.5)
    axs[0].set_ylabel('slip ratio')
    axs[0].set_ylim(-1.05, 1.05)
    axs[0].legend()
    axs[0].grid(True)
    axs[1].plot(te, run.est_body_speed_mps, 'r-', lw=0.8, label='estimated body speed')
    axs[1].plot(te, run.est_wheel_speed_mps, 'b-', lw=0.6, label='rim speed r*w')
    if vt is not None:
        tv = tt if ev.gnss_truth is not None else (run.truth_odom_stamp_ns - t0) * 1e-9
        axs[1].plot(tv, vt, 'k-', lw=0.8, label=vlab)
    axs[1].set_xlabel('time [s]')
    axs[1].set_ylabel('speed [m/s]')
    axs[1].legend()
    axs[1].grid(True)
    return fig


def _velocity_error_hist_figure(run: RunData, ev: RunEvaluation, plt: Any) -> Any:
    """Histogram of the forward-speed error."""
    fig, ax = plt.subplots(figsize=(6, 4))
    if ev.speed is not None and ev.speed.n:
        ax.hist(ev.speed.errors, bins=50, color='tab:blue')
        ax.set_title(f'forward-speed error: RMSE {ev.speed.rmse:.3f} m/s (n={ev.speed.n})')
    ax.set_xlabel('v_est - v_truth [m/s]')
    return fig


def _confusion_matrix_figure(run: RunData, ev: RunEvaluation, plt: Any) -> Any:
    """The slip confusion matrix, % of each truth class."""
    from slip_estimator.core.types import SLIP_CLASS_NAMES

    fig, ax = plt.subplots(figsize=(6, 5))
    if ev.slip is not None:
        pct = np.nan_to_num(ev.slip.percent)
        ax.imshow(pct, cmap='Blues', vmin=0, vmax=100)
        for e in range(pct.shape[0]):
            for t in range(pct.shape[1]):
                ax.text(t, e, f'{pct[e, t]:.1f}%\n({ev.slip.counts[e, t]})', ha='center',
                        va='center', fontsize=7, color='k' if pct[e, t] < 60 else 'w')
        ax.set_xticks(range(5), SLIP_CLASS_NAMES)
        ax.set_yticks(range(5), SLIP_CLASS_NAMES)
        ax.set_xlabel('truth class')
        ax.set_ylabel('estimated class')
        ax.set_title(f'balanced accuracy {ev.slip.balanced_accuracy:.3f}, '
                     f'coverage {ev.slip.coverage:.3f}')
    return fig


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------
