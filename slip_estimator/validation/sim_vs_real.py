"""The simulated IMU against the real one: the same statistics computed on both.

Each error mechanism of the simulator (:mod:`slip_estimator.sim.sensors`) has a statistic the
real Pathfinder logs show, computed here by one function on a ``streams.SensorData`` (body
frame, the node's view) whatever its source, so the real and the simulated figures cannot be
computed differently:

* sampling: rate and the standard deviation of the sample interval (jitter);
* at the rest after the drive: white scatter and the Allan deviation at a few averaging times
  (white noise falls as tau^-1/2; bias instability flattens it);
* while driving: the scatter of the specific force and rate above ~0.5 Hz (minus a 2-s moving
  mean), the frequency where the gyro's scatter peaks (with a 30-50 Hz IMU, where a
  resonance folds to), the gyro scatter above 8 Hz (vibration, not attitude) and the tilt it
  would integrate over the drive as an angle random walk if it were white down to 0 Hz;
* tilt wander: :func:`~slip_estimator.validation.imu_floor.tilt_closure_between`, the gyro's
  integrated tilt across the drive against accelerometer levelling at the rest after it;
* attitude motion: the spread of the tilt levelled from 1-s means of the specific force while
  driving (the ground's roll and pitch, plus the along-track acceleration the level reading
  cannot tell from tilt: the same on both sources).

:func:`compare` runs them on the real logs and on simulated drives shaped like test17run
(:func:`slip_estimator.sim.drives.straight_scenario`) for several IMU grades and seeds, and
returns a :class:`SimVsReal`; :mod:`.sim_vs_real_page` renders it. Only numpy, the core, the
simulator and the log reader are used.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

MOVING_MPS = 0.02
"""Mean rim speed above which the rover is moving (as :func:`pathfinder.motion_interval`)."""
ALLAN_TAUS_S = (0.1, 1.0, 3.0)
"""Averaging times of the Allan deviation at rest, s (rests last 12-30 s)."""
BAND_S = 2.0
"""Width of the moving mean taken out before the driving scatter, s (leaves > ~0.5 Hz)."""
HF_HZ = 8.0
"""Frequency above which the driving gyro scatter is vibration (the rocking is below), Hz."""
READING_SPAN_S = 1.5
"""Span of the oracle's reading (:data:`imu_floor.BOUND_SPANS_S`' middle one), s."""
REST_S = 12.0
"""Longest part of the rest after the drive used for the rest statistics, s."""


def allan_deviation(x: np.ndarray, dt_s: float, tau_s: float) -> float:
    """Non-overlapping Allan deviation of the samples ``x`` (1-D, spacing ``dt_s``) at
    averaging time ``tau_s``: sqrt(mean((m_k+1 - m_k)^2) / 2) over cluster means m_k of
    round(tau / dt) samples; NaN with fewer than three clusters. White noise of per-sample
    sigma gives sigma / sqrt(m)."""
    m = max(1, int(round(tau_s / dt_s)))
    k = len(x) // m
    if k < 3:
        return math.nan
    means = np.asarray(x[:k * m], dtype=float).reshape(k, m).mean(axis=1)
    return float(math.sqrt(0.5 * np.mean(np.diff(means) ** 2)))


def motion_interval(data: Any) -> tuple[float, float]:
    """First and last wheel time (s, the data's clock) with mean |rim speed| above
    :data:`MOVING_MPS` (for a Pathfinder log this is :func:`pathfinder.motion_interval`)."""
    moving = np.abs(data.rim_mps.mean(axis=1)) > MOVING_MPS
    if not moving.any():
        return math.nan, math.nan
    t = data.wheel_ns[moving] * 1e-9
    return float(t[0]), float(t[-1])


def _moving_mean(x: np.ndarray, n: int) -> np.ndarray:
    k = np.ones(n) / n
    return np.column_stack([np.convolve(x[:, j], k, mode='same') for j in range(x.shape[1])])


def peak_frequency_hz(x: np.ndarray, dt_s: float, min_hz: float = 0.3) -> float:
    """Frequency (Hz) of the largest Hann-windowed power, summed over the columns of ``x``,
    above ``min_hz``."""
    y = (x - x.mean(axis=0)) * np.hanning(len(x))[:, None]
    power = (np.abs(np.fft.rfft(y, axis=0)) ** 2).sum(axis=1)
    freq = np.fft.rfftfreq(len(x), dt_s)
    power[freq < min_hz] = 0.0
    return float(freq[int(np.argmax(power))])


def band_std(x: np.ndarray, dt_s: float, lo_hz: float, hi_hz: float = math.inf) -> np.ndarray:
    """Per column of ``x``, the standard deviation of its content between ``lo_hz`` and
    ``hi_hz`` (an FFT mask over the whole record)."""
    spectrum = np.fft.rfft(x - x.mean(axis=0), axis=0)
    freq = np.fft.rfftfreq(len(x), dt_s)
    spectrum[(freq < lo_hz) | (freq >= hi_hz)] = 0.0
    return np.fft.irfft(spectrum, n=len(x), axis=0).std(axis=0)


def reading_error_mps(params: Any, data: Any, v_true_mps: np.ndarray,
                      span_s: float = READING_SPAN_S) -> float:
    """RMS of the free INS's forward speed change over ``span_s`` less the true one, from
    every 0.1 s while driving faster than 0.4 m/s (the oracle of
    :func:`~slip_estimator.validation.imu_floor.reading_errors`, the shipped filter's state at
    each onset): what a body-side slip reading from this IMU errs by, m/s."""
    from slip_estimator.validation.imu_floor import grid_indices, reading_errors

    t = data.imu_ns * 1e-9
    onsets = [i for i in grid_indices(t, 0.1) if v_true_mps[i] > 0.4]
    errors = reading_errors(params, data, v_true_mps, onsets, (span_s,))[0]
    return float(np.sqrt(np.mean(errors ** 2))) if len(errors) else math.nan


def imu_statistics(data: Any, params: Any = None, v_true_mps: np.ndarray | None = None
                   ) -> dict[str, float]:
    """The statistics of the module docstring for one ``streams.SensorData`` that rests, drives
    and rests again. Keys end in their unit; rates are means over the three axes. With
    ``params`` and the true forward speed at the IMU samples, also the oracle's reading error
    (:func:`reading_error_mps`)."""
    from slip_estimator.core.alignment import level
    from slip_estimator.validation.imu_floor import tilt_closure_between

    t = data.imu_ns * 1e-9
    dt = np.diff(t)
    dt_s = float(np.median(dt))
    t_start, t_end = motion_interval(data)
    out = {'rate_hz': 1.0 / dt_s, 'dt_jitter_ms': float(dt.std() * 1e3),
           'drive_s': t_end - t_start}
    rest = (t > t_end + 1.0) & (t < t_end + 1.0 + REST_S)
    for name, x in (('gyro', data.omega_ib_b), ('accel', data.f_ib_b)):
        unit = 'rps' if name == 'gyro' else 'mps2'
        out[f'{name}_rest_std_{unit}'] = float(x[rest].std(axis=0).mean())
        for tau in ALLAN_TAUS_S:
            out[f'{name}_adev_{tau:g}s_{unit}'] = float(np.mean(
                [allan_deviation(x[rest, j], dt_s, tau) for j in range(3)]))
    n_band = max(1, int(round(BAND_S / dt_s)))
    drive = (t > t_start + 2.0) & (t < t_end - 2.0)
    for name, x in (('gyro', data.omega_ib_b), ('accel', data.f_ib_b)):
        unit = 'rps' if name == 'gyro' else 'mps2'
        band = x - _moving_mean(x, n_band)
        out[f'{name}_drive_std_{unit}'] = float(band[drive].std(axis=0).mean())
    out['gyro_drive_peak_hz'] = peak_frequency_hz(data.omega_ib_b[drive], dt_s)
    # Above HF_HZ the scatter is vibration, not attitude; if it is white down to 0 Hz (sampled
    # without an anti-alias filter) it integrates as an angle random walk over the drive.
    nyquist = 0.5 / dt_s
    hf = float(band_std(data.omega_ib_b[drive], dt_s, HF_HZ).mean()) if nyquist > HF_HZ \
        else math.nan
    out['gyro_drive_hf_std_rps'] = hf
    out['arw_tilt_deg'] = math.degrees(hf / math.sqrt(1.0 - HF_HZ / nyquist)
                                         * math.sqrt(dt_s * (t_end - t_start)))
    f_1s = _moving_mean(data.f_ib_b, max(1, int(round(1.0 / dt_s))))[drive]
    tilt = np.degrees(np.array([level(f) for f in f_1s[::max(1, int(round(0.1 / dt_s)))]]))
    out['roll_spread_deg'], out['pitch_spread_deg'] = (float(s) for s in tilt.std(axis=0))
    closure = tilt_closure_between(data, t_start, t_end)
    out['pitch_wander_deg'] = closure.get('pitch_diff_deg', math.nan)
    out['roll_wander_deg'] = closure.get('roll_diff_deg', math.nan)
    out['reading_error_mps'] = math.nan if v_true_mps is None \
        else reading_error_mps(params, data, v_true_mps)
    return out


@dataclass(frozen=True)
class SourceStats:
    """The statistics of one source: a real log, or one simulated grade over several seeds.

    ``per_run`` holds each run's :func:`imu_statistics`; :attr:`summary` is their mean, with
    the tilt wander as the RMS over runs (its mean is zero by construction)."""

    label: str
    real: bool
    per_run: tuple[dict[str, float], ...]

    @property
    def summary(self) -> dict[str, float]:
        keys = self.per_run[0].keys()
        out = {}
        for k in keys:
            v = np.array([r[k] for r in self.per_run])
            if len(v) == 1 or np.isnan(v).all():
                out[k] = float(v[0])
            elif k.endswith('_wander_deg'):
                out[k] = float(np.sqrt(np.nanmean(v * v)))
            else:
                out[k] = float(np.nanmean(v))
        return out


@dataclass(frozen=True)
class SimVsReal:
    """Every source's statistics and how they were produced (for the page's header)."""

    sources: tuple[SourceStats, ...]
    seeds: tuple[int, ...]
    logs: tuple[str, ...]


def real_stats(log_path: str | Path, rtk: bool = False) -> SourceStats:
    """:func:`imu_statistics` of a real Pathfinder log as the node sees it; with ``rtk`` (a
    log whose GNSS gives velocity truth) the reading error against its 1-s GNSS speed."""
    from slip_estimator.effects import gnss_speed
    from slip_estimator.pathfinder import pathfinder_params, read_pathfinder_mat
    from slip_estimator.streams import from_pathfinder

    log = read_pathfinder_mat(log_path)
    params = pathfinder_params(log)
    data = from_pathfinder(log, params)
    v_true = gnss_speed(log, data.imu_ns * 1e-9) if rtk else None
    return SourceStats(f'real {Path(log_path).stem}', True,
                       (imu_statistics(data, params, v_true),))


def sim_stats(label: str, scenario: Callable[[int], Any], seeds: Sequence[int]) -> SourceStats:
    """:func:`imu_statistics` of the simulated drive ``scenario(seed)`` for each seed."""
    from slip_estimator.sim import simulate
    from slip_estimator.sim.bag import sim_params
    from slip_estimator.streams import from_simulation

    runs = []
    for seed in seeds:
        r = simulate(scenario(seed))
        params = sim_params(r)
        runs.append(imu_statistics(from_simulation(r, params), params, r.speed_mps))
    return SourceStats(label, False, tuple(runs))


def sim_grades() -> dict[str, Callable[[int], Any]]:
    """The simulated sources of the comparison, by label: test17run-shaped drives with the
    default tactical IMU, the measured Pathfinder grade (also with its motion-bound vibration),
    the default on rough ground, and the
    consumer grades at 30 Hz without and with the real mechanisms."""
    import dataclasses

    from slip_estimator.sim.drives import straight_scenario
    from slip_estimator.sim.scenario import ImuErrorConfig, TerrainConfig

    rough = TerrainConfig(undulation_amplitude_m=0.2, undulation_wavelength_m=10.0)

    def grade(imu: ImuErrorConfig, rate_hz: float = 250.0, terrain: TerrainConfig | None = None
              ) -> Callable[[int], Any]:
        def make(seed: int) -> Any:
            cfg = straight_scenario(seed).replace(imu=imu, rate_imu_hz=rate_hz,
                                                  rate_truth_hz=10.0)
            return cfg if terrain is None else cfg.replace(terrain=terrain)
        return make

    rough_vib = dataclasses.replace(ImuErrorConfig(),
                                    vibration=ImuErrorConfig().vibration.scaled(3.0))
    return {
        'sim tactical (default)': grade(ImuErrorConfig.tactical()),
        'sim tactical, rough ground (patches rough)': grade(rough_vib, terrain=rough),
        'sim pathfinder_measured, rocking': grade(ImuErrorConfig.pathfinder_measured(),
                                                  terrain=TerrainConfig.pathfinder_measured()),
        'sim pathfinder_measured motion-bound, rocking': grade(
            ImuErrorConfig.pathfinder_measured(motion_bound=True),
            terrain=TerrainConfig.pathfinder_measured()),
        'sim consumer_mems, 30 Hz': grade(ImuErrorConfig.consumer_mems(), 30.0),
        'sim consumer_mems_vibrating, rocking, 30 Hz': grade(
            ImuErrorConfig.consumer_mems_vibrating(), 30.0, TerrainConfig.pathfinder_measured()),
    }


RTK_LOGS = ('test17run',)
"""Real logs whose GNSS is good enough for velocity truth (s5t1's is single-point)."""


def compare(log_paths: Sequence[str | Path], seeds: Sequence[int] = (0, 1, 2, 3)) -> SimVsReal:
    """The real logs' statistics and every simulated grade's over ``seeds``."""
    sources = [real_stats(p, rtk=Path(p).stem in RTK_LOGS) for p in log_paths]
    sources += [sim_stats(label, make, seeds) for label, make in sim_grades().items()]
    return SimVsReal(tuple(sources), tuple(seeds), tuple(str(Path(p).name) for p in log_paths))
