"""Command-line shell of ``slip-estimator evaluate``.

Thin by design (parse arguments, read bags, call :mod:`slip_estimator.evaluation`, draw the
figures of :mod:`slip_estimator.report_figures`, show progress). The bag reader
:func:`load_run` turns an input bag and an estimator output bag into a plain
:class:`~slip_estimator.evaluation.RunData`.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.evaluation import RunData, RunEvaluation
from slip_estimator.ros.stamps import header_stamp_ns

EST_SLIP_TOPIC = '/slip_estimator/slip'
EST_SLIP_VECTOR_TOPIC = '/slip_estimator/slip_ratio'
EST_ODOM_TOPIC = '/slip_estimator/odometry'
TRUTH_SLIP_TOPIC = '/truth/slip'
TRUTH_ODOM_TOPIC = '/truth/odometry'
GNSS_TOPIC = '/gnss/fix'
JOINT_TOPIC = '/joint_states'


class _Progress:
    """Bag-reading progress: messages and seconds of data read (see :mod:`progress`)."""

    def __init__(self, label: str, total_s: float | None, enabled: bool = True) -> None:
        from slip_estimator.progress import Progress

        self.label, self.total_s = label, total_s
        self._line = Progress(enabled)
        self._t0: int | None = None

    def update(self, n: int, log_time_ns: int) -> None:
        if self._t0 is None:
            self._t0 = log_time_ns
        if not self._line.due():
            return
        elapsed = (log_time_ns - self._t0) * 1e-9
        frac = f' {100.0 * elapsed / self.total_s:5.1f}%' if self.total_s else ''
        self._line.show(f'{self.label}: {n} messages, {elapsed:7.1f} s of data{frac}')

    def done(self, n: int) -> None:
        self._line.done(f'{self.label}: {n} messages read')


def first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


def number(text: Any) -> float:
    """A diagnostic value as a float ('unknown', None or garbage: NaN)."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return float('nan')


def _read(path: str | Path, topics: set[str], label: str, progress: bool) -> dict[str, list]:
    from slip_estimator.bagio import bag_duration_s, read_messages

    out: dict[str, list] = {t: [] for t in topics}
    try:
        total = bag_duration_s(path)
    except Exception:  # noqa: BLE001 - progress is cosmetic
        total = None
    bar = _Progress(label, total, progress)
    n = 0
    for m in read_messages(path, topics):
        out[m.topic].append(m.msg)
        n += 1
        bar.update(n, m.log_time_ns)
    bar.done(n)
    return out


def _odometry_arrays(msgs: list) -> tuple[np.ndarray, ...] | tuple[None, ...]:
    if not msgs:
        return None, None, None, None
    t = np.array([header_stamp_ns(m) for m in msgs], dtype=np.int64)
    p = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z]
                  for m in msgs])
    q = np.array([[m.pose.pose.orientation.w, m.pose.pose.orientation.x,
                   m.pose.pose.orientation.y, m.pose.pose.orientation.z] for m in msgs])
    v = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z]
                  for m in msgs])
    o = np.argsort(t, kind='stable')
    return t[o], p[o], q[o], v[o]


def load_run(input_bag: str | Path, output_bag: str | Path, *, wheel_radius_m: float = 0.12,
             wheel_joint_names: list[str] | None = None, progress: bool = True) -> RunData:
    """Arrays of a run: truth/GNSS/wheels from the input bag, estimates from the output bag.

    The estimated slip comes from the ``/slip_estimator/slip`` statuses (one per wheel sample,
    'unknown' values -> NaN, class -1); without them the ``/slip_estimator/slip_ratio`` vectors
    are used (those exist only for known estimates). Rim speeds for the GNSS truth are the mean
    of the named wheel joints (all joints when no names are given) times ``wheel_radius_m``.
    """
    inp = _read(input_bag, {TRUTH_SLIP_TOPIC, TRUTH_ODOM_TOPIC, GNSS_TOPIC, JOINT_TOPIC},
                f'reading {Path(input_bag).name}', progress)
    out = _read(output_bag, {EST_SLIP_TOPIC, EST_SLIP_VECTOR_TOPIC, EST_ODOM_TOPIC},
                f'reading {Path(output_bag).name}', progress)

    rows = []
    for m in out[EST_SLIP_TOPIC]:
        for st in m.status:
            kv = {k.key: k.value for k in st.values}
            if 'slip_ratio' not in kv:
                continue
            cls = number(kv.get('slip_class', 'unknown'))
            rows.append((header_stamp_ns(m), number(kv['slip_ratio']),
                         number(kv.get('slip_ratio_std')),
                         int(cls) if math.isfinite(cls) else -1, number(kv.get('body_speed')),
                         number(kv.get('wheel_speed'))))
            break
    if not rows:
        rows = [(header_stamp_ns(m), m.vector.x, m.vector.y, round(m.vector.z), float('nan'),
                 float('nan')) for m in out[EST_SLIP_VECTOR_TOPIC]]
    rows.sort(key=lambda r: r[0])
    cols = list(zip(*rows)) if rows else [[]] * 6
    est_t = np.array(cols[0], dtype=np.int64)
    est = [np.array(c, dtype=float) for c in cols[1:]]

    eo = _odometry_arrays(out[EST_ODOM_TOPIC])
    to = _odometry_arrays(inp[TRUTH_ODOM_TOPIC])
    ts = sorted(inp[TRUTH_SLIP_TOPIC], key=header_stamp_ns)
    truth_t = np.array([header_stamp_ns(m) for m in ts], dtype=np.int64) if ts else None
    truth_slip = np.array([m.vector.x for m in ts]) if ts else None
    truth_c = np.array([round(m.vector.z) for m in ts]) if ts else None

    gnss = sorted((m for m in inp[GNSS_TOPIC] if m.status.status >= 0), key=header_stamp_ns)
    g_t = g_llh = g_sig = None
    if gnss:
        g_t = np.array([header_stamp_ns(m) for m in gnss], dtype=np.int64)
        g_llh = np.array([[math.radians(m.latitude), math.radians(m.longitude), m.altitude]
                          for m in gnss])
        g_sig = np.array([math.sqrt(0.5 * (m.position_covariance[0] + m.position_covariance[4]))
                          if m.position_covariance_type > 0 else float('nan') for m in gnss])
    w_t = w_v = None
    joints = sorted(inp[JOINT_TOPIC], key=header_stamp_ns)
    if joints:
        names = wheel_joint_names or list(joints[0].name)
        w_t, w_v = [], []
        for m in joints:
            rates = dict(zip(m.name, m.velocity))
            vals = [rates[n] for n in names if n in rates]
            if vals:
                w_t.append(header_stamp_ns(m))
                w_v.append(wheel_radius_m * float(np.mean(vals)))
        w_t, w_v = np.array(w_t, dtype=np.int64), np.array(w_v)
    return RunData(est_t, est[0], est[1], est[2].astype(int) if len(est[2]) else
                   np.zeros(0, int), est[3], est[4], *eo, truth_t, truth_slip, truth_c, *to,
                   g_t, g_llh, g_sig, w_t, w_v)


# --------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------
def _fmt(x: float | None, unit: str = '', digits: int = 3) -> str:
    return 'n/a' if x is None or not math.isfinite(x) else f'{x:.{digits}f}{unit}'


def summary_text(ev: RunEvaluation) -> str:
    """Key figures with the truth they rest on."""
    from slip_estimator.metrics import format_confusion

    lines = [f'truth: {ev.truth_source}   (valid: '
             + ', '.join(f'{k}={"yes" if v else "NO"}' for k, v in ev.valid.items()) + ')']
    lines += [f'  note: {n}' for n in ev.notes]
    if ev.slip is not None:
        s = ev.slip
        lines += ['', 'confusion matrix (rows estimated, columns truth, % of column):',
                  format_confusion(s), '',
                  f'balanced accuracy {_fmt(s.balanced_accuracy)} (strict '
                  f'{_fmt(s.balanced_accuracy_strict)}), coverage {_fmt(s.coverage)}',
                  f'significant slip |s|>0.2: precision {_fmt(s.significant_precision)}, '
                  f'recall {_fmt(s.significant_recall)}, F1 {_fmt(s.significant_f1)}',
                  f'slip MAE {_fmt(s.slip_mae)}  (matched samples {s.n_matched})',
                  f'published slip sigma: mean z^2 {_fmt(s.slip_z2_mean)} (1 when honest), '
                  f'within 3 sigma {_fmt(s.slip_within_3sigma)}']
    if ev.speed is not None:
        lines.append(f'forward speed RMSE {_fmt(ev.speed.rmse, " m/s")}, mean '
                     f'{_fmt(ev.speed.mean, " m/s")} (n={ev.speed.n})')
    if ev.trajectory is not None:
        tr = ev.trajectory
        lines.append(f'position error final {_fmt(tr.final_error_m, " m")}, RMS '
                     f'{_fmt(tr.rms_error_m, " m")}, distance {_fmt(tr.distance_m, " m", 1)}, '
                     f'drift {_fmt(tr.drift_percent, " %", 2)}')
        lines.append(f'heading error RMS {_fmt(tr.heading_rms_deg, " deg", 2)}, final '
                     f'{_fmt(tr.heading_final_deg, " deg", 2)} (truth: {tr.heading_truth})')
    if ev.wheels_gyro is not None:
        wg = ev.wheels_gyro
        lines.append(f'wheels + gyro dead reckoning: position error final '
                     f'{_fmt(wg.final_error_m, " m")}, RMS {_fmt(wg.rms_error_m, " m")}')
    return '\n'.join(lines)


def default_report_dir(estimate: Path) -> Path:
    """Where ``evaluate`` writes without ``--report-dir``: ``ESTIMATE_report`` beside the
    estimate bag (a folder, or a file such as ``run.mcap``)."""
    estimate = Path(estimate)
    stem = estimate.name if estimate.is_dir() else estimate.stem
    return estimate.parent / f'{stem}_report'


def evaluate_main(argv: list[str] | None = None) -> int:
    """Run ``slip-estimator evaluate``; returns the exit code.

    ``slip-estimator evaluate --input IN --estimate OUT [--params F] [--report-dir D] [--json F]``
    (without ``--report-dir``: :func:`default_report_dir`)
    """
    ap = argparse.ArgumentParser(prog='slip-estimator evaluate',
                                 description='Evaluate estimator output against truth '
                                             '(simulation truth or GNSS).',
                                 epilog='example: slip-estimator evaluate --input my_robot.bag '
                                        '--estimate estimate --params my_robot.yaml')
    ap.add_argument('--input', required=True, help='input bag (sensors, truth or /gnss/fix)')
    ap.add_argument('--estimate', required=True, help='estimator output bag (replay)')
    ap.add_argument('--params', help='params file used for the run (wheel radius, joints, '
                                     'origin)')
    ap.add_argument('--report-dir', help='folder for figures and metrics.json (default: '
                                         'ESTIMATE_report next to the estimate bag)')
    ap.add_argument('--json', help='also write the metrics JSON here')
    ap.add_argument('--gnss-window', type=float, default=1.0,
                    help='GNSS velocity fit window, s (default 1.0, for 10 Hz RTK)')
    ap.add_argument('--wheel-time-offset', type=float, default=0.0,
                    help='compare a wheel stamp t with GNSS at t + offset, s (Pathfinder: '
                         'about -0.1 to -0.2)')
    ap.add_argument('--projection', choices=('course', 'estimate'), default='course',
                    help='GNSS truth forward speed: along the GNSS track (default, independent '
                         'of the estimate) or projected on the estimated body x axis')
    ap.add_argument('--no-plots', action='store_true', help='skip the figures')
    ap.add_argument('--quiet', action='store_true', help='no progress line')
    args = ap.parse_args(argv)

    from slip_estimator.bagio import BagError
    from slip_estimator.core.params import ParameterError, Params
    from slip_estimator.evaluation import evaluate_run
    from slip_estimator.paramfile import load_params

    try:
        params = load_params(args.params) if args.params else Params()
        run = load_run(args.input, args.estimate, wheel_radius_m=params.wheel_radius,
                       wheel_joint_names=list(params.wheel_joint_names),
                       progress=not args.quiet)
        if len(run.est_slip_stamp_ns) == 0:
            raise ValueError(f'{args.estimate}: no slip estimates (/slip_estimator/slip) in '
                             'the output bag')
        llh0 = None
        if args.params:
            llh0 = np.array([math.radians(params.initial_latitude_deg),
                             math.radians(params.initial_longitude_deg),
                             params.initial_height_m])
        ev = evaluate_run(run, llh0=llh0, moving_threshold_mps=params.moving_speed_threshold_mps,
                          gnss_window_s=args.gnss_window,
                          wheel_time_offset_s=args.wheel_time_offset,
                          projection=args.projection)
    except (ParameterError, BagError, ValueError) as exc:
        print(f'slip-estimator evaluate: {exc}', file=sys.stderr)
        return 2
    print(summary_text(ev))
    report_dir = (Path(args.report_dir) if args.report_dir
                  else default_report_dir(Path(args.estimate)))
    report_dir.mkdir(parents=True, exist_ok=True)
    metrics = ev.to_dict()
    metrics['input'] = str(args.input)
    metrics['estimate'] = str(args.estimate)
    text = json.dumps(metrics, indent=2)
    (report_dir / 'metrics.json').write_text(text)
    if args.json:
        Path(args.json).write_text(text)
    (report_dir / 'summary.txt').write_text(summary_text(ev) + '\n')
    if args.no_plots:
        if not args.report_dir:  # say where the default put it
            print(f'report: {report_dir} (metrics.json, summary.txt)')
    else:
        try:
            from slip_estimator.report_figures import write_figures

            files = write_figures(run, ev, report_dir)
        except ModuleNotFoundError as exc:
            if exc.name != 'matplotlib':
                raise
            print('figures skipped: matplotlib is not installed (pip install '
                  '"slip_estimator[plots]")', file=sys.stderr)
            return 0
        print(f'report: {report_dir} ({", ".join(f.name for f in files)})')
    return 0
