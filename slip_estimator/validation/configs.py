"""The study's model configurations (A..F) and its fixed inputs.

Each configuration is a set of :class:`~slip_estimator.core.params.Params` overrides on top of
the imported parameters; D and E depend on figures measured from the data (:class:`Measured`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import sys
from pathlib import Path
from typing import Any

from slip_estimator.core.params import Params
from slip_estimator.effects import TEST17RUN_WINDOWS

COMMAND = 'slip-estimator validate --out docs/validation.md'
LOGS = ('test17run', 's5t1')
RTK_LOG = 'test17run'
NS = 1_000_000_000

DEFAULT_DATA_DIR = Path(__file__).resolve().parents[2].parent / 'shared' / 'data' / 'pathfinder'
"""``<repo>/../shared/data/pathfinder``: the logs are read there, never copied into the repo."""

INJECTION_PATTERNS: tuple[tuple[tuple[float, float, float], ...], ...] = (
    TEST17RUN_WINDOWS,
    ((12.0, 22.0, 1.5), (28.0, 34.0, 3.0), (40.0, 48.0, 1.3)),
    ((8.0, 13.0, 2.2), (17.0, 25.0, 1.35), (30.0, 38.0, 1.7), (44.0, 50.0, 4.0)),
    ((7.0, 12.0, 1.3), (15.0, 19.0, 2.8), (24.0, 33.0, 1.5), (38.0, 44.0, 1.3), (47.0, 52.0, 2.0)),
)
"""Injection patterns for the spread of the slip metrics (core runs). The second (the first
study's) puts the x3 window's truth at 0.68, on the 0.7 bound, and the x1.3 window's at 0.23,
near the 0.2 bound; the fourth has windows right after the start and slip steps 4 s apart."""


@dataclass(frozen=True)
class Measured:
    """Figures measured from the data that configurations D and E use.

    Attributes
    ----------
    lag_s : per log, wheel-stamp lag behind the IMU from :func:`pathfinder.wheel_imu_lag`, s.
    lag_corr : per log, correlation at that lag.
    gnss_over_rim : test17run (RTK) GNSS speed / rim speed at the nominal radius.
    wheel_radius_nominal_m : radius of the imported params (0.12 m).
    """

    lag_s: dict[str, float]
    lag_corr: dict[str, float]
    gnss_over_rim: float
    wheel_radius_nominal_m: float

    @property
    def wheel_radius_eff_m(self) -> float:
        """Effective rolling radius from RTK on test17run, m."""
        return self.wheel_radius_nominal_m * self.gnss_over_rim


@dataclass(frozen=True)
class ConfigSpec:
    """One model configuration: a letter, a label, and its Params overrides (may depend on
    the measured figures and the log)."""

    key: str
    label: str
    overrides: Callable[[Measured, str], dict[str, Any]]


def cfg_a(m: Measured, log: str) -> dict[str, Any]:
    return {'wheel_aid': 'off', 'vibration_noise_fraction': 0.0}


def cfg_b(m: Measured, log: str) -> dict[str, Any]:
    # The shipped default fraction of the vibration spread.
    return {'wheel_aid': 'off', 'vibration_noise_fraction': Params().vibration_noise_fraction}


def cfg_c(m: Measured, log: str) -> dict[str, Any]:
    # The hold mode as first built, as closely as the parameters express it: the INS alone
    # measures each change over 1 s (its velocity change taken as measured), no baseline.
    return {**cfg_b(m, log), 'wheel_aid': 'hold', 'slip_measure_s': 1.0,
            'slip_continuity_sigma': 0.0, 'slip_baseline': 'off'}


def cfg_d(m: Measured, log: str) -> dict[str, Any]:
    # The shipped hold mode: velocity continuity across a change and the ground's baseline.
    d = Params()
    return {**cfg_b(m, log), 'wheel_aid': 'hold', 'slip_measure_s': d.slip_measure_s,
            'slip_continuity_sigma': d.slip_continuity_sigma, 'slip_baseline': d.slip_baseline}


def cfg_e(m: Measured, log: str) -> dict[str, Any]:
    return {**cfg_d(m, log), 'wheel_latency_s': round(max(m.lag_s[log], 0.0), 3)}


def cfg_f(m: Measured, log: str) -> dict[str, Any]:
    return {**cfg_d(m, log), 'wheel_radius': round(m.wheel_radius_eff_m, 4)}


CONFIGS: tuple[ConfigSpec, ...] = (
    ConfigSpec('A', 'paper', cfg_a),
    ConfigSpec('B', '+ vibration-aware process noise', cfg_b),
    ConfigSpec('C', '+ hold-mode wheel aid (first design)', cfg_c),
    ConfigSpec('D', '+ slip-change continuity and ground baseline (the shipped slip model)',
               cfg_d),
    ConfigSpec('E', 'D + wheel latency', cfg_e),
    ConfigSpec('F', 'D + effective wheel radius', cfg_f),
)
"""A-D each add one effect to the previous configuration; E and F each add one measured
effect to D (alternatives, not a chain)."""
CONFIG_BY_KEY = {c.key: c for c in CONFIGS}


def say(enabled: bool, text: str) -> None:
    """A progress line of the study on stderr."""
    if enabled:
        print(f'[validate] {text}', file=sys.stderr, flush=True)
