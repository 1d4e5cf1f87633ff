"""The report's judgements: thresholds, and the sentences whose wording depends on what the
study measured (within or beyond the s5t1 noise, whether the lag compensation helps, what the
NIS means and the low-slip bias say)."""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.validation.configs import RTK_LOG
from slip_estimator.validation.study import Study
from slip_estimator.validation.tables import fmt, metric_of


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


def s5t1_noise(study: Study, a: str, b: str, noise: str) -> str:
    """' (within <noise>)' when the s5t1 final errors of ``a`` and ``b`` differ by less than
    :data:`S5T1_NOISE_M`, ' (beyond <noise>)' otherwise."""
    d = abs(metric_of(study, b, 's5t1', 'pos_final_m') - metric_of(study, a, 's5t1', 'pos_final_m'))
    if not math.isfinite(d):
        return ''
    return f' ({"within" if d < S5T1_NOISE_M else "beyond"} {noise})'


def _improves(study: Study, a: str, b: str) -> bool:
    """``b`` beats ``a`` on test17run: lower injected slip MAE and lower plain speed RMSE."""
    return (metric_of(study, b, RTK_LOG, 'slip_mae', 'injected')
            < metric_of(study, a, RTK_LOG, 'slip_mae', 'injected')
            and metric_of(study, b, RTK_LOG, 'v_rmse') < metric_of(study, a, RTK_LOG, 'v_rmse'))


def largest_step(study: Study, chain: str = 'ABCD') -> str:
    """The configuration of ``chain`` whose step from its predecessor raises the injected
    balanced accuracy on test17run the most ('' when fewer than two are present)."""
    gains = {b: metric_of(study, b, RTK_LOG, 'balanced_accuracy', 'injected')
             - metric_of(study, a, RTK_LOG, 'balanced_accuracy', 'injected')
             for a, b in zip(chain, chain[1:])}
    gains = {k: v for k, v in gains.items() if math.isfinite(v)}
    return max(gains, key=gains.__getitem__) if gains else ''


def release_drift(rel: dict[str, np.ndarray]) -> str:
    """Whether the mean speed change after a release is a drift: beyond two standard errors."""
    n = len(rel['change'])
    drift = abs(np.mean(rel['change'])) > 2.0 * np.std(rel['change']) / math.sqrt(n)
    return 'a systematic drift' if drift else 'no systematic drift'


def radius_bias_text(study: Study) -> str:
    """How the estimator's own low-slip bias (F: estimate minus truth, plain) compares with
    the part the nominal radius accounts for (1 - RTK/rim speed)."""
    radius_part = 1.0 - study.measured.gnss_over_rim
    own = abs(metric_of(study, 'F', RTK_LOG, 'low_est_mean')
              - metric_of(study, 'F', RTK_LOG, 'low_truth_mean'))
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


def nis_text(study: Study, shipped: str) -> str:
    """What the NIS means say: a pseudo-measurement far below its degrees of freedom in the
    shipped model is over-conservative; those several times above in every configuration
    and log are named with their likely cause."""
    logs = study.logs
    low = metric_of(study, shipped, logs[0], 'nis_zupt') if logs else math.nan
    parts = []
    if all(metric_of(study, shipped, log, 'nis_zupt') < NIS_DOF['zupt'] / SEVERAL for log in logs) \
            and math.isfinite(low):
        parts.append('ZUPT is over-conservative (its 0.01 m/s sigma is large against a rover '
                     'at rest)')
    high = [k for k in _NIS_CAUSE if all(
        metric_of(study, c, log, f'nis_{k}') > SEVERAL * NIS_DOF[k]
        for c in study.configs for log in logs)]
    if high:
        names = ' and '.join(k.upper() for k in high)
        both = len(high) > 1
        parts.append(f'{names} residuals are several times their expectation in every '
                     f'configuration: ' + ' and '.join(_NIS_CAUSE[k] for k in high)
                     + f'. The node flags {"both" if both else "it"} in /diagnostics; none of '
                     f'the configurations addresses {"them" if both else "it"}')
    return '; '.join(parts) + '.' if parts else ''


def class_counts(study: Study, variant: str) -> str:
    r = next((x for x in study.results if x.log == RTK_LOG and x.variant == variant), None)
    if r is None:
        return ''
    from slip_estimator.core.types import SLIP_CLASS_NAMES

    cnt = ', '.join(f'{SLIP_CLASS_NAMES[c]} {fmt(r.metrics.get(f"n_truth_{c}"), 0)}'
                    for c in range(5))
    return f'Truth samples per class (10 Hz wheel samples): {cnt}.'


def latency_verdict(study: Study) -> str:
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


def lag_drift_text(study: Study) -> str:
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


SIM_REAL_FACTOR = 2.0
"""A simulated statistic within this factor of the real one, either way, reproduces it: the
spread between the two real logs (docs/sim-vs-real.md) and the sim-vs-real ratios the
simulator's measured grade was accepted on (0.5-2) are of this size."""


def sim_real_verdict(sim: float, real: float) -> str:
    """'reproduced' within :data:`SIM_REAL_FACTOR` of ``real``, else which side differs and by
    how much; 'n/a' without both figures."""
    if not (math.isfinite(sim) and math.isfinite(real)) or real <= 0.0 or sim <= 0.0:
        return 'n/a'
    ratio = sim / real
    if 1.0 / SIM_REAL_FACTOR <= ratio <= SIM_REAL_FACTOR:
        return f'reproduced (within x{SIM_REAL_FACTOR:g})'
    return (f'simulator {"larger" if ratio > 1.0 else "smaller"} by '
            f'x{max(ratio, 1.0 / ratio):.1f}: differs')
