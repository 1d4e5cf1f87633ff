"""What ``setup`` writes: the parameters from the declared ones and the measured figures,
each with its source (measured / declared / default / bag), and what the user must check.

Rules (pure, no IO):

* topics, wheel input and joint names come from the bag;
* the mounting is the measured one when decided (saying so when the declaration differs), the
  declared one otherwise (saying it could not be decided): never a guess;
* a parameter the user declared stays declared (the measured figure is reported beside it,
  and a check line when they disagree);
* a parameter not declared takes the measured figure where there is one (noise never below the
  defaults: a short rest misses vibration, as the node's own reading of message covariances),
  else the default, said in the report.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.core.params import Params, with_message_noise
from slip_estimator.robot_setup.measure import Measured
from slip_estimator.robot_setup.scan import Scan

MAX_LAG_S = 1.0
RADIUS_RATIO_CHECK = 0.15
"""A GNSS/rim speed ratio further than this from 1 is named (more than steady slip)."""
START_KEYS = ('initial_latitude_deg', 'initial_longitude_deg', 'initial_height_m')
MIN_MEASURED_LAG_S = 0.005


@dataclass
class Proposal:
    """The parameters to write, the source of each (``sources[name]``) and the report's
    lines: ``problems`` (one line each, what is wrong with the robot's data) and ``checks``
    (what could not be decided, what to look at)."""

    params: Params
    sources: dict[str, str]
    problems: list[str] = field(default_factory=list)
    checks: list[str] = field(default_factory=list)


def _deg(rpy: tuple[float, ...] | list[float]) -> str:
    return '(' + ', '.join(f'{math.degrees(a):.0f}' for a in rpy) + ') deg'


def propose(declared: Params, declared_keys: set[str], scan: Scan, m: Measured) -> Proposal:
    """The parameters and the report lines (see the module docstring)."""
    src = {name: ('declared' if name in declared_keys else 'default')
           for name in declared.to_dict()}
    values: dict = {'imu_topic': scan.imu_topic, 'wheel_input': scan.wheel_input}
    values['joint_states_topic' if scan.wheel_input == 'joint_states'
           else 'wheel_odometry_topic'] = scan.wheel_topic
    if scan.joint_names:
        values['wheel_joint_names'] = list(scan.joint_names)
    for k in values:
        src[k] = 'bag: topic found by its type'
    problems, checks = [], list(scan.notes)
    imu = m.imu
    if imu.gravity == 'removed':
        problems.append(f'IMU {scan.imu_topic}: gravity removed (|f| at rest '
                        f'{_norm(imu.f_rest_imu_mps2):.2f} m/s^2, not REP-145): publish the raw '
                        'accelerometer (specific force with gravity)')
    elif imu.gravity == 'in g':
        problems.append(f'IMU {scan.imu_topic}: acceleration in g, not m/s^2 (REP-145): '
                        'scale it by 9.81 in the driver')
    elif imu.gravity == 'scale?':
        problems.append(f'IMU {scan.imu_topic}: |f| at rest {_norm(imu.f_rest_imu_mps2):.2f} '
                        'm/s^2 is not gravity: wrong units or scale')
    elif imu.gravity == 'no rest':
        checks.append('no rest in the log (wheels stopped >= 1.6 s): gravity, noise and bias '
                      'at rest not measured; record 10 s standing still at the start')
    if imu.gyro_units == 'deg/s':
        problems.append(f'IMU {scan.imu_topic}: angular velocity in deg/s, not rad/s (REP-103)')
    for line in imu.clipping:
        problems.append(f'IMU {scan.imu_topic}: {line}')
    mount = m.mounting
    if mount.rpy_rad is not None:
        values['imu_to_base_rpy'] = list(mount.rpy_rad)
        how = 'axis-aligned, exact' if mount.exact else (
            f'yaw +-{mount.yaw_deg.spread:.1f} deg')
        src['imu_to_base_rpy'] = (f'measured: up from {mount.up_from}, forward from the '
                                  f'accelerations ({how}, {mount.yaw_deg.n} samples)')
        if 'imu_to_base_rpy' in declared_keys and _rotation_deg(
                declared.imu_to_base_rpy, mount.rpy_rad) > 5.0:
            problems.append(f'IMU mounting declared {_deg(declared.imu_to_base_rpy)} but '
                            f'measured {_deg(mount.rpy_rad)} ({_turn_words(declared, mount)}): '
                            'the measured one is written')
        elif 'imu_to_base_rpy' not in declared_keys and any(mount.rpy_rad):
            problems.append(f'IMU mounted at {_deg(mount.rpy_rad)} in base_link '
                            f'({_turn_words(declared, mount)}): written')
    else:
        checks.append('IMU mounting NOT decided (' + '; '.join(mount.notes) + f'): kept '
                      f'{src["imu_to_base_rpy"]} {_deg(declared.imu_to_base_rpy)}; check it')
    lag = m.lag_s
    if lag.ok and 'wheel_latency_s' not in declared_keys and lag.value >= MIN_MEASURED_LAG_S:
        values['wheel_latency_s'] = round(min(lag.value, MAX_LAG_S), 3)
        src['wheel_latency_s'] = _fig('measured: yaw rate vs wheel differential', lag, 's')
    elif not lag.ok:
        checks.append(f'wheel-to-IMU lag not measured ({lag.why}): wheel_latency_s '
                      f'{src["wheel_latency_s"]}')
    noise = m.noise
    if noise.accel_density_mps2_rthz.ok:
        keys = ('accel_noise_density_mps2_rthz', 'gyro_noise_density_rps_rthz')
        if not set(keys) & declared_keys:
            raised = with_message_noise(
                Params(), noise.accel_density_mps2_rthz.value ** 2 / m.imu_dt_s,
                noise.gyro_density_rps_rthz.value ** 2 / m.imu_dt_s, m.imu_dt_s,
                raise_only=True)
            for k, fig in zip(keys, (noise.accel_density_mps2_rthz,
                                     noise.gyro_density_rps_rthz)):
                values[k] = getattr(raised, k)
                src[k] = _fig('measured at rest (never below the default)', fig, '')
    track = m.track_m
    if track.ok and 'track_width' not in declared_keys and scan.wheel_input == 'joint_states':
        values['track_width'] = round(track.value, 4)
        src['track_width'] = _fig('measured: effective track in turns', track, 'm')
    elif not track.ok:
        checks.append(f'effective track not measured ({track.why})')
    ratio = m.radius_ratio
    if ratio.ok and 'wheel_radius' not in declared_keys and scan.wheel_input == 'joint_states':
        values['wheel_radius'] = round(declared.wheel_radius * ratio.value, 4)
        src['wheel_radius'] = _fig('measured: default x GNSS/rim speed on straight runs',
                                   ratio, '')
    elif ratio.ok and abs(ratio.value - 1.0) > RADIUS_RATIO_CHECK:
        checks.append(f'GNSS speed / rim speed is {ratio.value:.2f} on straight runs: the '
                      f'effective radius is {declared.wheel_radius * ratio.value:.3f} m against '
                      f'{declared.wheel_radius} m ({src["wheel_radius"]}): check the radius, or '
                      'the ground was soft')
    if ('wheel_radius' not in values and 'wheel_radius' not in declared_keys
            and scan.wheel_input == 'joint_states'):
        checks.append('wheel_radius is the default 0.12 m (not declared, not measured): '
                      'declare it (--declared FILE)')
    start = m.start
    if start.llh_deg_deg_m is not None:
        lat, lon, h = start.llh_deg_deg_m
        for k, v in zip(START_KEYS, (lat, lon, h)):
            if k not in declared_keys:
                values[k] = v
                src[k] = f'measured: first GNSS fix ({scan.gnss_topic})'
        if 'initial_latitude_deg' in declared_keys and abs(
                declared.initial_latitude_deg - lat) + abs(
                declared.initial_longitude_deg - lon) > 1e-3:
            checks.append(f'declared start {declared.initial_latitude_deg:.5f}, '
                          f'{declared.initial_longitude_deg:.5f} deg is not the first fix '
                          f'{lat:.5f}, {lon:.5f} deg (kept)')
    else:
        checks.append('no GNSS fix: initial latitude/height are '
                      f'{src["initial_latitude_deg"]} (they set gravity and the earth rate)')
    if start.heading is not None:
        hd = start.heading
        if 'initial_heading_deg' not in declared_keys:
            values['initial_heading_deg'] = round(hd.heading_deg, 2)
            src['initial_heading_deg'] = (f'measured: GNSS course over {hd.distance_m:.1f} m '
                                          f'({hd.n_fixes} fixes) less the gyro turn')
        elif abs(math.remainder(hd.heading_deg - declared.initial_heading_deg, 360.0)) > 5.0:
            checks.append(f'declared initial heading {declared.initial_heading_deg:.1f} deg, '
                          f'GNSS track says {hd.heading_deg:.1f} deg (kept the declared)')
    elif start.llh_deg_deg_m is not None:
        checks.append(f'initial heading not measured ({start.why})')
    return Proposal(declared.replace(**values), src, problems, checks)


def _norm(v: tuple[float, ...] | None) -> float:
    return math.sqrt(sum(x * x for x in v)) if v else float('nan')


def _fig(what: str, fig: object, unit: str) -> str:
    spread = f' +- {fig.spread:.3g}' if math.isfinite(fig.spread) else ''
    return f'{what}: {fig.value:.4g}{spread} {unit} ({fig.n} samples)'.replace('  ', ' ')


def _rotation_deg(rpy_a: list[float], rpy_b: tuple[float, ...]) -> float:
    """Angle between two mountings, deg."""
    R = rpy_to_dcm(*rpy_a).T @ rpy_to_dcm(*rpy_b)
    return math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))))


def _turn_words(declared: Params, mount: object) -> str:
    """'sideways', 'upside down', ... for a mounting."""
    roll, pitch, yaw = (math.degrees(a) for a in mount.rpy_rad)
    words = []
    if abs(abs(roll) - 180.0) < 10.0 or abs(abs(pitch) - 180.0) < 10.0:
        words.append('upside down')
    elif abs(abs(roll) - 90.0) < 10.0 or abs(abs(pitch) - 90.0) < 10.0:
        words.append('on its side')
    if abs(abs(yaw) - 90.0) < 10.0:
        words.append('yawed 90 deg (sideways)')
    elif abs(abs(yaw) - 180.0) < 10.0:
        words.append('facing backwards')
    return ', '.join(words) or 'tilted'
