"""Command-line shells: ``slip-estimator evaluate`` and ``slip-estimator import-pathfinder``.

Thin by design (parse arguments, read bags, call :mod:`slip_estimator.evaluation`, draw plots
with the Agg backend, show progress). The bag reader :func:`load_run` turns an input bag and an
estimator output bag into a plain :class:`~slip_estimator.evaluation.RunData`.
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
from slip_estimator.ros.convert import header_stamp_ns

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


def _first_line(exc: BaseException) -> str:
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
                  f'slip MAE {_fmt(s.slip_mae)}  (matched samples {s.n_matched})']
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
    return '\n'.join(lines)


def evaluate_main(argv: list[str] | None = None) -> int:
    """Run ``slip-estimator evaluate``; returns the exit code.

    ``slip-estimator evaluate --input IN --estimate OUT [--params F] --report-dir D [--json F]``
    """
    ap = argparse.ArgumentParser(prog='slip-estimator evaluate',
                                 description='Evaluate estimator output against truth '
                                             '(simulation truth or GNSS).')
    ap.add_argument('--input', required=True, help='input bag (sensors, truth or /gnss/fix)')
    ap.add_argument('--estimate', required=True, help='estimator output bag (replay)')
    ap.add_argument('--params', help='params file used for the run (wheel radius, joints, '
                                     'origin)')
    ap.add_argument('--report-dir', required=True, help='folder for figures and metrics.json')
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
    report_dir = Path(args.report_dir)
    report_dir.mkdir(parents=True, exist_ok=True)
    metrics = ev.to_dict()
    metrics['input'] = str(args.input)
    metrics['estimate'] = str(args.estimate)
    text = json.dumps(metrics, indent=2)
    (report_dir / 'metrics.json').write_text(text)
    if args.json:
        Path(args.json).write_text(text)
    (report_dir / 'summary.txt').write_text(summary_text(ev) + '\n')
    if not args.no_plots:
        try:
            files = write_figures(run, ev, report_dir)
        except ModuleNotFoundError as exc:
            if exc.name != 'matplotlib':
                raise
            print('figures skipped: matplotlib is not installed (pip install '
                  '"slip_estimator[plots]")', file=sys.stderr)
            return 0
        print(f'report: {report_dir} ({", ".join(f.name for f in files)})')
    return 0


def import_main(argv: list[str] | None = None) -> int:
    """Run ``slip-estimator import-pathfinder FILE.mat --output BAG [--params-out FILE]``."""
    ap = argparse.ArgumentParser(prog='slip-estimator import-pathfinder',
                                 description='Convert a WVU Pathfinder .mat log to an MCAP bag '
                                             'and a params file; prints what was verified.')
    ap.add_argument('mat', help='Pathfinder .mat file (MATLAB v7.3)')
    ap.add_argument('--output', required=True, help='output bag directory (must not exist)')
    ap.add_argument('--params-out', help='write a ROS 2 params file for this log')
    ap.add_argument('--heading', type=float, help='initial heading override, deg cw from north '
                                                  '(default: estimated from GNSS)')
    ap.add_argument('--measured-noise', action='store_true',
                    help='IMU noise densities measured at rest instead of the datasheet')
    ap.add_argument('--measured-lag', action='store_true',
                    help='wheel_latency_s = the wheel-stamp lag measured on the log (default 0)')
    args = ap.parse_args(argv)

    from slip_estimator import pathfinder as pf

    if Path(args.output).exists():
        print(f'slip-estimator import-pathfinder: {args.output} exists', file=sys.stderr)
        return 2
    if not Path(args.mat).is_file():
        print(f'slip-estimator import-pathfinder: {args.mat}: no such file', file=sys.stderr)
        return 2
    try:
        log, facts, params = pf.import_pathfinder(
            args.mat, args.output, args.params_out, measured_noise=args.measured_noise,
            measured_lag=args.measured_lag, heading_deg=args.heading, progress=True)
    except ImportError:
        print('slip-estimator import-pathfinder: needs h5py (pip install '
              '"slip_estimator[pathfinder]" or pip install h5py)', file=sys.stderr)
        return 2
    except (OSError, KeyError, ValueError) as exc:
        print(f'slip-estimator import-pathfinder: {args.mat}: not a Pathfinder .mat log '
              f'(MATLAB v7.3 / HDF5 with tTimu, Ax.., llhGPS): {_first_line(exc)}',
              file=sys.stderr)
        return 2
    print(pf.format_facts(log, facts))
    print(f'wrote {args.output}')
    if args.params_out:
        print(f'params -> {args.params_out} (initial heading {params.initial_heading_deg:.2f} '
              'deg)')
        notes = pf.params_notes(facts, args.measured_noise, args.measured_lag)
        print('\n'.join('  ' + n for n in notes))
    return 0
