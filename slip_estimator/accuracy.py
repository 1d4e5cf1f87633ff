"""``slip-estimator accuracy``: the slip model's score matrix over many seeded drives.

One drive decides little: a single slip change measured a few cm/s off moves a drive's
balanced accuracy by 0.1-0.3, and a change to the slip model moves individual drives both ways
(measured in session 5: patches drives 0.49-0.86 over 12 seeds of the same code). A model
change is judged on the mean over seeds of every drive family, and on the real test17run log
with the slip injected on either side (:mod:`slip_estimator.effects`), all through the core
with the declared parameters:

short, default   wheel-rate control: the body slows in sand (body-side slip), fixed drives
mixed            body-side slip and wheels spinning up at an unchanged body speed
patches          seeded random drives under wheel-rate control: patches of every class,
                 downhill run-aheads on hills (:func:`slip_estimator.sim.drives.patch_scenario`)
rough            the same on rough ground (terrain undulation, 3x vibration)
skid_steer_30hz, fifty_hz
                 the robot profiles of :mod:`slip_estimator.sim.robots` (consumer 30-Hz IMU
                 starting in motion; 50-Hz industrial IMU), through the core
test17run        plain forward-speed RMSE against RTK; wheel-side, body-side (four window
                 patterns) and mixed injection (four patterns): balanced accuracy and
                 significant-slip F1, and the means over the patterns

Beside every detection figure stands the false-alarm rate: the share of samples whose truth
is low slip (moving, ``|s| <= 0.2``) read medium or worse (:func:`false_alarm_share`).

``--set NAME=VALUE`` overrides a parameter everywhere (to compare a setting without editing
code); ``--json FILE`` writes every figure. Cases run in ``--jobs`` worker processes.
``--bound`` adds, per drive, what a perfect reading of each change could score
(:func:`reading_bound`): the ceiling the drive's IMU sets for any slip model.
"""
from __future__ import annotations

import argparse
import json
import sys
from multiprocessing import Pool
from pathlib import Path
from typing import Any

FAMILIES = ('short', 'default', 'mixed', 'patches', 'rough')
"""The drive families scored by default, in print order (the names of ``sim.bag.SCENARIOS``)."""
ROBOT_FAMILIES = ('skid_steer_30hz', 'fifty_hz', 'skid_steer_30hz_vibrating',
                  'skid_steer_30hz_no_slip')
"""Robot profiles that can be scored as families (``sim.robots.ROBOTS``; the gravity-free one
publishes no slip by design)."""
BOUND_SPAN_S = 1.5
"""Reading span of :func:`reading_bound`: a 1-s transition between two 0.5-s means."""
_BOUND_GRID_S = 0.5
_SETTLED_S = 3.0
"""A reading starts where the truth slip has not changed (by 0.05) for this long before and
until this long after the span: the filter state there is the one a change starts from."""
REAL_CASES = ('wheel', 'body0', 'body1', 'body2', 'body3', 'mixed0', 'mixed1', 'mixed2',
              'mixed3')


def sim_case(family: str, seed: int, overrides: dict[str, Any], bound: bool = False
             ) -> dict[str, Any]:
    """One simulated drive through the core; its slip scored on the simulator truth (with
    ``bound``, also :func:`reading_bound`)."""
    from slip_estimator.effects import score_on_sim
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import SCENARIOS, sim_params

    from slip_estimator.sim.robots import ROBOTS

    if family in ROBOTS:
        profile = ROBOTS[family](seed)
        r = simulate(profile.scenario)
        params = sim_params(r, profile.wheel_input, profile.joint_columns)
    else:
        r = simulate(SCENARIOS[family](seed))
        params = sim_params(r)
    params = params.replace(**overrides)
    s = score_on_sim(r, params).slip
    out = {'family': family, 'seed': seed, 'balanced_accuracy': s.balanced_accuracy,
           'sig_f1': s.significant_f1, 'recall': [float(x) for x in s.recall],
           'slip_z2_mean': s.slip_z2_mean, 'slip_within_3sigma': s.slip_within_3sigma,
           'alarms_at_rest': int(s.counts[2:, 0].sum()),
           'false_alarm': false_alarm_share(s.counts),
           'slip_within_2sigma': s.slip_within_2sigma,
           'p_medium_precision': s.p_medium_precision,
           'n_p_medium_confident': s.n_p_medium_confident}
    if bound:
        out['bound_recall'] = reading_bound(r, params)
    return out


def false_alarm_share(counts: Any) -> float:
    """Share of the samples whose truth is low slip that were read medium or worse, from a
    confusion matrix ``counts[est, truth]`` (classes 0 none .. 4 extreme); NaN without any."""
    low = counts[:, 1].sum()
    return float(counts[2:, 1].sum() / low) if low else float('nan')


def reading_bound(r: Any, params: Any) -> list[float]:
    """Per moving class (low .. extreme) the recall of an oracle that knows every change's
    instant and the true speed before it and reads the change with the filter's free INS over
    ``BOUND_SPAN_S`` (:mod:`slip_estimator.validation.imu_floor`), on the simulated drive
    ``r`` (a ``sim.SimResult``) with ``params``: no slip model that reads each change from
    this IMU does better (the oracle's timing is perfect; no chaining or false alarm counts)."""
    import numpy as np

    from slip_estimator.streams import from_simulation
    from slip_estimator.validation.imu_floor import (class_recall_bound, grid_indices,
                                                    reading_errors)

    data = from_simulation(r, params)
    t = data.imu_ns * 1e-9
    imu_ns = r.stamps_ns(r.imu_t_s)
    v_true = np.interp(data.imu_ns, imu_ns, r.v_ob_b[:, 0])
    speed = np.interp(data.imu_ns, imu_ns, r.speed_mps)
    slip = np.interp(data.imu_ns, r.stamps_ns(r.wheel_t_s), np.nan_to_num(r.slip_true))

    def settled(i: int) -> bool:
        a, b = np.searchsorted(t, [t[i] - _SETTLED_S, t[i] + BOUND_SPAN_S + _SETTLED_S])
        return b < len(t) and np.ptp(slip[a:b]) < 0.05 and speed[a:b].min() > 0.1

    onsets = [i for i in grid_indices(t, _BOUND_GRID_S) if settled(i)]
    errors = reading_errors(params, data, v_true, onsets, (BOUND_SPAN_S,))[0]
    rim = np.asarray(r.rim_speed_true_mps, dtype=float)
    return class_recall_bound(errors, np.asarray(r.slip_true, dtype=float),
                              np.asarray(r.slip_class), rim.mean(axis=1) if rim.ndim > 1 else rim)


def real_case(name: str, log_path: str, overrides: dict[str, Any]) -> dict[str, Any]:
    """test17run plain (``name`` 'plain': forward-speed RMSE) or with injected slip."""
    from slip_estimator import pathfinder as pf
    from slip_estimator.effects import (TEST17RUN_BODY_PATTERNS, TEST17RUN_MIXED_PATTERNS,
                                        TEST17RUN_WINDOWS, score_on_log)

    log = pf.read_pathfinder_mat(log_path)
    params = pf.pathfinder_params(log).replace(**overrides)
    if name == 'plain':
        r = score_on_log(log, params)
        return {'case': name, 'speed_rmse_mps': r.speed_rmse_mps,
                'false_alarm': false_alarm_share(r.slip.counts)}
    if name == 'wheel':
        r = score_on_log(log, params, TEST17RUN_WINDOWS)
    elif name.startswith('mixed'):
        wheel, body = TEST17RUN_MIXED_PATTERNS[int(name[5:])]
        r = score_on_log(log, params, wheel, body_windows=body)
    else:
        r = score_on_log(log, params, (), body_windows=TEST17RUN_BODY_PATTERNS[int(name[4:])])
    return {'case': name, 'balanced_accuracy': r.slip.balanced_accuracy,
            'sig_f1': r.slip.significant_f1, 'speed_rmse_mps': r.speed_rmse_mps,
            'slip_z2_mean': r.slip.slip_z2_mean, 'slip_within_3sigma': r.slip.slip_within_3sigma,
            'false_alarm': false_alarm_share(r.slip.counts)}


def _run(task: tuple) -> dict[str, Any]:
    kind, *args = task
    return sim_case(*args) if kind == 'sim' else real_case(*args)


def score_matrix(families: list[str], seeds: list[int], log_path: Path | None,
                 overrides: dict[str, Any], jobs: int = 2, bound: bool = False
                 ) -> dict[str, Any]:
    """Every (family, seed) drive (with ``bound``, also its reading bound) and, with
    ``log_path``, every test17run case."""
    tasks: list[tuple] = [('sim', f, s, overrides, bound) for f in families for s in seeds]
    if log_path is not None:
        tasks += [('real', c, str(log_path), overrides) for c in ('plain',) + REAL_CASES]
    if jobs > 1:
        with Pool(jobs) as pool:
            results = pool.map(_run, tasks, chunksize=1)
    else:
        results = [_run(t) for t in tasks]
    return {'sim': [r for r in results if 'family' in r],
            'real': [r for r in results if 'case' in r], 'overrides': overrides}


def summary_lines(m: dict[str, Any]) -> list[str]:
    """The printed table: per family the mean and worst balanced accuracy, the mean F1, the
    mean false-alarm share (:func:`false_alarm_share`), how honest the published slip sigma
    is (median over drives of the mean ``z^2``, 1 when honest; mean share within 3 sigma), the
    slip alarms at rest (samples read medium or above where the truth is at rest, summed over
    the drives) and each drive's balanced accuracy; then the calibration of the published
    sigma and probability (mean share of the truth within 2 sigma; the share truly medium or
    worse of all samples published with P(medium+) >= 0.8); then the real cases."""
    lines = []
    families = list(dict.fromkeys(r['family'] for r in m['sim']))
    for f in families:
        rows = [r for r in m['sim'] if r['family'] == f]
        bal = [r['balanced_accuracy'] for r in rows]
        f1 = [r['sig_f1'] for r in rows]
        z2 = sorted(r['slip_z2_mean'] for r in rows)
        in3 = [r['slip_within_3sigma'] for r in rows]
        fa = _nanmean([r['false_alarm'] for r in rows])
        lines.append(f'{f:8s} balanced mean {sum(bal) / len(bal):.3f} min {min(bal):.3f}  '
                     f'F1 mean {sum(f1) / len(f1):.3f}  false alarms {100 * fa:.1f} %  '
                     f'sigma z2 {z2[len(z2) // 2]:.1f} '
                     f'in 3 sigma {sum(in3) / len(in3):.2f}  at-rest alarms '
                     f'{sum(r["alarms_at_rest"] for r in rows)}  per seed '
                     + ' '.join(f'{x:.2f}' for x in bal))
        n_conf = sum(r['n_p_medium_confident'] for r in rows)
        hits = sum(r['p_medium_precision'] * r['n_p_medium_confident'] for r in rows
                   if r['n_p_medium_confident'])
        lines.append(f'{"":8s} calibration: truth within 2 sigma '
                     f'{_nanmean([r["slip_within_2sigma"] for r in rows]):.2f}, '
                     f'P(medium+) >= 0.8 truly medium+ '
                     + (f'{hits / n_conf:.2f} of {n_conf}' if n_conf else 'n/a (none)'))
        if all('bound_recall' in r for r in rows):
            per = [_nanmean([r['bound_recall'][c] for r in rows]) for c in range(4)]
            lines.append(f'{"":8s} reading bound ({BOUND_SPAN_S:.1f} s) recall low/medium/high/'
                         f'extreme ' + ' / '.join(f'{x:.2f}' for x in per)
                         + f', balanced {_nanmean(per):.3f}')
    if m['sim']:
        lines.append(f'all {len(m["sim"])} drives: balanced mean '
                     f'{sum(r["balanced_accuracy"] for r in m["sim"]) / len(m["sim"]):.3f}')
    for r in m['real']:
        if 'balanced_accuracy' in r:
            lines.append(f'test17run {r["case"]:6s} balanced {r["balanced_accuracy"]:.3f} '
                         f'F1 {r["sig_f1"]:.3f}  false alarms {100 * r["false_alarm"]:.1f} %  '
                         f'sigma z2 {r["slip_z2_mean"]:.1f} '
                         f'in 3 sigma {r["slip_within_3sigma"]:.2f}')
        else:
            lines.append(f'test17run plain  forward-speed RMSE {r["speed_rmse_mps"]:.4f} m/s  '
                         f'false alarms {100 * r["false_alarm"]:.1f} %')
    for kind in ('body', 'mixed'):  # one pattern flips on single alarms: judge the mean
        rows = [r for r in m['real'] if r['case'].rstrip('0123456789') == kind
                and 'balanced_accuracy' in r]
        if rows:
            lines.append(f'test17run {kind} patterns: balanced mean '
                         f'{sum(r["balanced_accuracy"] for r in rows) / len(rows):.3f} '
                         f'F1 mean {sum(r["sig_f1"] for r in rows) / len(rows):.3f}')
    return lines


def _value(text: str) -> Any:
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def _nanmean(xs: list[float]) -> float:
    vals = [x for x in xs if x == x]  # NaN: a class the drive did not have
    return sum(vals) / len(vals) if vals else float('nan')


def accuracy_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog='slip-estimator accuracy',
        description='Score the slip model over seeded simulated drives and the real '
                    'test17run log with injected slip (through the core, declared parameters).',
        epilog='example: slip-estimator accuracy --seeds 3')
    ap.add_argument('--families', default=','.join(FAMILIES),
                    help='comma-separated drive families (default: %(default)s; also every '
                         'other scenario of simulate --scenario and the robot profiles '
                         + ', '.join(ROBOT_FAMILIES) + ')')
    ap.add_argument('--seeds', type=int, default=12, help='seeds 0..N-1 per family')
    ap.add_argument('--data-dir', type=Path, default=None,
                    help='folder with test17run.mat (the real cases are skipped without it)')
    ap.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                    help='override a parameter everywhere (repeatable)')
    ap.add_argument('--jobs', type=int, default=2, help='worker processes')
    ap.add_argument('--json', type=Path, help='also write every figure to this file')
    ap.add_argument('--bound', action='store_true',
                    help='also what a perfect reading of each change could score per drive '
                         '(the IMU\'s ceiling for any slip model; ~20 s more per drive)')
    args = ap.parse_args(argv)
    families = [f for f in args.families.split(',') if f]
    from slip_estimator.sim.bag import SCENARIOS
    known = tuple(SCENARIOS) + ROBOT_FAMILIES
    unknown = [f for f in families if f not in known]
    if unknown:
        print(f'slip-estimator accuracy: unknown family {unknown[0]!r} (one of: '
              f'{", ".join(known)})', file=sys.stderr)
        return 2
    overrides = {}
    for item in args.set:
        name, sep, text = item.partition('=')
        if not sep:
            print(f'slip-estimator accuracy: --set needs NAME=VALUE, got {item!r}',
                  file=sys.stderr)
            return 2
        overrides[name.strip()] = _value(text.strip())
    import dataclasses

    from slip_estimator.core.params import Params
    names = {f.name for f in dataclasses.fields(Params)}
    unknown = [n for n in overrides if n not in names]
    if unknown:
        print(f'slip-estimator accuracy: unknown parameter {unknown[0]!r}', file=sys.stderr)
        return 2
    try:
        Params().replace(**overrides)
    except ValueError as exc:
        print(f'slip-estimator accuracy: {exc}', file=sys.stderr)
        return 2
    log_path = None
    if args.data_dir is not None:
        log_path = args.data_dir / 'test17run.mat'
        if not log_path.exists():
            print(f'slip-estimator accuracy: {log_path} not found: real-log cases skipped')
            log_path = None
    m = score_matrix(families, list(range(max(0, args.seeds))), log_path, overrides,
                     max(1, args.jobs), args.bound)
    for line in summary_lines(m):
        print(line)
    if args.json:
        args.json.write_text(json.dumps(m, indent=1))
    return 0
