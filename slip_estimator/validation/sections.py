"""The report's :class:`Page` and its sections outside the per-effect evidence: header, what
was run, which truth, the before/after tables, trajectories, undeclared effects, what remains
unexplained and the evaluation's notes. Each section takes the page and returns its lines."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from slip_estimator.effects import TEST17RUN_WINDOWS
from slip_estimator.validation.configs import COMMAND, CONFIG_BY_KEY, RTK_LOG
from slip_estimator.validation.sections_evidence import (stop_tilt_section,
                                                         undeclared_section)
from slip_estimator.validation.study import Study
from slip_estimator.validation.tables import (fmt, md_table, metric_of, nav_table, slip_table,
                                              window_table)
from slip_estimator.validation.verdicts import S5T1_NOISE_M, class_counts, nis_text


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


def header(page: Page) -> list[str]:
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


def what_was_run(page: Page) -> list[str]:
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
    lines += md_table(['', 'configuration', 'overrides'], rows)
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


def truth(page: Page) -> list[str]:
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


def before_after(page: Page) -> list[str]:
    """Slip and navigation tables per log and variant."""
    study = page.study
    lines = [
        '### test17run (RTK truth), plain log',
        '',
    ]
    lines += slip_table(study, RTK_LOG, 'plain')
    lines += ['']
    lines += nav_table(study, RTK_LOG, 'plain')
    lines += ['', class_counts(study, 'plain') + ' The plain drive is low slip (firm ground); '
              'the few medium/high/extreme truth samples are starts and stops, where rim and '
              'GNSS speed disagree for a sample or two. Balanced accuracy averages the recall '
              'over the classes present, so a handful of such samples weighs as much as the '
              'whole drive: read it with the counts, and prefer slip MAE, the low-class bias and '
              'the speed error here.', '',
              '### test17run with injected wheel slip (RTK truth)', '']
    lines += slip_table(study, RTK_LOG, 'injected')
    lines += ['']
    lines += nav_table(study, RTK_LOG, 'injected')
    lines += ['', class_counts(study, 'injected'), '',
              ('Median slip inside each window (first 2 s of a window skipped: the estimator '
              'needs `slip_measure_s` to measure a new slip) and on the driving part outside '
              'the windows:'), '']
    lines += window_table(study)
    lines += ['', '### s5t1 (single-point GNSS: coarse metrics only)', '']
    lines += nav_table(study, 's5t1', 'plain', coarse=True)
    lines += ['']
    return lines


def trajectories(page: Page) -> list[str]:
    """The s5t1 trajectory figure."""
    return page.fig('trajectory_s5t1', 's5t1 trajectories')


def undeclared(page: Page) -> list[str]:
    """Undeclared effects."""
    return undeclared_section(page.study.evidence.get('undeclared'))


def stop_tilt(page: Page) -> list[str]:
    """The tilt closure at stops, real against simulated."""
    return stop_tilt_section(page.study.evidence.get('stop_tilt'),
                             page.study.evidence.get('reading_error'))


def unexplained(page: Page) -> list[str]:
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
        nav_txt = '; '.join(f'{k}: up {fmt(v["up_drive_minus_rest"], 3)}, forward '
                            f'{fmt(v["forward_drive"], 3)}' for k, v in nav)
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
             f'{log} NIS ZUPT {fmt(metric_of(study, shipped, log, "nis_zupt"), 2)} (3), ZARU '
             f'{fmt(metric_of(study, shipped, log, "nis_zaru"), 1)} (3), NHC '
             f'{fmt(metric_of(study, shipped, log, "nis_nhc"), 1)} (2), wheel aid '
             f'{fmt(metric_of(study, shipped, log, "nis_wheel"), 2)} (1)'
             for log in study.logs)
         + '. ' + nis_text(study, shipped)),
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


def notes(page: Page) -> list[str]:
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
