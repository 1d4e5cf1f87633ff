"""The study's evidence figures (PNG, Agg backend, small), one function per figure."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.effects import TEST17RUN_WINDOWS
from slip_estimator.validation.configs import RTK_LOG
from slip_estimator.validation.study import Study

_COLORS = {'A': 'tab:red', 'B': 'tab:orange', 'C': 'tab:blue', 'D': 'tab:purple',
           'E': 'tab:brown', 'F': 'tab:green'}


def write_figures(study: Study, fig_dir: Path) -> dict[str, Path]:
    """The evidence figures (PNG, Agg backend, small). Returns name -> path."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    dpi = 80

    def save(fig: Any, name: str) -> None:
        files[name] = fig_dir / f'{name}.png'
        fig.tight_layout()
        fig.savefig(files[name], dpi=dpi)
        plt.close(fig)

    for figure in FIGURES:
        figure(study, plt, save)
    return files


def _velocity_error(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """Forward-velocity error vs time on test17run (effects B, C)."""
    plain = [study.get(k, RTK_LOG) for k in study.configs]
    plain = [r for r in plain if r is not None and 'odom_t' in r.series]
    if plain:
        fig, axs = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True)
        r0 = plain[0]
        axs[0].plot(r0.series['odom_t'], r0.series['gnss_v'], 'k-', lw=1.0, label='RTK speed')
        for r in plain:
            axs[0].plot(r.series['odom_t'], r.series['odom_v'], '-', lw=0.8,
                        color=_COLORS.get(r.config), label=f'{r.config} estimate')
            err = r.series['odom_v'] - r.series['gnss_v']
            err = np.where(r.series['gnss_v'] > 0.1, err, np.nan)
            axs[1].plot(r.series['odom_t'], err, '-', lw=0.8, color=_COLORS.get(r.config),
                        label=f'{r.config}: RMSE {r.metrics.get("v_rmse", np.nan):.3f} m/s')
        axs[0].set_ylabel('forward speed [m/s]')
        axs[0].legend(fontsize=7, ncol=3)
        axs[0].grid(True)
        axs[1].set_ylabel('v_est - v_RTK [m/s]')
        axs[1].set_xlabel('time since log start [s]')
        axs[1].set_ylim(-0.6, 0.6)
        axs[1].legend(fontsize=7, ncol=2)
        axs[1].grid(True)
        axs[0].set_title('test17run: forward speed vs RTK (driving only in the error plot)')
        save(fig, 'velocity_error_test17run')


def _wheel_latency(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """Wheel latency: cross-correlations and the lag over time."""
    fig, axs = plt.subplots(1, 3, figsize=(11, 3.2))
    for ax, key, title in ((axs[0], 'lag_curve', 'yaw rate: gyro vs wheel differential'),
                           (axs[1], 'accel_lag_curve', 'forward: Ax vs d(wheel rate)/dt')):
        for name, col in zip(study.logs, ('tab:blue', 'tab:orange')):
            if f'{key}_{name}' not in study.evidence:
                continue
            lags, cor = study.evidence[f'{key}_{name}']
            k = int(np.nanargmax(cor))
            ax.plot(lags, cor, '-', color=col, label=f'{name}: peak {lags[k]:+.3f} s')
            ax.plot(lags[k], cor[k], 'o', color=col)
        ax.axvline(0.0, color='0.6', lw=0.6)
        ax.set_xlabel('lag of wheel stamps behind IMU [s]')
        ax.set_ylabel('correlation')
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True)
    for name, col in zip(study.logs, ('tab:blue', 'tab:orange')):
        lt = study.evidence.get(f'lag_over_time_{name}')
        if lt is not None and len(lt['t']):
            axs[2].plot(lt['t'] + 15.0, lt['lag'], 'o-', color=col, ms=3,
                        label=f'{name} (r {np.min(lt["corr"]):.2f}-{np.max(lt["corr"]):.2f})')
    axs[2].set_xlabel('window centre [s] (30 s windows)')
    axs[2].set_ylabel('yaw-rate lag [s]')
    axs[2].set_title('lag over time', fontsize=9)
    axs[2].legend(fontsize=7)
    axs[2].grid(True)
    save(fig, 'wheel_latency_xcorr')


def _radius_ratio(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """Radius: GNSS speed / rim speed histogram."""
    if f'ratio_samples_{RTK_LOG}' in study.evidence:
        fig, ax = plt.subplots(figsize=(6, 3.2))
        ratios = study.evidence[f'ratio_samples_{RTK_LOG}']
        ax.hist(ratios, bins=np.arange(0.80, 1.12, 0.005), color='tab:green')
        ax.axvline(study.measured.gnss_over_rim, color='k', lw=1.2,
                   label=f'ratio of sums {study.measured.gnss_over_rim:.3f} -> r_eff '
                         f'{study.measured.wheel_radius_eff_m:.4f} m')
        ax.axvline(1.0, color='0.5', ls='--', lw=0.8, label='r = 0.12 m, zero slip')
        ax.set_xlabel(f'RTK speed / rim speed (r = {study.measured.wheel_radius_nominal_m} m), '
                      '1 s windows, > 0.3 m/s')
        ax.set_ylabel('windows')
        ax.legend(fontsize=7)
        ax.grid(True)
        save(fig, 'radius_ratio_test17run')


def _injected_slip(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """Injected slip: estimate vs truth (the configurations with a forward-speed aid)."""
    inj = [study.get(k, RTK_LOG, 'injected') for k in study.configs if k in 'BCD']
    inj = [r for r in inj if r is not None and 'slip_t' in r.series]
    if inj:
        fig, axs = plt.subplots(len(inj), 1, figsize=(8, 1.5 + 1.3 * len(inj)), sharex=True,
                                squeeze=False)
        for ax, r in zip(axs[:, 0], inj):
            ax.plot(r.series['slip_t'], r.series['slip_truth'], 'k-', lw=0.9, label='truth')
            ax.plot(r.series['slip_t'], r.series['slip_est'], '.', ms=2.5,
                    color=_COLORS.get(r.config), label=f'{r.config} estimate')
            for b in (0.2, 0.4, 0.7):
                ax.axhline(b, color='0.75', lw=0.5)
            for start, end, f in TEST17RUN_WINDOWS:
                ax.axvspan(start, end, color='0.92', zorder=0)
            ax.set_ylim(-0.3, 1.0)
            ax.set_ylabel('slip')
            ax.legend(fontsize=7, loc='upper right')
            ax.set_xlim(0, 60)
        axs[0, 0].set_title('test17run with injected wheel slip (grey: windows '
                            + ', '.join(f'x{f}' for _, _, f in TEST17RUN_WINDOWS) + ')')
        axs[-1, 0].set_xlabel('time since log start [s]')
        save(fig, 'injected_slip_test17run')


def _release(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """Release experiment: unaided INS speed error on real data."""
    rel = study.evidence.get('release')
    if rel is not None and len(rel['t']):
        fig, ax = plt.subplots(figsize=(7, 3.2))
        ax.plot(rel['t'], rel['aided'], 'o', ms=3.5, color='tab:blue',
                label=f'aided, 0.5 s before (std {np.std(rel["aided"]):.3f} m/s)')
        ax.plot(rel['t'], rel['change_early'], 's', ms=3.5, color='tab:orange',
                label=f'change 0-0.1 s after release (std {np.std(rel["change_early"]):.3f})')
        ax.plot(rel['t'], rel['change'], '^', ms=4, color='tab:red',
                label=f'change 0.25-0.85 s after (std {np.std(rel["change"]):.3f})')
        ax.axhline(0.0, color='0.5', lw=0.6)
        ax.set_xlabel('release time since log start [s]')
        ax.set_ylabel('speed error vs RTK [m/s]')
        ax.set_title('test17run: unaided INS forward-speed error after releasing the wheel aid',
                     fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True)
        save(fig, 'release_test17run')


def _trajectory_s5t1(study: Study, plt: Any, save: Callable[[Any, str], None]) -> None:
    """S5t1 trajectories (coarse: single-point GNSS)."""
    tr = [study.get(k, 's5t1') for k in study.configs]
    tr = [r for r in tr if r is not None and 'odom_p' in r.series]
    if tr:
        fig, ax = plt.subplots(figsize=(5.5, 5.0))
        p = tr[0].series['truth_p']
        tt = tr[0].series['truth_t']
        k = int(np.searchsorted(tt, tr[0].series['odom_t'][0]))
        p = p - p[min(k, len(p) - 1)] + tr[0].series['odom_p'][0]
        ax.plot(p[:, 0], p[:, 1], '.', color='0.4', ms=1.5, label='GNSS (single point)')
        for r in tr:
            ax.plot(r.series['odom_p'][:, 0], r.series['odom_p'][:, 1], '-', lw=1.0,
                    color=_COLORS.get(r.config),
                    label=f'{r.config}: final error {r.metrics.get("pos_final_m", np.nan):.1f} m')
        ax.axis('equal')
        ax.set_xlabel('east [m]')
        ax.set_ylabel('north [m]')
        ax.legend(fontsize=7)
        ax.grid(True)
        ax.set_title('s5t1 trajectory (odom frame)')
        save(fig, 'trajectory_s5t1')


FIGURES = (_velocity_error, _wheel_latency, _radius_ratio, _injected_slip, _release,
           _trajectory_s5t1)
"""Every figure function, in drawing order."""
