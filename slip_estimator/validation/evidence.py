"""Evidence behind the report's statements, measured from the logs and from core runs.

Each function returns plain arrays or dicts; :func:`collect_evidence` gathers them into the
study's ``evidence`` mapping (keys named after the log or configuration they describe).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from slip_estimator.core.params import Params
from slip_estimator.effects import TEST17RUN_BODY_PATTERNS, TEST17RUN_WINDOWS
from slip_estimator.validation.configs import (
    CONFIG_BY_KEY,
    INJECTION_PATTERNS,
    RTK_LOG,
    Measured,
    cfg_a,
    cfg_d,
    say,
)
from slip_estimator.validation.imu_floor import body_side_bound, tilt_closure

if TYPE_CHECKING:
    from slip_estimator.validation.study import CaseResult, LogInput


def collect_evidence(inputs: dict[str, LogInput], measured: Measured,
                     results: Sequence[CaseResult], evidence_runs: bool = True,
                     progress: bool = True) -> dict[str, Any]:
    """Every evidence figure of the study: per log (lag curves, radius ratios, specific force),
    per plain run (attitude-resolved specific force), and, with ``evidence_runs``, the
    core-level runs on test17run (release experiment, undeclared effects, injection patterns,
    body-side slip; ~40 s)."""
    evidence: dict[str, Any] = {}
    for name, inp in inputs.items():
        evidence[f'lag_curve_{name}'] = lag_curve(inp.log)
        evidence[f'accel_lag_curve_{name}'] = accel_lag_curve(inp.log)
        lags, cor = evidence[f'accel_lag_curve_{name}']
        evidence[f'accel_lag_{name}'] = float(lags[np.nanargmax(cor)])
        evidence[f'lag_over_time_{name}'] = lag_over_time(inp.log)
        evidence[f'ratio_samples_{name}'] = speed_ratio_samples(
            inp.log, measured.wheel_radius_nominal_m)
        evidence[f'f_offset_{name}'] = specific_force_offset(inp.log)
    for r in results:
        if r.variant == 'plain' and 'odom_q' in r.series:
            evidence[f'f_nav_{r.config}_{r.log}'] = nav_frame_specific_force(
                inputs[r.log].log, r.series['odom_t'], r.series['odom_q'],
                inputs[r.log].t0_ns * 1e-9)
    if RTK_LOG in inputs and evidence_runs:
        evidence.update(core_runs(inputs[RTK_LOG], measured, progress))
    if RTK_LOG in inputs:
        from slip_estimator import pathfinder as pf
        evidence['ratio_s5t1_single_point'] = (pf.gnss_over_wheel_speed(inputs['s5t1'].log)
                                               if 's5t1' in inputs else float('nan'))
    return evidence


def core_runs(rtk: LogInput, measured: Measured, progress: bool = True) -> dict[str, Any]:
    """The core-level evidence on the RTK log: release experiment, undeclared effects, C vs D
    over the injection patterns, body-side slip (A, D without its body side, D) and what the
    IMU can resolve of it (:mod:`slip_estimator.validation.imu_floor`)."""
    shipped = rtk.params.replace(**cfg_d(measured, RTK_LOG))
    say(progress, 'release experiment and undeclared effects (core, test17run)')
    out: dict[str, Any] = {}
    out['release'] = release_scatter(rtk.log, shipped)
    out['undeclared'] = undeclared_effects(rtk.log, rtk.params)
    out['patterns'] = injection_patterns(rtk.log, {
        k: rtk.params.replace(**CONFIG_BY_KEY[k].overrides(measured, RTK_LOG))
        for k in ('C', 'D')})
    out['imu_speed_scatter'] = imu_speed_scatter(rtk.log, rtk.params)
    out['tilt_closure'] = tilt_closure(rtk.log, shipped)
    out['body_side_bound'] = body_side_bound(
        rtk.log, shipped, [f for pattern in TEST17RUN_BODY_PATTERNS for _, _, f in pattern])
    out['body_side'] = body_side(rtk.log, {
        'A': rtk.params.replace(**cfg_a(measured, RTK_LOG)),
        'D wheel side only': shipped.replace(slip_change_sigma=20.0),
        'D': shipped})
    return out


def _correlation_vs_lag(log: Any, imu_signal: np.ndarray, wheel_signal: np.ndarray,
                        max_lag_s: float, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Correlation of an IMU signal (0.1 s means around each wheel time minus the lag) with a
    wheel signal, for lags in [-max_lag_s, max_lag_s] (wheel stamp t describes IMU time
    t - lag)."""
    from slip_estimator.core.timing import correlation_vs_lag

    t = log.wheel_t_s
    inside = (t > log.imu_t_s[0] + 1.0) & (t < log.imu_t_s[-1] - 1.0)
    lags = np.arange(-max_lag_s, max_lag_s + 1e-9, step_s)
    return lags, correlation_vs_lag(log.imu_t_s, imu_signal, t[inside], wheel_signal[inside],
                                    lags)


def lag_curve(log: Any, max_lag_s: float = 0.4, step_s: float = 0.005
              ) -> tuple[np.ndarray, np.ndarray]:
    """Correlation of the gyro yaw rate with the wheel differential rate vs lag: the curve
    whose peak :func:`pathfinder.wheel_imu_lag` returns (same signal, same sign)."""
    from slip_estimator import pathfinder as pf

    diff = pf.wheel_differential_rps(log)
    return _correlation_vs_lag(log, -log.omega_ib_imu[:, 2], diff, max_lag_s, step_s)


def lag_over_time(log: Any, window_s: float = 30.0, step_s: float = 15.0,
                  min_turn_rps: float = 0.05) -> dict[str, np.ndarray]:
    """The yaw-rate lag of the wheel stamps in sliding windows (``t`` window start s after the
    first IMU sample, ``lag`` s, ``corr``); windows without turning are left out."""
    from slip_estimator import pathfinder as pf
    from slip_estimator.core.timing import best_lag

    t0 = float(log.imu_t_s[0])
    diff = pf.wheel_differential_rps(log)
    rows = []
    for a in np.arange(0.0, float(log.imu_t_s[-1]) - t0 - window_s / 2, step_s):
        w = (log.wheel_t_s >= t0 + a) & (log.wheel_t_s < t0 + a + window_s)
        i = (log.imu_t_s >= t0 + a - 1.0) & (log.imu_t_s < t0 + a + window_s + 1.0)
        if w.sum() < 50 or log.omega_ib_imu[i, 2].std() < min_turn_rps:
            continue
        lag, corr = best_lag(log.imu_t_s[i], -log.omega_ib_imu[i, 2], log.wheel_t_s[w],
                             diff[w])
        rows.append((a, lag, corr))
    out = np.array(rows, dtype=float).reshape(-1, 3)
    return {'t': out[:, 0], 'lag': out[:, 1], 'corr': out[:, 2]}


def accel_lag_curve(log: Any, max_lag_s: float = 0.4, step_s: float = 0.005
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Second, independent lag measure: forward specific force Ax against the derivative of
    the mean wheel rate, vs lag."""
    w = log.wheel_rate_rps.mean(axis=1)
    return _correlation_vs_lag(log, log.f_ib_imu[:, 0], np.gradient(w, log.wheel_t_s),
                               max_lag_s, step_s)


def speed_ratio_samples(log: Any, wheel_radius_m: float, window_s: float = 1.0,
                        min_speed_mps: float = 0.3) -> np.ndarray:
    """GNSS speed / rim speed over 1 s windows while moving (the samples behind
    :func:`pathfinder.gnss_over_wheel_speed`, which is the ratio of their sums)."""
    from slip_estimator import pathfinder as pf

    enu = pf.gnss_enu(log)
    tg = log.gnss_t_s
    tq = np.arange(max(tg[0], log.wheel_t_s[0]) + 1.0, min(tg[-1], log.wheel_t_s[-1]) - 1.0,
                   window_s)

    def pos(tt: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(tt, tg, enu[:, k]) for k in range(2)])

    v_g = np.linalg.norm(pos(tq + window_s / 2) - pos(tq - window_s / 2), axis=1) / window_s
    rim = pf.rim_speed_mps(log, wheel_radius_m)
    c = np.concatenate([[0.0], np.cumsum(rim)])
    i0 = np.searchsorted(log.wheel_t_s, tq - window_s / 2)
    i1 = np.searchsorted(log.wheel_t_s, tq + window_s / 2)
    v_r = (c[i1] - c[i0]) / np.maximum(i1 - i0, 1)
    ok = v_r > min_speed_mps
    return v_g[ok] / v_r[ok]


def specific_force_offset(log: Any) -> dict[str, float]:
    """Mean specific force at rest and while driving (IMU frame, m/s^2).

    ``norm_of_mean`` is |mean f| (vibration averages out), ``mean_of_norm`` is mean |f|
    (vibration rectifies it upwards: not an accelerometer offset), ``forward`` the mean x
    component (depends on the pitch, i.e. on the slope, as well as on any offset).
    """
    from slip_estimator import pathfinder as pf

    rim = pf.rim_speed_mps(log)
    moving = np.interp(log.imu_t_s, log.wheel_t_s, (np.abs(rim) > 0.3).astype(float)) > 0.99
    t0, t1 = pf.motion_interval(log)
    rest = (log.imu_t_s < t0 - 0.5) | (log.imu_t_s > t1 + 1.0)
    f = log.f_ib_imu
    out = {}
    for name, m in (('drive', moving), ('rest', rest)):
        out[f'norm_of_mean_{name}'] = float(np.linalg.norm(f[m].mean(axis=0)))
        out[f'mean_of_norm_{name}'] = float(np.linalg.norm(f[m], axis=1).mean())
        out[f'forward_{name}'] = float(f[m, 0].mean())
        out[f'std_{name}'] = float(f[m].std(axis=0).mean())
    return out


def nav_frame_specific_force(log: Any, odom_t_s: np.ndarray, odom_q_wxyz: np.ndarray,
                             t0_s: float) -> dict[str, float]:
    """Specific force resolved with the ESTIMATED attitude (odometry orientation, ENU) and
    averaged while driving: up component minus its value at rest (an offset the INS integrates
    as vertical acceleration) and the forward-horizontal component (over a drive that starts
    and ends at rest the true mean forward acceleration is ~0, so its mean is an error the INS
    integrates into forward velocity)."""
    from slip_estimator import pathfinder as pf

    t = log.imu_t_s - t0_s
    q = np.asarray(odom_q_wxyz, dtype=float)
    q = q[np.clip(np.searchsorted(odom_t_s, t), 0, len(q) - 1)]
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    R = np.stack([
        np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)]),
        np.column_stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)]),
        np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]),
    ], axis=1)                                            # base_link -> odom (ENU)
    f_base = log.f_ib_imu * np.array([1.0, -1.0, -1.0])  # imu (FRD) -> base_link (FLU)
    f_enu = np.einsum('nij,nj->ni', R, f_base)
    x_h = R[:, :2, 0] / np.linalg.norm(R[:, :2, 0], axis=1, keepdims=True)
    f_fwd = np.einsum('ni,ni->n', f_enu[:, :2], x_h)
    rim = pf.rim_speed_mps(log)
    moving = np.interp(log.imu_t_s, log.wheel_t_s, (np.abs(rim) > 0.05).astype(float)) > 0.99
    a, b = pf.motion_interval(log)
    rest = (log.imu_t_s < a - 0.5) | (log.imu_t_s > b + 1.0)
    return {'up_drive_minus_rest': float(f_enu[moving, 2].mean() - f_enu[rest, 2].mean()),
            'forward_drive': float(f_fwd[moving].mean()),
            'drive_s': float(moving.sum() * np.median(np.diff(log.imu_t_s)))}


def release_scatter(log: Any, params: Params, period_s: float = 3.0, release_s: float = 1.0,
                    starts_s: Sequence[float] = (8.0, 9.5)) -> dict[str, np.ndarray]:
    """How fast the unaided INS loses the forward speed on real data (evidence for D).

    The shipped filter runs on the plain log with the wheel aid switched off for
    ``release_s`` every ``period_s`` (first release at each of ``starts_s`` s after the first
    IMU sample; one run per start, so releases never overlap), and the odometry speed is
    compared with the RTK speed. Returns per release: ``t`` (s), ``aided`` (mean error over the
    0.5 s before, m/s), ``change`` (mean error over 0.25-0.85 s after, minus ``aided``) and
    ``change_early`` (0-0.1 s after, minus ``aided``).
    """
    from slip_estimator import pathfinder as pf
    from slip_estimator.core.estimator import SlipEstimator
    from slip_estimator.effects import run_core
    from slip_estimator.streams import from_pathfinder
    from slip_estimator.truth import gnss_velocity_enu

    t0 = float(log.imu_t_s[0])
    p_enu = pf.gnss_enu(log)
    data = from_pathfinder(log, params)
    t_end = pf.motion_interval(log)[1] - t0 - release_s - 1.0
    rows = []
    for first in starts_s:
        releases = np.arange(first, t_end, period_s)

        class Released(SlipEstimator):
            def _reset_filter(self) -> None:
                super()._reset_filter()
                aid_update = self.wheel_update._aid_update

                def released(z_mps: float, v_hist: float, var: float,
                             excluded: bool = True) -> None:
                    t = self.stamp_ns * 1e-9 - t0
                    k = np.searchsorted(releases, t, side='right') - 1
                    if k < 0 or t - releases[k] >= release_s:
                        aid_update(z_mps, v_hist, var, excluded)
                self.wheel_update._aid_update = released  # type: ignore[method-assign]

        _, _, odo = run_core(params, data, 5, Released)
        t = odo[:, 0] * 1e-9
        err = odo[:, 1] - np.linalg.norm(gnss_velocity_enu(log.gnss_t_s, p_enu, t), axis=1)
        t -= t0
        for tr in releases:
            def mean(a: float, b: float) -> float:
                k = (t >= tr + a) & (t < tr + b)
                return float(np.nanmean(err[k])) if k.any() else math.nan
            rows.append((tr, mean(-0.5, 0.0), mean(0.25, 0.85), mean(0.0, 0.1)))
    r = np.array([x for x in rows if np.isfinite(x).all()]).reshape(-1, 4)
    return {'t': r[:, 0], 'aided': r[:, 1], 'change': r[:, 2] - r[:, 1],
            'change_early': r[:, 3] - r[:, 1]}


def injection_patterns(log: Any, params: dict[str, Params]) -> list[dict[str, Any]]:
    """Slip metrics of each configuration in ``params`` on test17run with each of
    :data:`INJECTION_PATTERNS` (core runs, RTK truth)."""
    from slip_estimator.effects import score_on_log

    out = []
    for pattern in INJECTION_PATTERNS:
        row: dict[str, Any] = {'pattern': pattern}
        for key, p in params.items():
            s = score_on_log(log, p, pattern).slip
            row[key] = {'balanced_accuracy': s.balanced_accuracy,
                        'recall': [float(x) for x in s.recall],
                        'n_truth': [int(x) for x in s.n_truth], 'sig_f1': s.significant_f1,
                        'slip_mae': s.slip_mae}
        out.append(row)
    return out


IMU_SPEED_SCALES_S = (0.5, 1.0, 1.5, 2.0, 3.0, 5.0)
"""Time scales of :func:`imu_speed_scatter`: a slip transition takes 0.5-3 s."""


def imu_speed_scatter(log: Any, params: Params, grid_s: float = 0.1) -> dict[str, list[float]]:
    """How well the IMU alone tells a change of the forward speed on this rover, the signal a
    body-side slip change has to be read from: the forward specific force less gravity (pitch
    from the bias-corrected y gyro, levelled at the initial rest), integrated, against the RTK
    speed change (1-s GNSS differences) and against the rim speed change (both as 0.5-s means)
    over each scale of :data:`IMU_SPEED_SCALES_S`, while driving. The rim-against-RTK spread is
    the floor of the comparison (the references' own noise). Returns per scale the std, 95th
    percentile and largest absolute difference (m/s)."""
    from slip_estimator.effects import gnss_speed
    from slip_estimator.pathfinder import motion_interval
    from slip_estimator.streams import from_pathfinder

    data = from_pathfinder(log, params)
    t = data.imu_ns * 1e-9
    f_b, w_b = data.f_ib_b, data.omega_ib_b
    rest = t < motion_interval(log)[0] - 0.5
    f0 = f_b[rest].mean(axis=0)
    g = float(np.linalg.norm(f0))
    dt = np.gradient(t)
    pitch = math.asin(f0[0] / g) + np.cumsum((w_b[:, 1] - w_b[rest, 1].mean()) * dt)
    u = np.cumsum((f_b[:, 0] - g * np.sin(pitch)) * dt)
    t_g = np.arange(t[0], t[-1], grid_s)
    n_mean = int(round(0.5 / grid_s))
    kernel = np.ones(n_mean) / n_mean
    u_g = np.convolve(np.interp(t_g, t, u), kernel, mode='same')
    rim = np.convolve(np.interp(t_g, data.wheel_ns * 1e-9, data.rim_mps.mean(axis=1)), kernel,
                      mode='same')
    v_rtk = gnss_speed(log, t_g)
    driving = (v_rtk > 0.4) & (rim > 0.5)
    ratio = float(np.median(v_rtk[driving] / rim[driving]))
    out: dict[str, list[float]] = {'scales_s': list(IMU_SPEED_SCALES_S)}
    for name, a, b in (('imu_vs_rtk', u_g, v_rtk), ('imu_vs_rim', u_g, ratio * rim),
                       ('rim_vs_rtk', ratio * rim, v_rtk)):
        for stat in ('std', 'p95', 'max'):
            out[f'{name}_{stat}'] = []
        for scale_s in IMU_SPEED_SCALES_S:
            n = int(round(scale_s / grid_s))
            e = (a[n:] - a[:-n]) - (b[n:] - b[:-n])
            e = np.abs(e[driving[n:] & driving[:-n]])
            out[f'{name}_std'].append(float(np.sqrt(np.mean(e ** 2))))
            out[f'{name}_p95'].append(float(np.percentile(e, 95)))
            out[f'{name}_max'].append(float(e.max()))
    return out


def body_side(log: Any, params: dict[str, Params]) -> list[dict[str, Any]]:
    """Each configuration in ``params`` on test17run with the body slowed in windows at the
    real wheel rates (:data:`effects.TEST17RUN_BODY_PATTERNS`) and with the mixed patterns
    (core runs, RTK truth minus the injected deficit)."""
    from slip_estimator.effects import (TEST17RUN_BODY_PATTERNS, TEST17RUN_MIXED_PATTERNS,
                                        score_on_log)

    cases = [('body', (), pattern) for pattern in TEST17RUN_BODY_PATTERNS]
    cases += [('mixed', wheel, body) for wheel, body in TEST17RUN_MIXED_PATTERNS]
    out = []
    for kind, wheel, body in cases:
        row: dict[str, Any] = {'kind': kind, 'wheel': wheel, 'body': body}
        for key, p in params.items():
            r = score_on_log(log, p, wheel, body_windows=body)
            s = r.slip
            row[key] = {'balanced_accuracy': s.balanced_accuracy,
                        'recall': [float(x) for x in s.recall], 'sig_f1': s.significant_f1,
                        'slip_mae': s.slip_mae, 'v_rmse': r.speed_rmse_mps,
                        'slip_z2': s.slip_z2_mean}
        out.append(row)
    return out


def undeclared_effects(log: Any, params: Params) -> list[dict[str, Any]]:
    """test17run with the injected slip of the tests (:data:`effects.TEST17RUN_WINDOWS`)
    and, one at a time, each undeclared effect, through the core with the imported (declared)
    parameters and the shipped model: slip metrics against RTK and what the node suspects."""
    from slip_estimator.effects import UNDECLARED_EFFECTS, Effects, score_on_log

    out = []
    for e in (Effects(),) + UNDECLARED_EFFECTS + (Effects(wheel_radius_error=0.15),):
        r = score_on_log(log, params, TEST17RUN_WINDOWS, e)
        s = r.slip
        plain = score_on_log(log, params, (), e)
        out.append({'effect': e.label(), 'balanced_accuracy': s.balanced_accuracy,
                    'recall': [float(x) for x in s.recall], 'sig_f1': s.significant_f1,
                    'slip_mae': s.slip_mae, 'v_rmse_injected': r.speed_rmse_mps,
                    'v_rmse_plain': plain.speed_rmse_mps,
                    'suspects': r.estimator.monitor.suspects()})
    return out
