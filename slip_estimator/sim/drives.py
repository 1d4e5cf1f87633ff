"""The seeded drives of the rover simulator: scenario builders from a truth seed.

:func:`short_scenario` (~90 s), :func:`default_scenario` (~6.5 min, every slip class),
:func:`mixed_scenario` (wheel- and body-control slip) and :func:`patch_scenario` (a random
drive over slip patches and downhill runs) build a :class:`~.scenario.ScenarioConfig` from
driving segments and hills placed by time (:class:`_Builder`, also used by :mod:`.robots`).
:func:`straight_scenario` is the real test17run's shape (rest, 52 s straight, rest) for
comparing the simulated IMU with the real one; :func:`no_slip` turns any drive into one over
ground that shows no slip at all (for the false-alarm rate), :func:`measured_ground` into one
with the IMU mechanisms and chassis rocking measured on the real Pathfinder.

Only the standard library and numpy are imported here.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from slip_estimator.sim.scenario import HillSpec, ScenarioConfig, Segment, TerrainConfig


def _low_slip(rng: np.random.Generator) -> float:
    # Realistic low slip on firm soil: a few percent, occasionally near the class edge.
    return float(rng.uniform(0.02, 0.12))


class _Builder:
    """Appends segments and keeps the running time so hills can be placed by time."""

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.segments: list[Segment] = []
        self.hills: list[HillSpec] = []
        self.t_s = 0.0

    def add(self, duration_s: float, speed_mps: float = 0.0, yaw_rate_rps: float = 0.0,
            slip: float | None = None, spin_mps: float = 0.0, label: str = '',
            speed_ramp_s: float = 2.0, control: str = 'wheel', slip_ramp_s: float = 1.5,
            grade_driven: bool = False) -> float:
        s = _low_slip(self.rng) if slip is None else slip
        self.segments.append(Segment(duration_s, speed_mps, yaw_rate_rps, s, spin_mps,
                                     speed_ramp_s, label, control, slip_ramp_s,
                                     grade_driven=grade_driven))
        t0 = self.t_s
        self.t_s += duration_s
        return t0

    def hill(self, t_center_s: float, height_m: float, sigma_m: float,
             lateral_offset_m: float = 0.0) -> None:
        self.hills.append(HillSpec(t_center_s, height_m, sigma_m, lateral_offset_m))


def short_scenario(seed: int = 0, noise_seed: int | None = None) -> ScenarioConfig:
    """About 90 s of wheel-rate control: alignment, a turn, a hill, stops and medium, high and
    extreme slip (the body slowing at held wheel rates), a downhill run-ahead, stuck.

    ``seed`` is the truth seed; the noise seed defaults to ``seed + 1``.
    """
    b = _Builder(np.random.default_rng(seed))
    b.add(12.0, label='stationary')
    b.add(8.0, 0.5, label='accelerate')
    b.add(8.0, 0.5, label='cruise')
    b.add(6.0, 0.5, 0.25, label='arc left')
    t_up = b.add(8.0, 0.55, slip=0.3, label='uphill medium slip')
    b.add(6.0, 0.4, slip=-0.12, label='downhill skid')
    b.hill(t_up + 8.0, 1.2, 4.0, lateral_offset_m=1.5)
    b.add(6.0, 0.55, slip=0.55, label='sand, high slip')
    b.add(5.0, 0.0, label='stop')
    b.add(6.0, 0.3, slip=0.98, speed_ramp_s=1.5, label='stuck, wheels spinning')
    b.add(6.0, 0.6, slip=0.8, label='extreme slip')
    b.add(6.0, 0.5, -0.2, label='arc right')
    b.add(5.0, 0.0, label='stop')
    b.add(5.0, 0.0, 0.5, slip=0.1, label='in-place turn')
    b.add(4.0, 0.0, label='stop')
    return ScenarioConfig(tuple(b.segments), truth_seed=seed,
                          noise_seed=seed + 1 if noise_seed is None else noise_seed,
                          terrain=TerrainConfig(tuple(b.hills)))


def default_scenario(seed: int = 0, noise_seed: int | None = None) -> ScenarioConfig:
    """About 6.5 minutes of wheel-rate control: 15 s alignment, ~5.5 min of driving with every
    slip class.

    Stops (>= 3 s at rest) every 30-60 s of driving, in-place turns, arcs, three hills (one
    crossed on its flank), uphill medium/high slip, downhill negative slip, extreme slip and
    a stuck rover with spinning wheels (s = 1). ``seed`` is the truth seed; the noise seed
    defaults to ``seed + 1``.
    """
    b = _Builder(np.random.default_rng(seed))
    b.add(15.0, label='stationary')
    # leg 1: straight, arc, stop
    b.add(10.0, 0.5, label='accelerate')
    b.add(20.0, 0.5, label='cruise')
    b.add(12.0, 0.5, 0.15, label='arc left')
    b.add(6.0, 0.0, label='stop')
    # leg 2: in-place turn, hill 1 with uphill medium slip and a downhill skid
    b.add(4.0, 0.0, -0.45, slip=0.08, label='in-place turn right')
    b.add(4.0, 0.0, label='stop')
    b.add(10.0, 0.6, label='cruise')
    t_up = b.add(12.0, 0.65, slip=0.3, label='uphill medium slip')
    b.add(4.0, 0.5, label='crest')
    b.add(10.0, 0.5, slip=-0.3, label='downhill skid medium')
    b.add(6.0, 0.5, slip=-0.12, label='downhill skid low')
    b.hill(t_up + 13.0, 3.0, 9.0)
    b.add(6.0, 0.0, label='stop')
    # leg 3: arcs and a sandy patch with high slip, hill 2 crossed on its flank
    b.add(15.0, 0.7, label='cruise')
    t_arc = b.add(15.0, 0.6, -0.1, label='arc right over hill flank')
    b.hill(t_arc + 7.5, 2.0, 8.0, lateral_offset_m=5.0)
    b.add(12.0, 0.75, slip=0.55, label='sand, high slip')
    b.add(10.0, 0.55, slip=0.45, label='sand, high slip')
    b.add(5.0, 0.0, label='stop')
    # leg 4: stuck in sand, wheels spinning, extreme slip while digging out
    b.add(8.0, 0.35, slip=0.98, speed_ramp_s=1.5, label='stuck, wheels spinning')
    b.add(12.0, 0.45, slip=0.78, label='digging out, extreme slip')
    b.add(8.0, 0.55, slip=0.72, label='digging out, extreme slip')
    b.add(5.0, 0.0, label='stop')
    # leg 5: long drive with turns, hill 3, several stops
    b.add(5.0, 0.0, 0.4, slip=0.1, label='in-place turn left')
    b.add(4.0, 0.0, label='stop')
    b.add(20.0, 0.8, label='cruise fast')
    t_h3 = b.add(20.0, 0.5, 0.05, label='arc left uphill')
    b.hill(t_h3 + 14.0, 2.5, 10.0, lateral_offset_m=-2.0)
    b.add(10.0, 0.4, slip=-0.15, label='downhill skid low')
    b.add(6.0, 0.0, label='stop')
    b.add(18.0, 0.6, -0.12, label='arc right')
    b.add(15.0, 0.6, label='cruise')
    b.add(6.0, 0.0, label='stop')
    b.add(20.0, 0.4, 0.05, label='cruise slow')
    b.add(10.0, 0.3, -0.3, label='tight arc right')
    b.add(8.0, 0.0, label='final stop')
    return ScenarioConfig(tuple(b.segments), truth_seed=seed,
                          noise_seed=seed + 1 if noise_seed is None else noise_seed,
                          terrain=TerrainConfig(tuple(b.hills)))


def mixed_scenario(seed: int = 0, noise_seed: int | None = None) -> ScenarioConfig:
    """About 3 minutes mixing both mechanisms: sand patches that slow the body at held wheel
    rates (wheel control) and patches where the wheels spin up at an unchanged body speed
    (body control), with arcs and stops."""
    b = _Builder(np.random.default_rng(seed))
    b.add(12.0, label='stationary')
    b.add(10.0, 0.6, label='start')
    b.add(10.0, 0.6, slip=0.35, label='sand, body slows (medium)')
    b.add(10.0, 0.6, 0.1, label='arc')
    b.add(10.0, 0.45, slip=0.5, control='body', label='wheels spin up (high)')
    b.add(10.0, 0.45, control='body', label='firm ground')
    b.add(5.0, 0.0, control='body', label='stop')
    b.add(10.0, 0.6, label='start')
    b.add(10.0, 0.6, slip=0.6, label='sand, body slows (high)')
    b.add(10.0, 0.6, -0.1, label='arc')
    b.add(10.0, 0.3, slip=0.8, control='body', label='wheels dig in (extreme)')
    b.add(10.0, 0.3, slip=0.3, control='body', label='wheels spin (medium)')
    b.add(10.0, 0.5, control='body', label='firm ground')
    b.add(5.0, 0.0, label='stop')
    b.add(10.0, 0.6, label='start')
    b.add(10.0, 0.6, slip=0.85, label='sand, nearly stuck (extreme)')
    b.add(10.0, 0.6, label='firm ground')
    b.add(6.0, 0.0, label='final stop')
    return ScenarioConfig(tuple(b.segments), truth_seed=seed,
                          noise_seed=seed + 1 if noise_seed is None else noise_seed)


def patch_scenario(seed: int = 0, duration_s: float = 600.0, rough: bool = False,
                   noise_seed: int | None = None) -> ScenarioConfig:
    """A seeded random drive under wheel-rate control: legs of 30-60 s between stops, arcs,
    patches of 5-20 s whose slip is drawn across every class (0.1-0.85) and downhill runs
    (-0.15 to -0.3, developed as far as the local downhill grade drives the body ahead: see
    :mod:`.truth`) on hills placed under them; ``rough`` raises the terrain undulation and
    the vibration (rough ground)."""
    rng = np.random.default_rng(seed)
    b = _Builder(rng)
    b.add(12.0, label='stationary')
    while b.t_s < duration_s - 20.0:
        leg_end = b.t_s + rng.uniform(30.0, 60.0)
        speed = float(rng.uniform(0.4, 0.8))
        b.add(6.0, speed, label='start')
        last = 'start'
        while b.t_s < leg_end:
            kind = rng.uniform()
            yaw = float(rng.choice([0.0, 0.0, 0.1, -0.1, 0.2, -0.2]))
            if kind < 0.4 or last == 'downhill':
                b.add(float(rng.uniform(5.0, 15.0)), speed, yaw, label='firm ground')
                last = 'firm'
            elif kind < 0.85:
                s = float(rng.uniform(0.1, 0.85))
                b.add(float(rng.uniform(5.0, 20.0)), speed, yaw, slip=s,
                      slip_ramp_s=float(rng.uniform(0.5, 3.0)), label=f'patch s={s:.2f}')
                last = 'patch'
            else:
                # Down the far flank of a hill (max grade 0.15) whose crest the rover passes
                # half a sigma before the run starts: the body runs ahead of its held wheels
                # only as far as the local downhill grade drives it (truth, step 2).
                s = float(rng.uniform(-0.3, -0.15))
                run_s = float(rng.uniform(6.0, 10.0))
                t0 = b.add(run_s, speed, 0.0, slip=s, slip_ramp_s=1.5,
                           label=f'downhill s={s:.2f}', grade_driven=True)
                sigma_m = 0.6 * speed / (1.0 + s) * run_s
                b.hill(t0 - 0.5 * sigma_m / speed, 0.25 * sigma_m, sigma_m)
                last = 'downhill'
        b.add(float(rng.uniform(3.0, 8.0)), 0.0, label='stop')
    b.add(8.0, label='final stop')
    terrain = TerrainConfig(tuple(b.hills))
    cfg = ScenarioConfig(tuple(b.segments), truth_seed=seed,
                         noise_seed=seed + 1 if noise_seed is None else noise_seed,
                         terrain=terrain)
    if rough:
        cfg = cfg.replace(
            terrain=dataclasses.replace(terrain, undulation_amplitude_m=0.2,
                                        undulation_wavelength_m=10.0),
            imu=dataclasses.replace(cfg.imu, vibration=cfg.imu.vibration.scaled(3.0)))
    return cfg


def no_slip(cfg: ScenarioConfig) -> ScenarioConfig:
    """The same drive over ground that shows no slip at all: every segment's slip, wheel spin
    and differential yaw set to zero, so the mean rim speed equals the body speed and the
    slip truth is 0 wherever the rover moves (hills, turns and vibration kept). For the
    false-alarm rate of a slip model."""
    return cfg.replace(segments=tuple(
        dataclasses.replace(seg, slip=0.0, spin_mps=0.0, differential_yaw_rps=0.0)
        for seg in cfg.segments))


def straight_scenario(seed: int = 0, noise_seed: int | None = None, drive_s: float = 52.0,
                      speed_mps: float = 0.73) -> ScenarioConfig:
    """The real test17run's shape: 10 s at rest, a straight drive of ``drive_s`` at
    ``speed_mps`` over gently undulating ground with a low slip, 15 s at rest. For the same
    statistics on the simulated and the real IMU (:mod:`slip_estimator.validation.sim_vs_real`)."""
    b = _Builder(np.random.default_rng(seed))
    b.add(10.0, label='stationary')
    b.add(drive_s, speed_mps, label='straight drive')
    b.add(15.0, label='stop')
    return ScenarioConfig(tuple(b.segments), truth_seed=seed,
                          noise_seed=seed + 1 if noise_seed is None else noise_seed)


def stop_and_go_scenario(seed: int = 0, noise_seed: int | None = None) -> ScenarioConfig:
    """The real s5t1's shape: 12 s at rest, nine legs of 10-16 s at 0.4-0.7 m/s (straight or
    arcs of up to 0.2 rad/s), each ended by a stop of 2-3.5 s (2 s of it braking), 15 s at
    rest. For the tilt closure at stops on simulated and real drives of the same shape
    (:mod:`slip_estimator.validation.stop_tilt`)."""
    rng = np.random.default_rng(seed)
    b = _Builder(rng)
    b.add(12.0, label='stationary')
    for _ in range(9):
        b.add(float(rng.uniform(10.0, 16.0)), float(rng.uniform(0.4, 0.7)),
              float(rng.choice([0.0, 0.1, -0.1, 0.2, -0.2])), label='leg')
        b.add(float(rng.uniform(2.0, 3.5)), label='stop')
    b.add(15.0, label='final stop')
    return ScenarioConfig(tuple(b.segments), truth_seed=seed,
                          noise_seed=seed + 1 if noise_seed is None else noise_seed)


def measured_ground(cfg: ScenarioConfig, motion_bound: bool = False, surge: bool = False
                    ) -> ScenarioConfig:
    """The same drive with the IMU error mechanisms measured on the real Pathfinder
    (:meth:`~.imu_grades.ImuErrorConfig.pathfinder_measured`, ``motion_bound`` passed on) and
    its chassis rocking (with ``surge`` also its fore-aft surge) added to the drive's own
    terrain (:meth:`~.scenario.TerrainConfig.pathfinder_measured`)."""
    from slip_estimator.sim.imu_grades import ImuErrorConfig

    rock = TerrainConfig.pathfinder_measured(surge)
    return cfg.replace(imu=ImuErrorConfig.pathfinder_measured(motion_bound),
                       terrain=dataclasses.replace(
                           cfg.terrain, rocking_harmonics=rock.rocking_harmonics,
                           rocking_rad_per_mps=rock.rocking_rad_per_mps,
                           surge_harmonics=rock.surge_harmonics,
                           surge_m_per_mps=rock.surge_m_per_mps))
