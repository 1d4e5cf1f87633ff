"""The chassis's own motion about the path the wheels roll along, as real truth motion the IMU
sees and the rims do not: rocking in roll and pitch (``TerrainConfig.rocking_harmonics``) and a
fore-aft surge (``TerrainConfig.surge_harmonics``), both harmonics of the wheel rotation with
amplitudes proportional to the speed (:func:`~.truth._truth` adds them to the attitude and the
path). Only the standard library and numpy are imported here.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.sim.kinematics import cumtrapz
from slip_estimator.sim.scenario import ScenarioConfig


def _wheel_angle_rad(cfg: ScenarioConfig, v: np.ndarray, h: float) -> np.ndarray:
    """The wheel rotation angle phi = integral(|v| / r) on the fine grid of step ``h`` s."""
    return cumtrapz(np.abs(v) / cfg.rover.wheel_radius_m, h)


def rocking_rad(cfg: ScenarioConfig, v: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad) of the chassis rocking on the fine grid: sum over harmonics m of
    a_m |v| sin(m phi + phase_m) along a direction in the roll-pitch plane, phi the wheel
    rotation angle."""
    terr = cfg.terrain
    rng = np.random.default_rng([cfg.truth_seed, 1])  # not the hills' and undulation's stream
    phi = _wheel_angle_rad(cfg, v, h)
    d_roll, d_pitch = np.zeros_like(v), np.zeros_like(v)
    for mult, amp in zip(terr.rocking_harmonics, terr.rocking_rad_per_mps):
        phase, direction = rng.uniform(0.0, 2.0 * math.pi, 2)
        wave = amp * np.abs(v) * np.sin(mult * phi + phase)
        d_roll += math.cos(direction) * wave
        d_pitch += math.sin(direction) * wave
    return d_roll, d_pitch


def surge_m(cfg: ScenarioConfig, v: np.ndarray, h: float) -> np.ndarray:
    """Fore-aft displacement (m) of the chassis surge on the fine grid: sum over harmonics m of
    b_m |v| sin(m phi + phase_m), phi as the rocking's."""
    terr = cfg.terrain
    rng = np.random.default_rng([cfg.truth_seed, 2])  # not the rocking's stream
    phi = _wheel_angle_rad(cfg, v, h)
    x = np.zeros_like(v)
    for mult, amp in zip(terr.surge_harmonics, terr.surge_m_per_mps):
        x += amp * np.abs(v) * np.sin(mult * phi + rng.uniform(0.0, 2.0 * math.pi))
    return x
