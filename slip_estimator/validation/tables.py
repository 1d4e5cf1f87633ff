"""Cells, tables and metric look-ups of the validation report (:mod:`.markdown`).

:func:`fmt` formats one number ('n/a' when missing or not finite), :func:`md_table` builds a
Markdown table, :func:`slip_table` / :func:`nav_table` / :func:`window_table` are the
per-configuration tables, and :func:`metric_of` / :func:`delta` / :func:`changes` read and
compare one metric between configurations.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from slip_estimator.effects import TEST17RUN_WINDOWS
from slip_estimator.validation.configs import CONFIG_BY_KEY, RTK_LOG
from slip_estimator.validation.study import Study


def fmt(x: Any, d: int = 3, unit: str = '') -> str:
    """``x`` with ``d`` decimals and ``unit``; 'n/a' when missing, not a number or not finite."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return 'n/a'
    return 'n/a' if not math.isfinite(v) else f'{v:.{d}f}{unit}'


def md_table(head: list[str], rows: list[list[str]]) -> list[str]:
    """The lines of a Markdown table: header, separator, one line per row."""
    out = ['| ' + ' | '.join(head) + ' |', '|' + '|'.join('---' for _ in head) + '|']
    out += ['| ' + ' | '.join(r) + ' |' for r in rows]
    return out


def config_label(key: str) -> str:
    """'<key> <label>' of a configuration, the first cell of a table row."""
    return f'{key} {CONFIG_BY_KEY[key].label}'


def slip_table(study: Study, log: str, variant: str) -> list[str]:
    """Slip classification metrics, one row per configuration."""
    head = ['config', 'bal. acc.', 'recall low', 'med', 'high', 'extr', 'coverage',
            'sig. P', 'sig. R', 'sig. F1', 'slip MAE', 'low: est / truth (bias)']
    rows = []
    for k, r in study.present(log, variant):
        m = r.metrics
        rows.append([config_label(k), fmt(m.get('balanced_accuracy')),
                     *[fmt(x, 2) for x in r.recall[1:5]], fmt(m.get('coverage'), 2),
                     fmt(m.get('sig_precision'), 2), fmt(m.get('sig_recall'), 2),
                     fmt(m.get('sig_f1'), 2), fmt(m.get('slip_mae')),
                     (f'{fmt(m.get("low_est_mean"))} / {fmt(m.get("low_truth_mean"))} '
                     f'({fmt(m.get("low_bias"), 3)})')])
    return md_table(head, rows)


def nav_table(study: Study, log: str, variant: str, coarse: bool = False) -> list[str]:
    """Navigation and residual metrics, one row per configuration."""
    if coarse:
        head = ['config', 'final pos. err. [m]', 'drift [% dist.]', 'net disp. est / GNSS [m]',
                'path length est [m]', 'mean slip driving', 'NIS zupt', 'NIS zaru', 'NIS nhc',
                'NIS wheel', 'div. resets', 'recoveries']
    else:
        head = ['config', 'v RMSE [m/s]', 'v mean err', 'max abs v err', 'final pos. err. [m]',
                'drift [%]',
                'heading RMS [deg]', 'NIS zupt', 'NIS zaru', 'NIS nhc', 'NIS wheel',
                'div. resets', 'recoveries']
    rows = []
    for k, r in study.present(log, variant):
        m = r.metrics
        resid = [fmt(m.get('nis_zupt'), 2), fmt(m.get('nis_zaru'), 2), fmt(m.get('nis_nhc'), 2),
                 fmt(m.get('nis_wheel'), 2), fmt(m.get('n_divergence_resets'), 0),
                 fmt(m.get('n_recoveries'), 0)]
        if coarse:
            rows.append([config_label(k), fmt(m.get('pos_final_m'), 2), fmt(m.get('drift_pct'), 2),
                         f'{fmt(m.get("net_disp_est_m"), 1)} / {fmt(m.get("net_disp_gnss_m"), 1)}',
                         fmt(m.get('path_len_est_m'), 1), fmt(m.get('drive_est_mean'), 3),
                         *resid])
        else:
            rows.append([config_label(k), fmt(m.get('v_rmse')), fmt(m.get('v_mean_err')),
                         fmt(m.get('v_err_max'), 2),
                         fmt(m.get('pos_final_m'), 2), fmt(m.get('drift_pct'), 2),
                         fmt(m.get('heading_rms_deg'), 2), *resid])
    return md_table(head, rows)


def window_table(study: Study) -> list[str]:
    head = ['config'] + [f'x{f} ({a:.0f}-{b:.0f} s): est / truth' for a, b, f in
                         TEST17RUN_WINDOWS] + ['outside windows, driving: est / truth']
    rows = []
    for k, r in study.present(RTK_LOG, 'injected'):
        if 'slip_t' not in r.series:
            continue
        t, e, tr = r.series['slip_t'], r.series['slip_est'], r.series['slip_truth']
        cells = [config_label(k)]
        outside = np.isfinite(e) & np.isfinite(tr) & (t > 8.0) & (t < 50.0)
        for a, b, _f_ in TEST17RUN_WINDOWS:
            # Skip the first 2 s of a window: the estimator needs slip_measure_s to see it.
            w = np.isfinite(e) & np.isfinite(tr) & (t >= a + 2.0) & (t < b)
            outside &= ~((t >= a - 0.5) & (t < b + 1.0))
            cells.append(f'{fmt(np.median(e[w]) if w.any() else np.nan, 2)} / '
                         f'{fmt(np.median(tr[w]) if w.any() else np.nan, 2)}')
        cells.append(f'{fmt(np.median(e[outside]) if outside.any() else np.nan, 3)} / '
                     f'{fmt(np.median(tr[outside]) if outside.any() else np.nan, 3)}')
        rows.append(cells)
    return md_table(head, rows)


def metric_of(study: Study, config: str, log: str, key: str, variant: str = 'plain') -> float:
    r = study.get(config, log, variant)
    return r.metrics.get(key, float('nan')) if r is not None else float('nan')


def delta(study: Study, a: str, b: str, metric: str, log: str = RTK_LOG,
          variant: str = 'plain', d: int = 3) -> str:
    ra, rb = study.get(a, log, variant), study.get(b, log, variant)
    if ra is None or rb is None:
        return 'n/a'
    return f'{fmt(ra.metrics.get(metric), d)} -> {fmt(rb.metrics.get(metric), d)}'


def changes(study: Study, a: str, b: str, *items: tuple, log: str = RTK_LOG,
            variant: str = 'plain') -> str:
    """'label a -> b unit, ...' for items (label, metric[, unit[, digits]])."""
    out = []
    for label, metric, *rest in items:
        unit = rest[0] if rest else ''
        d = rest[1] if len(rest) > 1 else 3
        out.append(f'{label} {delta(study, a, b, metric, log, variant, d)}{unit}')
    return ', '.join(out)
