"""The study: import the logs, replay every (configuration, log, variant) case, evaluate it.

:func:`run_study` returns a :class:`Study` (plain data, no rendering); :meth:`Study.save` /
:meth:`Study.load` write and read it as JSON, so the report can be re-rendered without
re-running (``slip-estimator validate --from-json``).
"""
from __future__ import annotations

import json
import math
import shutil
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from slip_estimator.core.params import Params
from slip_estimator.effects import TEST17RUN_WINDOWS, window_factor
from slip_estimator.validation.case_metrics import (
    low_slip_metrics,
    slip_class_metrics,
    speed_metrics,
    trajectory_metrics,
)
from slip_estimator.validation.configs import (
    CONFIG_BY_KEY,
    DEFAULT_DATA_DIR,
    LOGS,
    RTK_LOG,
    Measured,
    cfg_d,
    say,
)
from slip_estimator.validation.evidence import collect_evidence
from slip_estimator.validation.stop_tilt import submit_closures

@dataclass
class LogInput:
    """An imported log: bag, params, and the plain arrays for the evidence figures."""

    name: str
    bag: Path
    params: Any
    log: Any
    t0_ns: int


def inject_wheel_slip(in_bag: str | Path, out_bag: str | Path, t0_ns: int,
                      windows: Sequence[tuple[float, float, float]] = TEST17RUN_WINDOWS
                      ) -> int:
    """Copy a bag, scaling the ``/joint_states`` velocities by a factor inside time windows.

    The IMU (and GNSS) stay real; a wheel sample whose header stamp lies in
    ``[t0 + start, t0 + end)`` has every velocity multiplied by the window's factor (positions,
    which neither the estimator nor the evaluation use, are left alone). The wheels then turn
    faster than the body moves: injected slip. Returns the number of scaled samples.
    """
    from slip_estimator.bagio import BagWriter, read_messages
    from slip_estimator.ros.stamps import header_stamp_ns

    n = 0
    with BagWriter(out_bag) as writer:
        for m in read_messages(in_bag):
            if m.topic == '/joint_states':
                t = (header_stamp_ns(m.msg) - t0_ns) * 1e-9
                factor = float(window_factor(np.array([t]), windows)[0])
                if factor != 1.0:
                    m.msg.velocity = [float(v) * factor for v in m.msg.velocity]
                    n += 1
            writer.write(m.topic, m.msg, m.log_time_ns)
    return n


def prepare(data_dir: Path, work_dir: Path, logs: Sequence[str], injected: bool,
            progress: bool = True) -> tuple[dict[str, LogInput], Measured, dict[str, Path]]:
    """Import the logs into ``work_dir``, measure lag and radius, write the injected bag."""
    from slip_estimator import pathfinder as pf

    inputs: dict[str, LogInput] = {}
    lag, corr = {}, {}
    for name in logs:
        mat = data_dir / f'{name}.mat'
        if not mat.exists():
            raise FileNotFoundError(f'{mat} not found (real logs live in '
                                    '<repo>/../shared/data/pathfinder)')
        say(progress, f'importing {name}')
        log, _facts, params = pf.import_pathfinder(mat, work_dir / name,
                                                   work_dir / f'{name}.yaml')
        inputs[name] = LogInput(name, work_dir / name, params, log,
                                round(float(log.imu_t_s[0]) * 1e9))
        lag[name], corr[name] = pf.wheel_imu_lag(log)
    if RTK_LOG in inputs:
        ratio = pf.gnss_over_wheel_speed(inputs[RTK_LOG].log)
    else:  # the radius needs RTK; without test17run E falls back to the nominal radius
        ratio = 1.0
    measured = Measured(lag, corr, ratio, float(next(iter(inputs.values())).params.wheel_radius))
    extra: dict[str, Path] = {}
    if injected and RTK_LOG in inputs:
        say(progress, 'writing test17run with injected wheel slip')
        extra[RTK_LOG] = work_dir / f'{RTK_LOG}_injected'
        inject_wheel_slip(inputs[RTK_LOG].bag, extra[RTK_LOG], inputs[RTK_LOG].t0_ns)
    return inputs, measured, extra


@dataclass
class CaseResult:
    """Metrics of one (configuration, log, variant) replay, plus series for the figures."""

    config: str
    log: str
    variant: str            # 'plain' or 'injected'
    overrides: dict[str, Any]
    truth_source: str
    valid: dict[str, bool]
    metrics: dict[str, float]
    recall: list[float]
    confusion_percent: list[list[float]]
    notes: tuple[str, ...]
    wall_s: float
    series: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class CaseTask:
    """Picklable description of one case for a worker process."""

    config: str
    log: str
    variant: str
    input_bag: str
    output_bag: str
    params: dict[str, Any]
    overrides: dict[str, Any]
    truth_lag_s: float
    t0_ns: int


def read_diagnostics(output_bag: str | Path) -> dict[str, float]:
    """Residual statistics from the node's ``/diagnostics``.

    ``nis_mean_<name>`` is the core's exponential average of the NIS (weight 0.02 per update,
    i.e. ~50 updates); its time average over the 1 Hz diagnostics is reported as
    ``nis_<name>``. Counters (``divergence_resets``, ``recoveries``, ``resets``,
    ``covariance_repairs``, ``gated``, updates per kind) are taken from the last message: they
    survive filter resets.
    """
    from slip_estimator.bagio import read_messages
    from slip_estimator.report import number

    nis: dict[str, list[float]] = {}
    last: dict[str, str] = {}
    for m in read_messages(output_bag, {'/diagnostics'}):
        for st in m.msg.status:
            kv = {k.key: k.value for k in st.values}
            if not kv:
                continue
            last.update(kv)
            for k, v in kv.items():
                if k.startswith('nis_mean_'):
                    x = number(v)
                    if math.isfinite(x):
                        nis.setdefault(k[len('nis_mean_'):], []).append(x)
    out = {f'nis_{k}': float(np.mean(v)) for k, v in nis.items()}
    for k in ('zupt', 'zaru', 'nhc', 'wheel'):
        out.setdefault(f'nis_{k}', float('nan'))
    for k in ('divergence_resets', 'recoveries', 'resets', 'covariance_repairs', 'gated',
              'zupt', 'zaru', 'nhc', 'wheel', 'imu_gaps', 'node_resets'):
        out[f'n_{k}'] = number(last.get(k, 'nan'))
    return out


def run_case(task: CaseTask) -> CaseResult:
    """Replay one bag with one configuration and evaluate it (runs in a worker process)."""
    from slip_estimator.evaluation import evaluate_run
    from slip_estimator.replay import replay_bag
    from slip_estimator.report import load_run

    t_start = time.perf_counter()
    params = Params.from_dict(task.params).replace(**task.overrides)
    out_bag = Path(task.output_bag)
    if out_bag.exists():
        shutil.rmtree(out_bag)
    replay_bag(task.input_bag, params, out_bag)
    run = load_run(task.input_bag, out_bag, wheel_radius_m=params.wheel_radius,
                   wheel_joint_names=list(params.wheel_joint_names), progress=False)
    llh0 = np.array([math.radians(params.initial_latitude_deg),
                     math.radians(params.initial_longitude_deg), params.initial_height_m])
    # The truth must not depend on the model: every configuration is scored against the
    # GNSS velocity at the time the wheel sample describes (stamp - measured lag).
    ev = evaluate_run(run, llh0=llh0, moving_threshold_mps=params.moving_speed_threshold_mps,
                      wheel_time_offset_s=-task.truth_lag_s)
    s = ev.slip
    m: dict[str, float] = slip_class_metrics(s) if s is not None else {}
    if ev.speed is not None:
        m['v_rmse_slip'] = ev.speed.rmse
    series: dict[str, np.ndarray] = {}
    if run.est_odom_stamp_ns is not None and ev.truth_p_m is not None:
        speed_metrics(run, ev, task.t0_ns, m, series)
    if ev.trajectory is not None:
        m.update(trajectory_metrics(run, ev))
    if ev.gnss_truth is not None and len(run.est_slip_stamp_ns):
        low_slip_metrics(run, ev.gnss_truth, task.t0_ns, m, series)
    m.update(read_diagnostics(out_bag))
    shutil.rmtree(out_bag, ignore_errors=True)
    recall = [float(x) for x in (s.recall if s is not None else [np.nan] * 5)]
    pct = s.percent.tolist() if s is not None else []
    return CaseResult(task.config, task.log, task.variant, dict(task.overrides),
                      ev.truth_source, dict(ev.valid), m, recall, pct, ev.notes,
                      time.perf_counter() - t_start, series)


@dataclass
class Study:
    """Everything the report needs."""

    configs: list[str]
    logs: list[str]
    measured: Measured
    results: list[CaseResult]
    evidence: dict[str, Any]
    wall_s: float
    jobs: int

    def present(self, log: str, variant: str = 'plain') -> list[tuple[str, CaseResult]]:
        """(configuration key, result) of every configuration run on ``log`` / ``variant``."""
        return [(k, r) for k in self.configs if (r := self.get(k, log, variant)) is not None]

    def get(self, config: str, log: str, variant: str = 'plain') -> CaseResult | None:
        """The result of one case, or None."""
        for r in self.results:
            if (r.config, r.log, r.variant) == (config, log, variant):
                return r
        return None

    def save(self, path: str | Path) -> None:
        """Write the study as JSON (arrays and tuples tagged, so :meth:`load` restores them)."""
        Path(path).write_text(json.dumps(_encode(asdict(self)), indent=None))

    @classmethod
    def load(cls, path: str | Path) -> Study:
        """A study written by :meth:`save`."""
        d = json.loads(Path(path).read_text(), object_hook=_decode)
        d['measured'] = Measured(**d['measured'])
        d['results'] = [CaseResult(**r) for r in d['results']]
        return cls(**d)


def _encode(x: Any) -> Any:
    """JSON-ready copy: ndarray -> {'__ndarray__': list, 'dtype'}, tuple -> {'__tuple__': list},
    numpy scalars -> Python numbers (NaN stays NaN, which :mod:`json` writes and reads)."""
    if isinstance(x, dict):
        return {k: _encode(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return {'__ndarray__': x.tolist(), 'dtype': str(x.dtype)}
    if isinstance(x, tuple):
        return {'__tuple__': [_encode(v) for v in x]}
    if isinstance(x, list):
        return [_encode(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def _decode(d: dict[str, Any]) -> Any:
    if '__ndarray__' in d:
        return np.array(d['__ndarray__'], dtype=d['dtype'])
    if '__tuple__' in d:
        return tuple(d['__tuple__'])
    return d


def run_study(data_dir: Path = DEFAULT_DATA_DIR, work_dir: Path | None = None,
              configs: Sequence[str] = tuple(CONFIG_BY_KEY), logs: Sequence[str] = LOGS,
              injected: bool = True, jobs: int = 2, progress: bool = True,
              evidence_runs: bool = True) -> Study:
    """Run the whole study and return its results (nothing is written but ``work_dir``).

    ``evidence_runs``: also the core-level runs on test17run (release experiment, undeclared
    effects; ~40 s) and the tilt closure at stops on the real logs and simulated drives
    (:mod:`~slip_estimator.validation.stop_tilt`, on ``jobs`` workers)."""
    t_start = time.perf_counter()
    own_tmp = work_dir is None
    work = Path(tempfile.mkdtemp(prefix='slip_validate_')) if own_tmp else Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    try:
        inputs, measured, extra = prepare(Path(data_dir), work, logs, injected, progress)
        results = run_cases(case_tasks(configs, inputs, extra, measured, work), jobs, progress)
        if not evidence_runs:
            evidence = collect_evidence(inputs, measured, results, False, progress)
        else:  # the stop closures' drives run beside the serial core-level evidence runs
            import multiprocessing as mp
            say(progress, 'tilt closure at stops (core: real logs, simulated drives)')
            with ProcessPoolExecutor(max(1, jobs - 1), mp_context=mp.get_context('spawn')
                                     ) as pool:
                stop_tilt = submit_closures(pool, {
                    name: (Path(data_dir) / f'{name}.mat',
                           inp.params.replace(**cfg_d(measured, name)))
                    for name, inp in inputs.items()})
                evidence = collect_evidence(inputs, measured, results, True, progress)
                evidence['stop_tilt'], evidence['reading_error'] = stop_tilt()
        return Study(list(configs), list(inputs), measured, results, evidence,
                     time.perf_counter() - t_start, jobs)
    finally:
        if own_tmp:
            shutil.rmtree(work, ignore_errors=True)


def case_tasks(configs: Sequence[str], inputs: dict[str, LogInput], extra: dict[str, Path],
               measured: Measured, work: Path) -> list[CaseTask]:
    """One task per (configuration, log, variant), longest first so that the two workers
    finish together."""
    tasks = []
    for key in configs:
        spec = CONFIG_BY_KEY[key]
        for name, inp in inputs.items():
            variants = [('plain', inp.bag)]
            if name in extra:
                variants.append(('injected', extra[name]))
            for variant, bag in variants:
                tasks.append(CaseTask(
                    key, name, variant, str(bag), str(work / f'out_{key}_{name}_{variant}'),
                    inp.params.to_dict(), spec.overrides(measured, name),
                    max(measured.lag_s[name], 0.0), inp.t0_ns))
    tasks.sort(key=lambda t: (t.log != 's5t1', t.config))
    return tasks


def run_cases(tasks: Sequence[CaseTask], jobs: int, progress: bool) -> list[CaseResult]:
    """Every task through :func:`run_case`, on ``jobs`` spawned worker processes; results in
    task order."""
    results: list[CaseResult] = []
    say(progress, f'{len(tasks)} replays on {jobs} worker(s)')
    if jobs > 1:
        import multiprocessing as mp
        with ProcessPoolExecutor(jobs, mp_context=mp.get_context('spawn')) as pool:
            done = pool.map(run_case, tasks)
            for r in done:
                results.append(r)
                _say_done(progress, r, len(results), len(tasks))
    else:
        for t in tasks:
            results.append(run_case(t))
            _say_done(progress, results[-1], len(results), len(tasks))
    return results


def _say_done(progress: bool, r: CaseResult, n: int, total: int) -> None:
    say(progress, f'{r.config} {r.log} {r.variant}: done in {r.wall_s:.1f} s ({n}/{total})')
