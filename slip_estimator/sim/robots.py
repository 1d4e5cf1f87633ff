"""Seeded profiles of other robots than the rover: their drives, IMUs, rates and how their
drivers publish (issue 10), for system tests through ``slip-estimator replay``.

A :class:`RobotProfile` is a scenario plus what the bag writer must do to look like that
robot's drivers (wheel input topic, joint states with or without velocities, an IMU driver
that removes gravity). Only the standard library and numpy are imported here.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from slip_estimator.sim.drives import _Builder, no_slip
from slip_estimator.sim.scenario import (
    GnssConfig,
    ImuErrorConfig,
    RoverConfig,
    ScenarioConfig,
    Segment,
    TerrainConfig,
)


@dataclass(frozen=True)
class RobotProfile:
    """A simulated robot as its logs would present it.

    Attributes
    ----------
    name : profile name.
    scenario : the drive, rover geometry, IMU and rates.
    wheel_input : 'odometry' (nav_msgs/Odometry on /wheel/odometry) or 'joint_states'.
    joint_velocities : /joint_states carry velocities (False: positions only).
    joint_columns : which simulated wheel columns the joint states name (a differential
        drive has two wheels).
    imu_gravity_removed : the IMU driver publishes linear acceleration without gravity (not
        REP-145).
    """

    name: str
    scenario: ScenarioConfig
    wheel_input: str = 'joint_states'
    joint_velocities: bool = True
    joint_columns: tuple[int, ...] = (0, 1, 2, 3)
    imu_gravity_removed: bool = False


def _drive(seed: int, legs: list[tuple[float, float, float, float | None, str]]
           ) -> tuple[Segment, ...]:
    """Segments from (duration s, speed m/s, yaw rate rad/s, slip or None for a random low
    slip, label) rows, low slips drawn from the truth seed."""
    b = _Builder(np.random.default_rng(seed))
    for duration_s, speed_mps, yaw_rate_rps, slip, label in legs:
        b.add(duration_s, speed_mps, yaw_rate_rps, slip=slip, label=label)
    return tuple(b.segments)


def consumer_imu(rate_hz: float, accel_std_mps2: float, gyro_std_rps: float) -> ImuErrorConfig:
    """The consumer MEMS profile with its white noise set by the per-sample std at rest at
    ``rate_hz`` (what a user measures on the robot standing still)."""
    return dataclasses.replace(ImuErrorConfig.consumer_mems(),
                               accel_noise_density_mps2_rthz=accel_std_mps2 / math.sqrt(rate_hz),
                               gyro_noise_density_rps_rthz=gyro_std_rps / math.sqrt(rate_hz))


def skid_steer_robot(seed: int = 0) -> RobotProfile:
    """A skid-steer robot moving from its first second, 395 s: consumer IMU at 30 Hz mounted
    sideways (imu x to the left), rest noise 0.05 m/s^2 and 0.02 rad/s, turn-on biases of
    0.5 deg/s and 0.1 m/s^2 (1 sigma), wheel odometry at 10 Hz, an effective track 1.7x the
    geometric one, arcs and slip patches, one 10 s stop after 236 s, GNSS at 10 Hz."""
    rng = np.random.default_rng(seed)
    b = _Builder(rng)
    b.add(12.0, 0.9, label='cruise (log starts here)')
    while b.t_s < 236.0:
        kind = rng.uniform()
        speed = float(rng.uniform(0.6, 1.1))
        if kind < 0.35:
            b.add(float(rng.uniform(8.0, 20.0)), speed, label='cruise')
        elif kind < 0.7:
            yaw = float(rng.choice([-0.4, -0.25, 0.25, 0.4]))
            b.add(float(rng.uniform(4.0, 10.0)), speed, yaw, label='arc')
        else:
            s = float(rng.uniform(0.15, 0.5))
            b.add(float(rng.uniform(5.0, 12.0)), speed, slip=s, label=f'patch s={s:.2f}')
    b.add(12.0, 0.0, label='stop')  # 2 s of braking, 10 s still
    while b.t_s < 395.0:
        speed = float(rng.uniform(0.6, 1.1))
        yaw = float(rng.choice([0.0, 0.0, -0.3, 0.3]))
        b.add(min(float(rng.uniform(6.0, 15.0)), 395.0 - b.t_s + 1.0), speed, yaw,
              label='arc' if yaw else 'cruise')
    rate = 30.0
    cfg = ScenarioConfig(
        tuple(b.segments), truth_seed=seed, noise_seed=seed + 1, rate_imu_hz=rate,
        rate_wheel_hz=10.0, rate_truth_hz=10.0, duration_s=395.0, start_moving=True,
        rover=RoverConfig(wheel_radius_m=0.165, track_width_m=0.555,
                          effective_track_factor=1.7,
                          imu_to_base_rpy_rad=(0.0, 0.0, math.pi / 2),
                          imu_to_base_xyz_m=(0.1, 0.0, 0.2), encoder_pulses_per_m=10000.0),
        imu=consumer_imu(rate, 0.05, 0.02), gnss=GnssConfig(10.0, 0.5, 1.0))
    return RobotProfile('skid_steer_30hz', cfg, wheel_input='odometry')


def fifty_hz_robot(seed: int = 0) -> RobotProfile:
    """IMU and wheel odometry at 50 Hz, an industrial MEMS IMU; stands still 1.2 s, then
    drives for two minutes with arcs, slip patches and two stops."""
    segments = _drive(seed, [
        (1.2, 0.0, 0.0, None, 'stationary'), (20.0, 0.8, 0.0, None, 'cruise'),
        (10.0, 0.8, 0.3, None, 'arc left'), (10.0, 0.8, 0.0, 0.35, 'sand'),
        (4.0, 0.0, 0.0, None, 'stop'), (20.0, 0.7, -0.2, None, 'arc right'),
        (15.0, 0.9, 0.0, 0.5, 'sand, high slip'), (20.0, 0.8, 0.0, None, 'cruise'),
        (4.0, 0.0, 0.0, None, 'stop'), (16.0, 0.6, 0.2, None, 'arc left')])
    cfg = ScenarioConfig(
        segments, truth_seed=seed, noise_seed=seed + 1, rate_imu_hz=50.0,
        rate_wheel_hz=50.0, rate_truth_hz=50.0, start_moving=True,
        rover=RoverConfig(wheel_radius_m=0.1, track_width_m=0.4, effective_track_factor=1.5,
                          imu_to_base_rpy_rad=(0.0, 0.0, 0.0), encoder_pulses_per_m=20000.0),
        imu=ImuErrorConfig.industrial_mems())
    return RobotProfile('fifty_hz', cfg, wheel_input='odometry')


def diff_drive_gravity_free_robot(seed: int = 0) -> RobotProfile:
    """A differential drive (two wheels) whose /joint_states carry positions only and whose
    IMU driver removes gravity: 3 s at rest, then a minute of driving with arcs."""
    segments = _drive(seed, [
        (3.0, 0.0, 0.0, None, 'stationary'), (15.0, 0.5, 0.0, None, 'cruise'),
        (10.0, 0.5, 0.3, None, 'arc left'), (5.0, 0.0, 0.0, None, 'stop'),
        (15.0, 0.6, -0.2, None, 'arc right'), (15.0, 0.5, 0.0, None, 'cruise')])
    cfg = ScenarioConfig(
        segments, truth_seed=seed, noise_seed=seed + 1, rate_imu_hz=100.0,
        rate_wheel_hz=20.0, rate_truth_hz=20.0, start_moving=True,
        rover=RoverConfig(wheel_radius_m=0.05, track_width_m=0.3,
                          imu_to_base_rpy_rad=(0.0, 0.0, 0.0), encoder_pulses_per_m=5000.0),
        imu=ImuErrorConfig.industrial_mems())
    return RobotProfile('diff_drive_gravity_free', cfg, joint_velocities=False,
                        joint_columns=(0, 1), imu_gravity_removed=True)


def rate_sweep_scenario(rate_imu_hz: float, rate_wheel_hz: float,
                        seed: int = 0) -> ScenarioConfig:
    """A 45 s drive (2 s at rest, arcs, a slip patch, a stop) with a consumer IMU at the given
    rates, for rate sweeps (20-1000 Hz IMU, 5-100 Hz wheels)."""
    segments = _drive(seed, [
        (2.0, 0.0, 0.0, None, 'stationary'), (10.0, 0.7, 0.0, None, 'cruise'),
        (8.0, 0.7, 0.3, None, 'arc left'), (8.0, 0.7, 0.0, 0.4, 'sand'),
        (4.0, 0.0, 0.0, None, 'stop'), (13.0, 0.6, -0.2, None, 'arc right')])
    lcm = math.lcm(int(rate_imu_hz), int(rate_wheel_hz), 10)
    oversample = max(4, lcm // int(rate_imu_hz))
    return ScenarioConfig(segments, truth_seed=seed, noise_seed=seed + 1,
                          rate_imu_hz=rate_imu_hz, rate_wheel_hz=rate_wheel_hz,
                          rate_truth_hz=10.0, oversample=oversample, start_moving=True,
                          imu=consumer_imu(rate_imu_hz, 0.05, 0.02))


def vibrating_robot(seed: int = 0) -> RobotProfile:
    """The skid-steer robot of :func:`skid_steer_robot` (same drive, geometry and 30-Hz
    rates) with :meth:`ImuErrorConfig.consumer_mems_vibrating`: misalignment, bias
    instability, g-sensitivity, the Pathfinder's measured driving vibration and tilt wander,
    and a 70-Hz resonance folded to 10 Hz by the 30-Hz sampling, on ground that rocks the
    chassis like the Pathfinder's (:meth:`TerrainConfig.pathfinder_measured`); the rest noise
    is the same 0.05 m/s^2 and 0.02 rad/s."""
    base = skid_steer_robot(seed)
    imu = dataclasses.replace(ImuErrorConfig.consumer_mems_vibrating(),
                              accel_noise_density_mps2_rthz=0.05 / math.sqrt(30.0),
                              gyro_noise_density_rps_rthz=0.02 / math.sqrt(30.0))
    return dataclasses.replace(base, name='skid_steer_30hz_vibrating',
                               scenario=base.scenario.replace(
                                   imu=imu, terrain=TerrainConfig.pathfinder_measured()))


def no_slip_robot(seed: int = 0) -> RobotProfile:
    """:func:`vibrating_robot` over ground that shows no slip at all
    (:func:`~slip_estimator.sim.drives.no_slip`): the false-alarm rate of a consumer IMU."""
    base = vibrating_robot(seed)
    return dataclasses.replace(base, name='skid_steer_30hz_no_slip',
                               scenario=no_slip(base.scenario))


ROBOTS = {'skid_steer_30hz': skid_steer_robot, 'fifty_hz': fifty_hz_robot,
          'diff_drive_gravity_free': diff_drive_gravity_free_robot,
          'skid_steer_30hz_vibrating': vibrating_robot, 'skid_steer_30hz_no_slip': no_slip_robot}
"""The robot profiles by name (each a function of the truth seed)."""
