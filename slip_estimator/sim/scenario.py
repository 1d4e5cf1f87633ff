"""Configuration of the seeded rover simulator: frozen dataclasses with units in names.

A scenario is a list of driving :class:`Segment` s (body speed, heading rate, slip and wheel
spin targets that the profile blends into at the start of each segment), terrain hills placed
along the path by time, the rover geometry, the IMU error model and two seeds, one for the
truth (terrain undulation, hill placement jitter, low-slip values) and one for the sensor
noise (biases, random walks, white noise, vibration phases, encoder phases, GNSS noise), like
the OpenVINS simulator's separate truth and measurement seeds.

Conventions (see :mod:`slip_estimator.core.frames`): truth is resolved on a flat local tangent
plane with ENU axes at the start position (the ROS ``odom`` frame); base_link is FLU; the IMU
pose in base_link is ``imu_to_base_rpy`` / ``imu_to_base_xyz`` (static transform
base_link -> imu_link). Heading rate ``yaw_rate_rps`` is the rate of the ENU yaw angle
(counter-clockwise positive, like a ROS ``angular.z``).

The seeded drives built from these (``short_scenario`` and the others) live in :mod:`.drives`.

Only the standard library is imported here.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from slip_estimator.sim.imu_grades import ImuErrorConfig, VibrationConfig

__all__ = ['WHEEL_JOINT_NAMES', 'WHEEL_IS_LEFT', 'Segment', 'HillSpec', 'TerrainConfig',
           'RoverConfig', 'VibrationConfig', 'ImuErrorConfig', 'SiteConfig', 'GnssConfig',
           'ScenarioConfig']

WHEEL_JOINT_NAMES = ('front_left_wheel_joint', 'front_right_wheel_joint',
                     'rear_left_wheel_joint', 'rear_right_wheel_joint')
"""Joint names of the four wheels, in the column order of all per-wheel arrays."""
WHEEL_IS_LEFT = (True, False, True, False)
"""Side of each wheel column (front and rear of a side turn at the same speed)."""


@dataclass(frozen=True)
class Segment:
    """One piece of the commanded motion; targets are reached by smooth (C2) ramps.

    Two physical mechanisms, chosen by ``control``:

    * ``'wheel'`` (default): the motor controllers hold the commanded wheel rate, as on every
      planetary rover. ``speed_mps`` is the commanded rim speed r*omega; the terrain's slip
      sets the body speed, v = r*omega (1 - s) for s >= 0 (sand slows the body, s -> 1 is
      stuck with the wheels turning) and v = r*omega / (1 + s) for s < 0 (downhill the body
      runs ahead of its wheels). A slip change therefore shows as a body acceleration the
      IMU sees, over ``slip_ramp_s``, at an unchanged wheel rate;
    * ``'body'``: the body speed is scripted and the wheels spin up: ``speed_mps`` is the
      body speed and rim = v/(1-s) (s >= 0) or v (1+s) (s < 0), plus ``spin_mps``. A slip
      change shows in the encoders at an unchanged body speed.

    Attributes
    ----------
    duration_s : length of the segment, s.
    speed_mps : commanded rim speed (wheel control) or body speed of base_link along its x
        axis (body control), m/s, >= 0.
    yaw_rate_rps : target heading rate (ENU yaw, counter-clockwise positive), rad/s.
    slip : target longitudinal slip s (paper eq. 1); < 0.95 with body control (s = 1 there is
        ``speed_mps=0`` with ``spin_mps>0``), <= 0.98 with wheel control.
    spin_mps : extra rim speed added to every wheel (body control only), m/s, >= 0.
    speed_ramp_s : duration of the speed blend at the segment start, s.
    label : free text used in reports ('stationary', 'cruise', 'turn', 'stop', ...).
    control : 'wheel' or 'body' (see above).
    slip_ramp_s : duration of the slip blend at the segment start, s, in [0.5, 3]: how fast
        the rover enters or leaves a patch of other ground.
    differential_yaw_rps : part of ``yaw_rate_rps`` the wheel differential does not show,
        rad/s: one side on softer ground or a side slope makes the body yaw while the wheels
        turn as for ``yaw_rate_rps - differential_yaw_rps`` (equal to it: the wheels say
        straight while the body yaws).
    grade_driven : a negative slip (wheel control) is a run-ahead that the terrain's downhill
        grade drives: it develops only as far as the local grade exceeds the rolling
        resistance (:mod:`.truth`, step 2), zero on level or nose-up ground. Off: the scripted
        slip regardless of the ground (drives that place it on a known downslope).
    """

    duration_s: float
    speed_mps: float = 0.0
    yaw_rate_rps: float = 0.0
    slip: float = 0.05
    spin_mps: float = 0.0
    speed_ramp_s: float = 2.0
    label: str = ''
    control: str = 'wheel'
    slip_ramp_s: float = 1.5
    differential_yaw_rps: float = 0.0
    grade_driven: bool = False

    def __post_init__(self) -> None:
        if not self.duration_s > 0.0:
            raise ValueError(f'segment {self.label!r}: duration_s must be > 0')
        if self.speed_mps < 0.0 or self.spin_mps < 0.0:
            raise ValueError(f'segment {self.label!r}: speed_mps and spin_mps must be >= 0')
        if self.control not in ('wheel', 'body'):
            raise ValueError(f'segment {self.label!r}: control must be wheel or body')
        if self.control == 'body' and not -1.0 < self.slip < 0.95:
            raise ValueError(f'segment {self.label!r}: slip must be in (-1, 0.95); use '
                             'speed_mps=0 with spin_mps>0 for s=1')
        if self.control == 'wheel' and not (-1.0 < self.slip <= 0.98 and self.spin_mps == 0.0):
            raise ValueError(f'segment {self.label!r}: with wheel control slip must be in '
                             '(-1, 0.98] and spin_mps 0 (the controller holds the rim speed)')
        if not 0.5 <= self.slip_ramp_s <= 3.0:
            raise ValueError(f'segment {self.label!r}: slip_ramp_s must be in [0.5, 3] s')
        if not self.speed_ramp_s > 0.0:
            raise ValueError(f'segment {self.label!r}: speed_ramp_s must be > 0')


@dataclass(frozen=True)
class HillSpec:
    """A Gaussian hill placed where the (flat-ground) path is at ``t_center_s``.

    z(x, y) = height_m * exp(-|p - c|^2 / (2 sigma_m^2)); the maximum slope is about
    0.61 height_m / sigma_m. ``lateral_offset_m`` moves the centre to the left of the path
    (positive) so the rover crosses the flank and rolls.
    """

    t_center_s: float
    height_m: float
    sigma_m: float
    lateral_offset_m: float = 0.0


@dataclass(frozen=True)
class TerrainConfig:
    """Smooth terrain height: hills plus a gentle undulation with seeded phases.

    Attributes
    ----------
    hills : Gaussian hills (see :class:`HillSpec`).
    undulation_amplitude_m : amplitude of each of two crossing sinusoids, m.
    undulation_wavelength_m : their wavelength, m.
    hill_jitter_m : 1-sigma random shift of each hill centre along/across the path (truth seed), m.
    rocking_harmonics : chassis rocking on the ground's small bumps, as multiples of the wheel
        rotation rate: the body's roll and pitch oscillate about the terrain tangent plane
        (real attitude motion, so the gyro and the gravity the accelerometer senses agree),
        each harmonic along a seeded direction in the roll-pitch plane with a seeded phase.
    rocking_rad_per_mps : amplitude of each harmonic per m/s of body speed, rad/(m/s).
    rocking_pivot_depth_m : depth of the rocking axis below base_link, m: base_link (and the
        IMU) swing about it, so the accelerometer also senses the swing's linear acceleration.
    surge_harmonics : fore-aft surge of the chassis on its tyres and suspension, as multiples
        of the wheel rotation rate: base_link (and the IMU) oscillates along its forward axis
        about the path the wheels follow, sum over harmonics m of b_m |v| sin(m phi + phase_m)
        (phi the wheel rotation angle), real motion the accelerometer senses and the rims do
        not, with zero mean displacement (a stop does not close on it).
    surge_m_per_mps : displacement amplitude of each surge harmonic per m/s of body speed,
        m/(m/s); at a steady speed v its displacement RMS is v sqrt(sum b_m^2 / 2) and its
        acceleration amplitude b_m v (m v / r)^2.

    The rocking and the surge default to off (every existing drive keeps its truth); each
    draws from its own stream of the truth seed.
    """

    hills: tuple[HillSpec, ...] = ()
    undulation_amplitude_m: float = 0.1
    undulation_wavelength_m: float = 30.0
    hill_jitter_m: float = 0.5
    rocking_harmonics: tuple[float, ...] = ()
    rocking_rad_per_mps: tuple[float, ...] = ()
    rocking_pivot_depth_m: float = 0.0
    surge_harmonics: tuple[float, ...] = ()
    surge_m_per_mps: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if len(self.rocking_harmonics) != len(self.rocking_rad_per_mps):
            raise ValueError('terrain: one rocking amplitude per rocking harmonic')
        if len(self.surge_harmonics) != len(self.surge_m_per_mps):
            raise ValueError('terrain: one surge amplitude per surge harmonic')

    @classmethod
    def pathfinder_measured(cls, surge: bool = False) -> TerrainConfig:
        """The default undulation with the chassis rocking measured on the real Pathfinder
        (test17run at 0.73 m/s: roll and pitch 0.3-0.7 deg 1-sigma at 1-2 Hz, gyro 0.07-0.1
        rad/s below 8 Hz; ``python -m slip_estimator.validation.sim_vs_real_page``), about an
        axis 0.3 m below base_link.

        ``surge``: also the fore-aft surge fitted to the real logs' forward residual against
        the rims at 1-4 Hz (issue 27, deliverable 4; ``docs/limits.md``, "The chassis
        surge"): twice and three times the wheel rotation rate, 2.7 and 2.2 mm per m/s
        (at 0.73 m/s 1.9 and 2.9 Hz, 0.25 and 0.54 m/s^2, 0.023 m/s RMS)."""
        if surge:
            return dataclasses.replace(cls.pathfinder_measured(), surge_harmonics=(2.0, 3.0),
                                       surge_m_per_mps=(0.0027, 0.0022))
        return cls(rocking_harmonics=(1.0, 2.0), rocking_rad_per_mps=(0.02, 0.016),
                   rocking_pivot_depth_m=0.3)


@dataclass(frozen=True)
class RoverConfig:
    """Rover geometry, IMU mounting and wheel encoders (defaults: WVU Pathfinder).

    Attributes
    ----------
    wheel_radius_m : rolling radius r, m.
    track_width_m : distance between left and right wheel centres, m.
    effective_track_factor : a skid-steer turn needs a wheel differential of yaw rate x
        track x this factor (the wheels scrub sideways; real skid-steer robots: 1.5-1.9).
    imu_to_base_rpy_rad : orientation of imu_link in base_link (roll, pitch, yaw), rad. The
        default (pi, 0, 0) is an x-forward / y-right / z-down sensor.
    imu_to_base_xyz_m : position of imu_link in base_link, m.
    encoder_pulses_per_m : encoder pulses per metre of rim travel.
    """

    wheel_radius_m: float = 0.12
    track_width_m: float = 0.685
    effective_track_factor: float = 1.0
    imu_to_base_rpy_rad: tuple[float, float, float] = (math.pi, 0.0, 0.0)
    imu_to_base_xyz_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    encoder_pulses_per_m: float = 47000.0


@dataclass(frozen=True)
class SiteConfig:
    """Where the rover starts.

    Attributes
    ----------
    latitude_deg, longitude_deg : geodetic start position of base_link, deg.
    height_m : ellipsoidal height of base_link at the start, m.
    heading_deg : initial heading of base_link x, clockwise from true north, deg.
    planet : 'earth', 'mars' or 'moon' (see :mod:`slip_estimator.core.planet`).
    """

    latitude_deg: float = 39.65
    longitude_deg: float = -79.95
    height_m: float = 300.0
    heading_deg: float = 30.0
    planet: str = 'earth'


@dataclass(frozen=True)
class GnssConfig:
    """GNSS fix simulated from truth (antenna at base_link).

    Attributes
    ----------
    rate_hz : fix rate, Hz.
    horizontal_std_m, vertical_std_m : white position noise 1-sigma, m.
    """

    rate_hz: float = 10.0
    horizontal_std_m: float = 0.02
    vertical_std_m: float = 0.04


@dataclass(frozen=True)
class ScenarioConfig:
    """Everything :func:`slip_estimator.sim.rover.simulate` needs.

    Attributes
    ----------
    segments : the commanded motion; the first must be stationary for >= 10 s unless
        ``start_moving``.
    truth_seed : seed of the trajectory/terrain randomness.
    noise_seed : seed of all sensor errors.
    rate_imu_hz, rate_wheel_hz, rate_truth_hz : sample rates, Hz. ``rate_imu_hz *
        oversample`` must be an integer multiple of every other rate.
    oversample : truth is generated at rate_imu_hz * oversample for finite differences.
    duration_s : optional cut of the scenario (None = sum of the segment durations), s.
    epoch_ns : Unix time of t = 0, ns (stamps in the bag).
    start_moving : the rover is already at the first segment's speed, heading rate and slip
        at t = 0 (a log that starts in motion; no initial stationary period is required).
    """

    segments: tuple[Segment, ...]
    truth_seed: int = 0
    noise_seed: int = 1
    rate_imu_hz: float = 250.0
    rate_wheel_hz: float = 10.0
    rate_truth_hz: float = 50.0
    oversample: int = 4
    duration_s: float | None = None
    rover: RoverConfig = field(default_factory=RoverConfig)
    imu: ImuErrorConfig = field(default_factory=ImuErrorConfig)
    site: SiteConfig = field(default_factory=SiteConfig)
    terrain: TerrainConfig = field(default_factory=TerrainConfig)
    gnss: GnssConfig = field(default_factory=GnssConfig)
    epoch_ns: int = 1_700_000_000_000_000_000
    start_moving: bool = False

    def __post_init__(self) -> None:
        if not self.segments:
            raise ValueError('a scenario needs at least one segment')
        first = self.segments[0]
        if self.start_moving:
            pass
        elif first.speed_mps != 0.0 or first.yaw_rate_rps != 0.0 or first.spin_mps != 0.0 \
                or first.duration_s < 10.0:
            raise ValueError('the first segment must be stationary for >= 10 s (alignment)')
        fine = self.rate_imu_hz * self.oversample
        for name in ('rate_imu_hz', 'rate_wheel_hz', 'rate_truth_hz'):
            ratio = fine / getattr(self, name)
            if abs(ratio - round(ratio)) > 1e-9:
                raise ValueError(f'{name} must divide rate_imu_hz * oversample = {fine}')
        ratio = fine / self.gnss.rate_hz
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f'gnss.rate_hz must divide rate_imu_hz * oversample = {fine}')

    @property
    def total_duration_s(self) -> float:
        """Simulated duration, s."""
        total = sum(s.duration_s for s in self.segments)
        return total if self.duration_s is None else min(total, self.duration_s)

    def replace(self, **changes: object) -> ScenarioConfig:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)

