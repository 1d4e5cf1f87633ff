"""The report: ``docs/validation.md`` rendered from a :class:`~.study.Study`.

:data:`TEMPLATE` is the page; each ``{name}`` line is filled by the section function of that
name in :data:`SECTIONS`, which reads every number from the study (none is typed in here).
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.effects import TEST17RUN_WINDOWS
from slip_estimator.validation.configs import COMMAND, CONFIG_BY_KEY, RTK_LOG
from slip_estimator.validation.study import Study


def _f(x: Any, d: int = 3, unit: str = '') -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return 'n/a'
    return 'n/a' if not math.isfinite(v) else f'{v:.{d}f}{unit}'


def _table(head: list[str], rows: list[list[str]]) -> list[str]:
    out = ['| ' + ' | '.join(head) + ' |', '|' + '|'.join('---' for _ in head) + '|']
    out += ['| ' + ' | '.join(r) + ' |' for r in rows]
    return out


def _code_state() -> str:
    """Git HEAD of the repository and whether production files differ from it (the study
    measures the working tree, which may hold uncommitted changes)."""
    import subprocess

    repo = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=repo, text=True,
                              capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(['git', 'status', '--porcelain', '--', 'slip_estimator'],
                               cwd=repo, text=True, capture_output=True,
                               check=True).stdout.split('\n')
    except (OSError, subprocess.CalledProcessError):
        return 'not a git checkout'
    changed = sorted(f for f in {ln[3:] for ln in dirty if ln.strip()}
                     if not f.startswith('slip_estimator/validation/'))
    return f'commit {head}' + (f' + uncommitted changes in {", ".join(changed)}' if changed
                               else ' (production code clean)')


def _label(key: str) -> str:
    return f'{key} {CONFIG_BY_KEY[key].label}'


def slip_table(study: Study, log: str, variant: str) -> list[str]:
    """Slip classification metrics, one row per configuration."""
    head = ['config', 'bal. acc.', 'recall low', 'med', 'high', 'extr', 'coverage',
            'sig. P', 'sig. R', 'sig. F1', 'slip MAE', 'low: est / truth (bias)']
    rows = []
    for k, r in study.present(log, variant):
        m = r.metrics
        rows.append([_label(k), _f(m.get('balanced_accuracy')),
                     *[_f(x, 2) for x in r.recall[1:5]], _f(m.get('coverage'), 2),
                     _f(m.get('sig_precision'), 2), _f(m.get('sig_recall'), 2),
                     _f(m.get('sig_f1'), 2), _f(m.get('slip_mae')),
                     (f'{_f(m.get("low_est_mean"))} / {_f(m.get("low_truth_mean"))} '
                     f'({_f(m.get("low_bias"), 3)})')])
    return _table(head, rows)


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
        resid = [_f(m.get('nis_zupt'), 2), _f(m.get('nis_zaru'), 2), _f(m.get('nis_nhc'), 2),
                 _f(m.get('nis_wheel'), 2), _f(m.get('n_divergence_resets'), 0),
                 _f(m.get('n_recoveries'), 0)]
        if coarse:
            rows.append([_label(k), _f(m.get('pos_final_m'), 2), _f(m.get('drift_pct'), 2),
                         f'{_f(m.get("net_disp_est_m"), 1)} / {_f(m.get("net_disp_gnss_m"), 1)}',
                         _f(m.get('path_len_est_m'), 1), _f(m.get('drive_est_mean'), 3),
                         *resid])
        else:
            rows.append([_label(k), _f(m.get('v_rmse')), _f(m.get('v_mean_err')),
                         _f(m.get('v_err_max'), 2),
                         _f(m.get('pos_final_m'), 2), _f(m.get('drift_pct'), 2),
                         _f(m.get('heading_rms_deg'), 2), *resid])
    return _table(head, rows)


def _window_table(study: Study) -> list[str]:
    head = ['config'] + [f'x{f} ({a:.0f}-{b:.0f} s): est / truth' for a, b, f in
                         TEST17RUN_WINDOWS] + ['outside windows, driving: est / truth']
    rows = []
    for k, r in study.present(RTK_LOG, 'injected'):
        if 'slip_t' not in r.series:
            continue
        t, e, tr = r.series['slip_t'], r.series['slip_est'], r.series['slip_truth']
        cells = [_label(k)]
        outside = np.isfinite(e) & np.isfinite(tr) & (t > 8.0) & (t < 50.0)
        for a, b, _f_ in TEST17RUN_WINDOWS:
            # Skip the first 2 s of a window: the estimator needs slip_measure_s to see it.
            w = np.isfinite(e) & np.isfinite(tr) & (t >= a + 2.0) & (t < b)
            outside &= ~((t >= a - 0.5) & (t < b + 1.0))
            cells.append(f'{_f(np.median(e[w]) if w.any() else np.nan, 2)} / '
                         f'{_f(np.median(tr[w]) if w.any() else np.nan, 2)}')
        cells.append(f'{_f(np.median(e[outside]) if outside.any() else np.nan, 3)} / '
                     f'{_f(np.median(tr[outside]) if outside.any() else np.nan, 3)}')
        rows.append(cells)
    return _table(head, rows)


def _m(study: Study, config: str, log: str, key: str, variant: str = 'plain') -> float:
    r = study.get(config, log, variant)
    return r.metrics.get(key, float('nan')) if r is not None else float('nan')


S5T1_NOISE_M = 3.0
"""s5t1 final-position differences below this are within its single-point GNSS noise
(reported sigma 2.6 / 1.6 m horizontal)."""
SEVERAL = 2.0
"""A NIS mean this many times its degrees of freedom is "several times its expectation"."""
NIS_DOF = {'zupt': 3, 'zaru': 3, 'nhc': 2, 'wheel': 1}
"""Degrees of freedom of each pseudo-measurement (NHC: 1 while turning)."""
_NIS_CAUSE = {
    'zaru': 'the datasheet gyro noise/bias model is too optimistic at rest (measured noise ~2x, '
            'turn-on bias)',
    'nhc': 'the contact-centre lateral/vertical velocity is not as small as the NHC sigmas say '
           '(vibration, suspension, skid)'}


def _s5t1_noise(study: Study, a: str, b: str, noise: str) -> str:
    """' (within <noise>)' when the s5t1 final errors of ``a`` and ``b`` differ by less than
    :data:`S5T1_NOISE_M`, ' (beyond <noise>)' otherwise."""
    d = abs(_m(study, b, 's5t1', 'pos_final_m') - _m(study, a, 's5t1', 'pos_final_m'))
    if not math.isfinite(d):
        return ''
    return f' ({"within" if d < S5T1_NOISE_M else "beyond"} {noise})'


def _improves(study: Study, a: str, b: str) -> bool:
    """``b`` beats ``a`` on test17run: lower injected slip MAE and lower plain speed RMSE."""
    return (_m(study, b, RTK_LOG, 'slip_mae', 'injected')
            < _m(study, a, RTK_LOG, 'slip_mae', 'injected')
            and _m(study, b, RTK_LOG, 'v_rmse') < _m(study, a, RTK_LOG, 'v_rmse'))


def _largest_step(study: Study, chain: str = 'ABCD') -> str:
    """The configuration of ``chain`` whose step from its predecessor raises the injected
    balanced accuracy on test17run the most ('' when fewer than two are present)."""
    gains = {b: _m(study, b, RTK_LOG, 'balanced_accuracy', 'injected')
             - _m(study, a, RTK_LOG, 'balanced_accuracy', 'injected')
             for a, b in zip(chain, chain[1:])}
    gains = {k: v for k, v in gains.items() if math.isfinite(v)}
    return max(gains, key=gains.__getitem__) if gains else ''


def _release_drift(rel: dict[str, np.ndarray]) -> str:
    """Whether the mean speed change after a release is a drift: beyond two standard errors."""
    n = len(rel['change'])
    drift = abs(np.mean(rel['change'])) > 2.0 * np.std(rel['change']) / math.sqrt(n)
    return 'a systematic drift' if drift else 'no systematic drift'


def _radius_bias_text(study: Study) -> str:
    """How the estimator's own low-slip bias (F: estimate minus truth, plain) compares with
    the part the nominal radius accounts for (1 - RTK/rim speed)."""
    radius_part = 1.0 - study.measured.gnss_over_rim
    own = abs(_m(study, 'F', RTK_LOG, 'low_est_mean') - _m(study, 'F', RTK_LOG, 'low_truth_mean'))
    if not math.isfinite(own):
        return (f'the share of the {radius_part:.3f} the radius accounts for is not measured '
                'here (F not run)')
    if own >= SEVERAL * radius_part:
        return (f'the estimator\'s own low-slip bias (tables, column "low") is several times the '
                f'{radius_part:.3f} the radius accounts for, so correcting the radius does not '
                'remove the bias users would see on firm ground')
    if own >= radius_part / SEVERAL:
        return (f'the estimator\'s own low-slip bias ({own:.3f} with F) is comparable to the '
                f'{radius_part:.3f} the radius accounts for, so correcting the radius removes '
                'only part of the bias users would see on firm ground')
    return (f'the estimator\'s own low-slip bias ({own:.3f} with F) is a fraction of the '
            f'{radius_part:.3f} the radius accounts for, so correcting the radius removes most '
            'of the bias users would see on firm ground')


def _nis_text(study: Study, shipped: str) -> str:
    """What the NIS means say: a pseudo-measurement far below its degrees of freedom in the
    shipped model is over-conservative; those several times above in every configuration
    and log are named with their likely cause."""
    logs = study.logs
    low = _m(study, shipped, logs[0], 'nis_zupt') if logs else math.nan
    parts = []
    if all(_m(study, shipped, log, 'nis_zupt') < NIS_DOF['zupt'] / SEVERAL for log in logs) \
            and math.isfinite(low):
        parts.append('ZUPT is over-conservative (its 0.01 m/s sigma is large against a rover '
                     'at rest)')
    high = [k for k in _NIS_CAUSE if all(
        _m(study, c, log, f'nis_{k}') > SEVERAL * NIS_DOF[k]
        for c in study.configs for log in logs)]
    if high:
        names = ' and '.join(k.upper() for k in high)
        both = len(high) > 1
        parts.append(f'{names} residuals are several times their expectation in every '
                     f'configuration: ' + ' and '.join(_NIS_CAUSE[k] for k in high)
                     + f'. The node flags {"both" if both else "it"} in /diagnostics; none of '
                     f'the configurations addresses {"them" if both else "it"}')
    return '; '.join(parts) + '.' if parts else ''


def _class_counts(study: Study, variant: str) -> str:
    r = next((x for x in study.results if x.log == RTK_LOG and x.variant == variant), None)
    if r is None:
        return ''
    from slip_estimator.core.types import SLIP_CLASS_NAMES

    cnt = ', '.join(f'{SLIP_CLASS_NAMES[c]} {_f(r.metrics.get(f"n_truth_{c}"), 0)}'
                    for c in range(5))
    return f'Truth samples per class (10 Hz wheel samples): {cnt}.'


def _delta(study: Study, a: str, b: str, metric: str, log: str = RTK_LOG,
           variant: str = 'plain', d: int = 3) -> str:
    ra, rb = study.get(a, log, variant), study.get(b, log, variant)
    if ra is None or rb is None:
        return 'n/a'
    return f'{_f(ra.metrics.get(metric), d)} -> {_f(rb.metrics.get(metric), d)}'


_V_RMSE = ('forward-speed RMSE', 'v_rmse', ' m/s')
_POS_FINAL = ('final position error', 'pos_final_m', ' m', 2)
_NHC_NIS = ('NHC NIS', 'nis_nhc', '', 2)


def _changes(study: Study, a: str, b: str, *items: tuple, log: str = RTK_LOG,
             variant: str = 'plain') -> str:
    """'label a -> b unit, ...' for items (label, metric[, unit[, digits]])."""
    out = []
    for label, metric, *rest in items:
        unit = rest[0] if rest else ''
        d = rest[1] if len(rest) > 1 else 3
        out.append(f'{label} {_delta(study, a, b, metric, log, variant, d)}{unit}')
    return ', '.join(out)


def _slip_cell(m: dict[str, Any], digits: int, extra: str, tail: str) -> str:
    """'balanced (recall medium / high / extreme<extra>), F1 f1, <tail>' of one run."""
    rec = m['recall']
    return (f'{_f(m["balanced_accuracy"], digits)} ({_f(rec[2], 2)} / {_f(rec[3], 2)} / '
            f'{_f(rec[4], 2)}{extra}), F1 {_f(m["sig_f1"], 2)}, {tail}')


def _pattern_section(rows: list[dict[str, Any]] | None) -> list[str]:
    """C against D over several injection patterns (the spread behind one table row)."""
    if not rows:
        return []
    table = []
    for r in rows:
        cells = [', '.join(f'x{f} {a:.0f}-{b:.0f} s' for a, b, f in r['pattern'])]
        for key in ('C', 'D'):
            m = r[key]
            cells.append(_slip_cell(m, 3, f', n = {m["n_truth"][4]}', f'MAE {_f(m["slip_mae"])}'))
        table.append(cells)
    return (['Across injection patterns (core runs on test17run, RTK truth; balanced accuracy '
             '(recall medium / high / extreme, extreme truth samples), significant-slip F1, '
             'slip MAE). Where the extreme class has a handful of samples (starts, stops, a '
             'window on the 0.7 bound), those samples move the balanced accuracy by up to a '
             'quarter; medium/high recall, F1 and MAE are the stable figures:', '']
            + _table(['injected windows', 'C (first design)', 'D (shipped)'], table) + [''])


def _latency_verdict(study: Study) -> str:
    """Whether compensating the measured lag (E) helps the shipped model (D), and what
    follows for ``wheel_latency_s``."""
    if _improves(study, 'D', 'E'):
        return ('Compensating the measured lag improves the shipped model on these logs (slip '
                'MAE and speed RMSE above); `wheel_latency_s` is worth measuring per rover '
                '(`pathfinder.wheel_imu_lag`) and declaring.')
    return ('Compensating the measured lag does not improve the shipped model on these logs; '
            'the two measures of the lag disagree on test17run (weak yaw-rate correlation) and '
            'part of the apparent lag may be the encoder speed itself (a count difference over '
            'the 0.1 s sample interval describes the middle of the interval). '
            '`wheel_latency_s` therefore stays a declared parameter with default 0, not a '
            'default correction.')


def _lag_drift_text(study: Study) -> str:
    """What the windowed lag says about a clock drift between the wheels and the IMU."""
    parts = []
    for log in study.logs:
        lt = study.evidence.get(f'lag_over_time_{log}')
        good = lt is not None and len(lt['t']) >= 3
        if good:
            k = lt['corr'] > 0.8
            good = k.sum() >= 3
        if not good:
            parts.append(f'{log}: too little turning for a lag per 30 s window')
            continue
        slope = np.polyfit(lt['t'][k], lt['lag'][k], 1)[0]
        parts.append(f'{log}: {lt["lag"][k].min():.3f}-{lt["lag"][k].max():.3f} s over '
                     f'{k.sum()} windows with r > 0.8, a trend of {slope * 1e3:+.2f} ms per s')
    return ('Per 30 s window (figure, right) the lag is not constant: ' + '; '.join(parts)
            + '. A lag that grows through a log is a drift between the wheel and IMU clocks '
            '(or a growing transport delay); no single `wheel_latency_s` fits it, '
            + ('which is why a constant compensation does not help' if not _improves(
                study, 'D', 'E') else 'so a constant compensation helps only on average')
            + '. The node measures the lag online '
            '(`core.timing.WheelTimingMonitor`, yaw rate vs wheel differential over the last '
            '30 s of turning) and names an undeclared one in `/diagnostics`.')


def _imu_scatter_text(sc: dict[str, list[float]] | None) -> str:
    """Where body-side reading fails on this rover, from ``evidence.imu_speed_scatter``."""
    if not sc:
        return ''
    scales = sc['scales_s']
    at = {s: k for k, s in enumerate(scales)}
    shown = [s for s in (1.0, 1.5, 2.0, 3.0) if s in at]
    std = ' / '.join(_f(sc['imu_vs_rim_std'][at[s]], 3) for s in shown)
    p95 = ' / '.join(_f(sc['imu_vs_rim_p95'][at[s]], 3) for s in shown)
    floor = max(sc['rim_vs_rtk_std'])
    walk = math.sqrt(max(0.0, sc['imu_vs_rim_std'][-1] ** 2 - sc['imu_vs_rim_std'][0] ** 2)
                     / (scales[-1] - scales[0]))
    step_mps = 0.2  # a medium body-side step on this log: slip +0.27 at 0.72 m/s
    k15 = at.get(1.5, 0)
    return (
        f'Where it fails, measured (`validation.evidence.imu_speed_scatter`): the forward speed '
        f'change the IMU alone gives (specific force less gravity, pitch from the gyro) differs '
        f'from the rim speed\'s over {" / ".join(_f(s, 1) for s in shown)} s by {std} m/s '
        f'(RMS; 95th percentile {p95} m/s), while rim and RTK agree to {_f(floor, 3)} m/s or '
        f'better at every scale: the IMU speed wanders like a random walk of about '
        f'{_f(walk, 3)} m/s per sqrt(s) (vibration folded into the samples). A body-side '
        f'change is read across its 1-3 s '
        f'transition, so a medium step of this log (about {_f(step_mps, 1)} m/s) is '
        f'{_f(step_mps / sc["imu_vs_rim_std"][k15], 1)} times the 1.5-s scatter, and '
        f'excursions of that size with steady wheels and RTK occur in this one drive (largest '
        f'over 1.5 s: {_f(sc["imu_vs_rim_max"][k15], 3)} m/s): the IMU cannot tell such a '
        'change from its own error, whatever the model. The slip model therefore keeps the '
        'measured change only beyond its learned threshold; a missed onset followed by a '
        'detected end is read as a run-ahead, which it refuses on level ground (a body cannot '
        'run ahead of steady wheels without a downhill pull) and puts back to the baseline. '
        'Each measured change starts from the held model before it, so errors chain until the '
        'next stop or a return to the baseline ground.')


def body_side_section(rows: list[dict[str, Any]] | None,
                      scatter: dict[str, list[float]] | None = None) -> list[str]:
    """The slip model on body-side and mixed slip of the real log."""
    if not rows:
        return []
    keys = [k for k in rows[0] if k not in ('kind', 'wheel', 'body')]
    table = []
    for r in rows:
        what = ', '.join([f'wheels x{f} {a:.0f}-{b:.0f} s' for a, b, f in r['wheel']]
                         + [f'body x{f} {a:.0f}-{b:.0f} s' for a, b, f in r['body']])
        cells = [f'{r["kind"]}: {what}']
        for key in keys:
            m = r[key]
            cells.append(_slip_cell(m, 2, '', f'{_f(m["v_rmse"], 3)} m/s'))
        table.append(cells)
    mean = {k: np.mean([r[k]['balanced_accuracy'] for r in rows if r['kind'] == 'body'])
            for k in keys}
    f1 = {k: np.mean([r[k]['sig_f1'] for r in rows if r['kind'] == 'body']) for k in keys}
    return ([
        '### The slip model on body-side slip (real IMU)', '',
        ('A rover holds its commanded wheel rate: in soft ground the wheels keep turning and '
         'the body slows, so the slip shows in the IMU, not the encoders. Here the real '
         'test17run wheels are kept and the body is slowed inside windows (`effects.'
         'inject_body_slip`: the derivative of the speed deficit taken out of the real '
         'forward specific force, 1 s transitions; truth = RTK speed minus the deficit). '
         'D is the shipped slip model (`core/slip_model.py`); "wheel side only" is D with the '
         'body-side step test off (`slip_change_sigma=20`), which is what the earlier hold '
         'mode could see; A is the paper. Cells: balanced accuracy (recall medium / high / '
         'extreme), significant-slip F1, forward-speed RMSE against the truth:'), '']
        + _table(['windows'] + keys, table)
        + ['', (f'Mean over the four body-side patterns: balanced accuracy '
                + ', '.join(f'{k} {_f(mean[k], 2)}' for k in keys) + '; F1 '
                + ', '.join(f'{k} {_f(f1[k], 2)}' for k in keys) + '.'), '',
           _imu_scatter_text(scatter), ''])


def undeclared_section(rows: list[dict[str, Any]] | None) -> list[str]:
    """Issue 3 sec. 3: the shipped model on data with an effect its parameters do not declare."""
    if not rows:
        return []
    lines = [
        '## Undeclared effects (shipped model, declared parameters only)', '',
        ('test17run with injected slip '
         + ', '.join(f'x{f} for {a:.0f}-{b:.0f} s' for a, b, f in TEST17RUN_WINDOWS)
         + ' and, one at a time, an effect the imported parameters do not declare, put into '
         'the data by `effects.Effects` (the IMU rotated off its declared mounting, the gyro '
         'scaled, the wheel stamps shifted, the rim speeds scaled as by a wrong declared '
         'radius); run through the core (`effects.score_on_log`, the same code as the tests in '
         '`test/integration/test_effects.py`), truth from RTK. Acceptance levels: balanced accuracy >= 0.80, '
         'medium and high recall >= 0.70, significant-slip F1 >= 0.85, speed RMSE <= 0.05 m/s '
         '(plain log).'), '']
    table = []
    for r in rows:
        rec = r['recall']
        table.append([r['effect'], _f(r['balanced_accuracy']), _f(rec[2], 2), _f(rec[3], 2),
                      _f(r['sig_f1'], 2), _f(r['slip_mae']), _f(r['v_rmse_injected']),
                      _f(r['v_rmse_plain']),
                      '; '.join(r['suspects']) if r['suspects'] else '(none)'])
    lines += _table(['undeclared effect', 'bal. acc.', 'recall med', 'high', 'sig. F1',
                     'slip MAE', 'v RMSE inj. [m/s]', 'v RMSE plain', 'suspected in /diagnostics'],
                    table)
    lines += ['', ('A radius declared 15 % too large reads as +0.15 slip on all ordinary ground '
                   'and moves the truth with it (the truth uses the declared radius, as any '
                   'user would): radius and slip cannot be told apart without a speed '
                   'reference, so the node names the radius as the likely cause rather than '
                   'correcting it (its lower medium recall is the x1.4 window, whose truth '
                   'the radius error moves onto the 0.4 class bound). The zero-rate suspicion '
                   'is the real IMU\'s (gyro noise above the datasheet at rest, see below), '
                   'present in every row. Mounting errors of a few degrees and a 2 % gyro '
                   'scale factor leave the residual means within their noise on this straight '
                   'drive, so they are not named; they also leave the slip accuracy where it '
                   'was. A wheel/IMU timestamp offset is not named by the residual means; the '
                   'online lag monitor names it when the rover turns (this test drive is '
                   'straight), and it costs accuracy at every slip step.'), '']
    return lines

@dataclass(frozen=True)
class Page:
    """What every section reads: the study, the figure files and where the page goes."""

    study: Study
    figures: dict[str, Path]
    md_path: Path
    command: str = COMMAND

    def fig(self, name: str, caption: str) -> list[str]:
        """The Markdown image line of figure ``name`` (relative to the page), or nothing."""
        if name not in self.figures:
            return []
        rel = Path(self.figures[name]).resolve().relative_to(self.md_path.resolve().parent)
        return [f'![{caption}]({rel.as_posix()})', '']


def _header(page: Page) -> list[str]:
    """Title, the command, provenance and code state."""
    study = page.study
    cases = len(study.results)
    return [
        '# Model validation on the real Pathfinder logs',
        '',
        'Generated, numbers and figures, from the data by:',
        '',
        '```bash',
        page.command,
        '```',
        '',
        (f'(equivalently `python -m slip_estimator.validation --out docs/validation.md`). '
        f'Logs read from `../shared/data/pathfinder`; imported and replayed in a temporary '
        f'folder. This run: {cases} replays + evaluations in {study.wall_s:.0f} s wall on '
        f'{study.jobs} worker process(es). Do not edit by hand: change '
        '`slip_estimator/validation/` and regenerate.'),
        '',
        f'Code state: {_code_state()}.',
        '',
    ]


def _what_was_run(page: Page) -> list[str]:
    """The configurations, the measured inputs, the injected slip."""
    study = page.study
    ms = page.study.measured
    lines = [
        ('A-D each add ONE effect to the previous configuration; E and F each add ONE measured '
        'effect to D, the shipped model (alternatives, not a chain). Overrides are Params on '
        'top of the imported params (datasheet IMU noise, r = 0.12 m, heading from the GNSS '
        'track):'),
        '',
    ]
    rows = []
    for k in study.configs:
        spec = CONFIG_BY_KEY[k]
        ov = {log: spec.overrides(ms, log) for log in study.logs}
        first = ov[study.logs[0]]
        txt = ', '.join(f'`{a}={b!r}`' for a, b in first.items())
        if len({repr(v) for v in ov.values()}) > 1:
            txt += ' (' + '; '.join(
                f'{log}: ' + ', '.join(f'`{a}={b!r}`' for a, b in v.items() if first.get(a) != b)
                for log, v in ov.items() if v != first) + ')'
        rows.append([k, spec.label, txt])
    lines += _table(['', 'configuration', 'overrides'], rows)
    lag_txt = ', '.join(f'{log} {ms.lag_s[log]:.3f} s (r = {ms.lag_corr[log]:.2f})'
                        for log in study.logs)
    lines += [
        '',
        (f'Measured from the data in this run: wheel-stamp lag behind the IMU '
        f'(`pathfinder.wheel_imu_lag`, yaw-rate cross-correlation) {lag_txt}; '
        f'RTK speed / rim speed on test17run (`pathfinder.gnss_over_wheel_speed`) '
        f'{ms.gnss_over_rim:.4f}, i.e. effective radius {ms.wheel_radius_eff_m:.4f} m, applied to '
        'both logs (same rover, same wheels).'),
        '',
        'Injected slip (test17run only, the log with RTK truth): the real IMU and GNSS, the '
        '`/joint_states` velocities multiplied by '
        + ', '.join(f'x{f} for {a:.0f}-{b:.0f} s' for a, b, f in TEST17RUN_WINDOWS)
        + ' after the first IMU sample (the drive is 5.4-54.6 s), written by '
        '`validation.study.inject_wheel_slip` through `bagio.read_messages` / `BagWriter`. '
        '**Truth slip = eq. 1 between the scaled rim speed and the RTK forward speed** (exactly '
        'what `evaluate_run` computes on the rewritten bag). Chosen over "scaled vs unscaled rim '
        'speed combined with the baseline slip" because it needs no rule for combining two slip '
        'ratios (eq. 1 is not additive, and switches branch at v = r w), it contains the real '
        'baseline slip and radius error of this drive, and it is the same truth as in the plain '
        'run, so both tables are scored alike.',
        '',
    ]
    return lines


def _truth(page: Page) -> list[str]:
    """Which metric rests on which truth."""
    return [
        ('* **test17run, RTK** (mm at rest, ~1 cm driving, 10 Hz): valid for everything — slip '
        'classes and ratio (eq. 30 with the GNSS forward speed over a 1 s fit), forward speed, '
        'position, drift, heading (GNSS course while moving). Truth slip uses the GNSS velocity '
        'at the time the wheel sample describes (stamp minus the measured lag), for every '
        'configuration alike, so the truth does not depend on the model. Slip truth also '
        'depends on the radius the rim speed is computed with: each configuration is scored '
        'with its own radius (see effect F).'),
        ('* **s5t1, single point** (sigma ~2-5 m, jittery receive stamps): only coarse whole-run '
        'checks are valid — final position error, drift in % of distance, net displacement, '
        'path shape (figure). Its per-sample speed, slip classes and heading are NOT valid and '
        'are not tabulated; the mean slip reported while driving is shown for information '
        '(no truth).'),
        ('* **Residual statistics** (both logs, no truth needed): `nis_<name>` is the time '
        'average of the node\'s `/diagnostics` KeyValue `nis_mean_<name>` (itself an exponential '
        'average over ~50 updates). A consistent filter gives its degrees of freedom: ZUPT 3, '
        'ZARU 3, NHC 2 (1 while turning), wheel aid 1. Divergence resets and recoveries are the '
        'node\'s counters at the end of the run.'),
        ('* Forward-speed RMSE is the odometry output\'s body-x speed against the RTK speed at the '
        'same instants while driving (> 0.1 m/s): independent of the wheel timing, so configs '
        'with and without the latency model are compared on equal terms. `evaluate_run`\'s own '
        'figure (body speed at the wheel stamps vs GNSS at stamp minus lag) is not tabulated.'),
        (f'* s5t1 final position errors that differ by less than ~{S5T1_NOISE_M:.0f} m are '
        'within the single-point '
        'GNSS noise (reported sigma 2.6 / 1.6 m horizontal): only larger differences rank the '
        'configurations.'),
        '',
    ]


def _before_after(page: Page) -> list[str]:
    """Slip and navigation tables per log and variant."""
    study = page.study
    lines = [
        '### test17run (RTK truth), plain log',
        '',
    ]
    lines += slip_table(study, RTK_LOG, 'plain')
    lines += ['']
    lines += nav_table(study, RTK_LOG, 'plain')
    lines += ['', _class_counts(study, 'plain') + ' The plain drive is low slip (firm ground); '
              'the few medium/high/extreme truth samples are starts and stops, where rim and '
              'GNSS speed disagree for a sample or two. Balanced accuracy averages the recall '
              'over the classes present, so a handful of such samples weighs as much as the '
              'whole drive: read it with the counts, and prefer slip MAE, the low-class bias and '
              'the speed error here.', '',
              '### test17run with injected wheel slip (RTK truth)', '']
    lines += slip_table(study, RTK_LOG, 'injected')
    lines += ['']
    lines += nav_table(study, RTK_LOG, 'injected')
    lines += ['', _class_counts(study, 'injected'), '',
              ('Median slip inside each window (first 2 s of a window skipped: the estimator '
              'needs `slip_measure_s` to measure a new slip) and on the driving part outside '
              'the windows:'), '']
    lines += _window_table(study)
    lines += ['', '### s5t1 (single-point GNSS: coarse metrics only)', '']
    lines += nav_table(study, 's5t1', 'plain', coarse=True)
    lines += ['']
    return lines


def _effect_b(page: Page) -> list[str]:
    """Evidence for B: vibration-aware process noise."""
    study = page.study
    fig = page.fig
    lines = [
        '### B: vibration-aware process noise', '',
        ('On test17run ' + _changes(study, 'A', 'B', _V_RMSE, _POS_FINAL, _NHC_NIS)
         + '; on s5t1 ' + _changes(study, 'A', 'B', _POS_FINAL, _NHC_NIS, log='s5t1') + '. '
        'The vibration term widens Q while driving (the IMU window spread is an order of '
        'magnitude above the datasheet noise), which makes the filter trust the '
        'pseudo-measurements more and the INS less; it cannot make the forward velocity '
        'observable — NHC constrains only lateral and vertical velocity, so with the paper\'s '
        'measurements the forward speed still drifts (figure below, A and B).'), '']
    lines += fig('velocity_error_test17run', 'forward speed error vs RTK on test17run')
    return lines


def _effect_c(page: Page) -> list[str]:
    """Evidence for C: the hold-mode wheel aid."""
    study = page.study
    fig = page.fig
    lines = [
        '### C: hold-mode wheel aid (first design)', '',
        ('test17run ' + _changes(study, 'B', 'C', _V_RMSE, _POS_FINAL,
                                 ('low-class recall / balanced accuracy', 'balanced_accuracy'))
         + '; injected: ' + _changes(study, 'B', 'C', ('balanced accuracy', 'balanced_accuracy'),
                                     ('significant-slip F1', 'sig_f1', '', 2),
                                     ('slip MAE', 'slip_mae'), variant='injected')
         + '; s5t1 ' + _changes(study, 'B', 'C', _POS_FINAL, log='s5t1') + '. '
        + ('This is the one effect that changes the picture: ' if _largest_step(study) == 'C'
           else 'Not the largest step on these logs (tables above); still, ')
        + 'without a forward-velocity '
        'measurement the unaided INS drifts by tenths of m/s within seconds and the slip '
        'classes above "low" are unreliable; with the held slip the rim speed bounds the drift '
        'without forcing zero slip.'), '']
    lines += fig('injected_slip_test17run', 'injected slip: estimate vs truth')
    return lines


def _effect_d(page: Page) -> list[str]:
    """Evidence for D: continuity and baseline; the slip model on the real IMU."""
    study = page.study
    ev = page.study.evidence
    fig = page.fig
    lines: list[str] = []
    rel = ev.get('release')
    if rel is not None and len(rel['t']):
        rel_txt = (f'{len(rel["t"])} releases: the aided speed error (0.5 s before) has std '
                   f'{np.std(rel["aided"]):.3f} m/s; 0-0.1 s after the release the error has '
                   f'already changed by {np.std(rel["change_early"]):.3f} m/s (std) and over '
                   f'0.25-0.85 s by {np.std(rel["change"]):.3f} m/s (std; mean '
                   f'{np.mean(rel["change"]):+.3f}, i.e. {_release_drift(rel)})')
    else:
        rel_txt = 'not run'
    lines += [
        '### D: slip-change continuity and ground baseline', '',
        ('Residual evidence: with C the slips held after each change are biased and the bias '
        'grows from one slip episode to the next (window table above; the slip read on '
        'ordinary ground between the windows drifts away from the truth), because every '
        'measurement starts from the velocity the previous hold anchored and adds the unaided '
        'INS error of the measurement interval. How large that error is on this rover was '
        'measured directly (release experiment, `validation.evidence.release_scatter`: the '
        'shipped filter on the plain log with the wheel aid switched off for 1 s every 3 s, '
        f'odometry speed against RTK): {rel_txt}. The unaided INS of this rover scatters by ~0.05 m/s '
        'within a fraction of a second (vibration and pitching of the double-bogie body at the '
        'IMU, where the datasheet noise alone predicts millimetres per second), so a 0.5-1 s '
        'INS measurement cannot place a slip better than ~0.07 at 0.7 m/s, about a third of a '
        'class. The simulator, with an IMU that follows its noise model, shows a scatter of '
        '~0.01 m/s (wheel-aid innovation spread 0.008-0.010 m/s simulated vs 0.040 test17run, '
        '0.024 s5t1).'), '',
        ('Model change (`slip_continuity_sigma`, `slip_baseline`, `slip_measure_s` 1.0 -> 0.5 s; '
        'on by default): (1) a slip change is measured by velocity continuity — the held '
        'model\'s speed before the change plus the INS speed change across it — and an INS '
        'change below 2 sigma of the wheel-aid innovation spread, measured online, is taken '
        'as none (a wheel-speed step the body does not follow); (2) the first slip measured '
        'after a start, anchored on the stop\'s ZUPT, is the ground\'s baseline, and a later '
        'measurement within the change threshold of it is that ground again, which ends the '
        'chain; (3) the velocity is re-anchored on the held slip at once; (4) a measurement '
        'waits while the body is still accelerating. The noise scale is measured, not tuned '
        'per log: on the simulator it shrinks to the simulated IMU\'s and the INS change is '
        'used almost as measured.'), '',
        (f'Effect on test17run with injected slip: balanced accuracy '
        f'{_delta(study, "C", "D", "balanced_accuracy", variant="injected")}, medium recall '
        f'{_delta(study, "C", "D", "recall_medium", variant="injected", d=2)}, high recall '
        f'{_delta(study, "C", "D", "recall_high", variant="injected", d=2)}, significant-slip '
        f'F1 {_delta(study, "C", "D", "sig_f1", variant="injected", d=2)}, slip MAE '
        f'{_delta(study, "C", "D", "slip_mae", variant="injected")}, speed RMSE '
        f'{_delta(study, "C", "D", "v_rmse", variant="injected")} m/s; plain log speed RMSE '
        f'{_delta(study, "C", "D", "v_rmse")} m/s, slip MAE {_delta(study, "C", "D", "slip_mae")}'
        f'; s5t1 final position error {_delta(study, "C", "D", "pos_final_m", log="s5t1", d=2)} '
        'm. What it cannot do: a slip change that comes with a body-speed change smaller than '
        'the INS scatter is read as no change of body speed; and the baseline assumes the '
        'ground after an episode is the ground before it.'), '']
    lines += fig('release_test17run', 'unaided INS speed error after release')
    lines += _pattern_section(ev.get('patterns'))
    lines += body_side_section(ev.get('body_side'), ev.get('imu_speed_scatter'))
    return lines


def _effect_e(page: Page) -> list[str]:
    """Evidence for E: wheel latency."""
    study = page.study
    ms = page.study.measured
    ev = page.study.evidence
    fig = page.fig
    lines: list[str] = []
    lc = {log: ev.get(f'accel_lag_{log}') for log in study.logs}
    lines += [
        '### E: wheel latency', '',
        'Two independent cross-correlations put the wheel stamps late: gyro yaw rate vs wheel '
        'differential (the value used, `pathfinder.wheel_imu_lag`) gives '
        + ', '.join(f'{log} {ms.lag_s[log]:+.3f} s (r = {ms.lag_corr[log]:.2f})'
                    for log in study.logs)
        + '; forward specific force vs d(wheel rate)/dt gives '
        + ', '.join(f'{log} {_f(lc[log], 3)} s' for log in study.logs)
        + '. test17run is a straight drive, so its yaw-rate correlation is weak (small heading '
        'wander only) and its value less certain than s5t1\'s (long arcs); each log uses its own '
        'measured lag (the two sessions are a year apart).', '',
        (f'Effect: test17run injected balanced accuracy '
        f'{_delta(study, "D", "E", "balanced_accuracy", variant="injected")}, slip MAE '
        f'{_delta(study, "D", "E", "slip_mae", variant="injected")}, significant-slip F1 '
        f'{_delta(study, "D", "E", "sig_f1", variant="injected", d=2)}, speed RMSE '
        f'{_delta(study, "D", "E", "v_rmse", variant="injected")} m/s; plain slip MAE '
        f'{_delta(study, "D", "E", "slip_mae")}, speed RMSE {_delta(study, "D", "E", "v_rmse")} '
        f'm/s, max speed error {_delta(study, "D", "E", "v_err_max", d=2)} m/s; s5t1 final '
        f'error {_delta(study, "D", "E", "pos_final_m", log="s5t1", d=2)} m'
        f'{_s5t1_noise(study, "D", "E", "the single-point noise")}. '
        + _lag_drift_text(study) + ' At steady speed a 0.1-0.2 s '
        'shift changes nothing; it matters at '
        'starts, stops and slip steps (~1-2 of the 10 Hz samples each). '
        + _latency_verdict(study)),
        '']
    lines += fig('wheel_latency_xcorr', 'wheel latency cross-correlations')
    return lines


def _effect_f(page: Page) -> list[str]:
    """Evidence for F: the effective wheel radius."""
    study = page.study
    ms = page.study.measured
    ev = page.study.evidence
    fig = page.fig
    lines: list[str] = []
    f_ratio = ev.get(f'ratio_samples_{RTK_LOG}')
    spread = (f'{np.percentile(f_ratio, 10):.3f}-{np.percentile(f_ratio, 90):.3f}'
              if f_ratio is not None and len(f_ratio) else 'n/a')
    r_e = study.get('F', RTK_LOG)
    r_d = study.get('D', RTK_LOG)
    lines += [
        '### F: effective wheel radius', '',
        (f'On test17run (RTK, firm ground, straight) the GNSS speed is {ms.gnss_over_rim:.3f} of '
        f'the rim speed at r = {ms.wheel_radius_nominal_m} m (1 s windows: 10-90 % range '
        f'{spread}), so r_eff = {ms.wheel_radius_eff_m:.4f} m. **A radius error is '
        f'indistinguishable from a constant slip**: with r = {ms.wheel_radius_nominal_m} m the '
        'same drive reads '
        f's = 1 - r_eff/r = {1 - ms.gnss_over_rim:+.3f} everywhere. Radius and slip can be '
        'separated only against a truth reference on ground where the slip is known to be '
        '~0 — here RTK on firm ground (test17run); part of the '
        f'{100 * (1 - ms.gnss_over_rim):.1f} % may well be genuine '
        'longitudinal slip of polyurethane wheels on that surface, which then gets absorbed '
        'into the "radius" and would be missed on any other terrain. The single-point GNSS of '
        f's5t1 gives a ratio of {_f(ev.get("ratio_s5t1_single_point"), 3)} — not a radius: '
        'metre-level position noise adds speed of its own, and turns add skid; it cannot '
        'calibrate anything.'), '',
        ('Because the slip definition moves with the radius, the low-class truth moves from '
        f'{_f(r_d.metrics.get("low_truth_mean") if r_d else None)} (D, r = '
        f'{ms.wheel_radius_nominal_m} m) to '
        f'{_f(r_e.metrics.get("low_truth_mean") if r_e else None)} (F) on the plain log. The '
        'estimate in the low class reads '
        f'{_f(r_d.metrics.get("low_est_mean") if r_d else None)} -> '
        f'{_f(r_e.metrics.get("low_est_mean") if r_e else None)} (plain) and '
        f'{_delta(study, "D", "F", "low_est_mean", variant="injected")} (injected): '
        + _radius_bias_text(study) + '. Injected balanced accuracy '
        f'{_delta(study, "D", "F", "balanced_accuracy", variant="injected")} moves mostly '
        'through the extreme class, i.e. a handful of start/stop samples (counts above); slip '
        f'MAE {_delta(study, "D", "F", "slip_mae", variant="injected")}. Position: test17run '
        f'final error {_delta(study, "D", "F", "pos_final_m", d=2)} m, injected '
        f'{_delta(study, "D", "F", "pos_final_m", variant="injected", d=2)} m; s5t1 '
        f'{_delta(study, "D", "F", "pos_final_m", log="s5t1", d=2)} m'
        f'{_s5t1_noise(study, "D", "F", "its noise")}.'), '']
    lines += fig('radius_ratio_test17run', 'RTK speed over rim speed')
    return lines


def _trajectories(page: Page) -> list[str]:
    """The s5t1 trajectory figure."""
    fig = page.fig
    return page.fig('trajectory_s5t1', 's5t1 trajectories')


def _undeclared(page: Page) -> list[str]:
    """Undeclared effects."""
    return undeclared_section(page.study.evidence.get('undeclared'))


def _unexplained(page: Page) -> list[str]:
    """What remains unexplained."""
    study = page.study
    ev = page.study.evidence
    lines: list[str] = []
    shipped = 'D' if 'D' in study.configs else study.configs[-1]
    fo = {log: ev.get(f'f_offset_{log}') for log in study.logs}
    for log in study.logs:
        f = fo[log]
        if not f:
            continue
        nav = [(k, ev[f'f_nav_{k}_{log}']) for k in study.configs if f'f_nav_{k}_{log}' in ev]
        nav_txt = '; '.join(f'{k}: up {_f(v["up_drive_minus_rest"], 3)}, forward '
                            f'{_f(v["forward_drive"], 3)}' for k, v in nav)
        lines.append(
            f'* **Accelerometer offset while driving ({log})**, raw IMU: |mean f| '
            f'{f["norm_of_mean_drive"]:.3f} m/s^2 driving vs {f["norm_of_mean_rest"]:.3f} at '
            f'rest ({f["norm_of_mean_drive"] - f["norm_of_mean_rest"]:+.3f}); mean |f| '
            f'{f["mean_of_norm_drive"]:.3f} vs {f["mean_of_norm_rest"]:.3f} (vibration, per-axis '
            f'std {f["std_drive"]:.2f} vs {f["std_rest"]:.3f}, rectifies the norm upwards — '
            f'not an offset); mean forward component {f["forward_drive"]:+.3f} vs '
            f'{f["forward_rest"]:+.3f} (pitch on the slope and offset are not separable in the '
            'raw data). Resolved with each configuration\'s ESTIMATED attitude, mean while '
            f'driving (up: minus the rest value; forward: true mean ~0 over a rest-to-rest '
            f'drive): {nav_txt} m/s^2 (raw f: the filter\'s accelerometer-bias estimate, published '
            'in /diagnostics, is not subtracted, so part of this is what the bias states '
            'absorb). Each 0.01 m/s^2 left in the forward channel is 1 cm/s of velocity drift '
            'per second of unaided INS (the hold mode\'s measure intervals). The raw |f| does '
            'not show a drop below g of the size reported earlier (~0.07 m/s^2); what the data '
            'do show is a vibration-dependent change of the forward component and of the '
            'attitude-resolved forward specific force. Its origin (rectified vibration, '
            'attitude error, an accelerometer scale/offset that changes with vibration, or '
            'pitch dynamics on the slope) the logs do not tell; no configuration models it.')
    lines += [
        ('* **Residuals not at their degrees of freedom** (configuration '
         f'{shipped}): ' + '; '.join(
             f'{log} NIS ZUPT {_f(_m(study, shipped, log, "nis_zupt"), 2)} (3), ZARU '
             f'{_f(_m(study, shipped, log, "nis_zaru"), 1)} (3), NHC '
             f'{_f(_m(study, shipped, log, "nis_nhc"), 1)} (2), wheel aid '
             f'{_f(_m(study, shipped, log, "nis_wheel"), 2)} (1)'
             for log in study.logs)
         + '. ' + _nis_text(study, shipped)),
        ('* **IMU noise above the datasheet** (import facts: gyro ~2x, accelerometer ~8x at rest): '
        'the study keeps the datasheet values in Q (the imported params) and lets the '
        'vibration term (B) carry the excess; a run with `measured_noise=True` would be the '
        'next one-effect step.'),
        ('* The low-slip bias of the reported slip (tables, column "low") is what a user sees on '
        'firm ground: with r = 0.12 m it is the radius error; with r_eff what remains is the '
        'estimator\'s own bias.'),
        '',
    ]
    return lines


def _notes(page: Page) -> list[str]:
    """The evaluation's notes, once each."""
    study = page.study
    lines: list[str] = []
    seen = []
    for r in study.results:
        for n in r.notes:
            t = f'{r.log}: {n}'
            if t not in seen:
                seen.append(t)
    lines += [f'* {n}' for n in seen]
    lines += ['']
    return lines


TEMPLATE = """\
{header}
## What was run

{what_was_run}
## Which metric rests on which truth

{truth}
## Before / after

{before_after}
## Evidence per effect

{effect_b}
{effect_c}
{effect_d}
{effect_e}
{effect_f}
### s5t1 trajectories

{trajectories}
{undeclared}
## What remains unexplained

{unexplained}
## Notes from the evaluation

{notes}"""
"""The page: literal lines, and ``{name}`` lines replaced by the lines of section ``name``."""

SECTIONS: dict[str, Callable[[Page], list[str]]] = {
    'header': _header, 'what_was_run': _what_was_run, 'truth': _truth,
    'before_after': _before_after, 'effect_b': _effect_b, 'effect_c': _effect_c,
    'effect_d': _effect_d, 'effect_e': _effect_e, 'effect_f': _effect_f,
    'trajectories': _trajectories, 'undeclared': _undeclared, 'unexplained': _unexplained,
    'notes': _notes}
_SLOT = re.compile(r'^\{(\w+)\}$')


def render_markdown(study: Study, figures: dict[str, Path], md_path: Path,
                    command: str = COMMAND) -> str:
    """The report text (Markdown). Figures are linked relative to ``md_path``."""
    page = Page(study, figures, md_path, command)
    lines: list[str] = []
    for line in TEMPLATE.split('\n'):
        slot = _SLOT.match(line)
        lines += SECTIONS[slot.group(1)](page) if slot else [line]
    return '\n'.join(lines)
