"""The one parameter schema of the estimator and node.

Every parameter is a field of :class:`Params` with a unit, a one-line description and an allowed
range. ``config/slip_estimator.yaml`` mirrors it key for key (a test checks that), the ROS node
declares its parameters from it and the bag replay reads the same YAML.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from typing import Any

PLANETS = ('earth', 'mars', 'moon')
WHEEL_INPUTS = ('odometry', 'joint_states')


class ParameterError(ValueError):
    """An invalid parameter value; the message names the parameter and its allowed range."""


GROUPS = ('rover', 'imu_noise', 'filter', 'detectors', 'slip_model', 'node')
"""The parameter groups, by the part that reads them: the rover and its sensor mounting (the
node's public interface: stream conversion, alignment, odometry), the IMU's noise model (the
filter's process noise, clipping), the filter (initial covariance, pseudo-measurements, gaps
and recovery), the detectors (stationarity, turning, stale wheels), the slip model (wheel aid,
hold mode, slip output and when the rover counts as moving) and the node's outputs."""


def _p(default: Any, unit: str, doc: str, lo: float | None = None, hi: float | None = None,
       choices: tuple[str, ...] | None = None, length: int | None = None, *,
       group: str) -> Any:
    meta = {'unit': unit, 'doc': doc, 'lo': lo, 'hi': hi, 'choices': choices, 'length': length,
            'group': group}
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=meta)
    return field(default=default, metadata=meta)


_rover = functools.partial(_p, group='rover')
_imu = functools.partial(_p, group='imu_noise')
_filter = functools.partial(_p, group='filter')
_detector = functools.partial(_p, group='detectors')
_slip = functools.partial(_p, group='slip_model')
_node = functools.partial(_p, group='node')


def _view(group: str, doc: str) -> property:
    """The read-only attribute of :class:`Params` giving its ``group`` view."""
    return property(lambda params: params.group(group), doc=f'{doc} (frozen view)')


@dataclass(frozen=True)
class Params:
    """Estimator and node parameters (SI units). The node's interface parameters (rover
    geometry, wheel input, IMU mounting, initial pose, planet) keep the names users' launch
    files set; every other physical parameter ends with its unit (``_s``, ``_mps``,
    ``_mps2``, ``_rps``, ``_mps2_rthz`` = m/s^2/sqrt(Hz), ...). One flat schema (the YAML
    mirrors it key for key); each part can take only its group (:attr:`rover`,
    :attr:`imu_noise`, :attr:`filter`, :attr:`detectors`, :attr:`slip_model`, :attr:`node`)."""

    # --- rover: geometry and wheel input -------------------------------------------------------
    wheel_radius: float = _rover(0.12, 'm', 'effective rolling radius of the wheels', 0.01, 5.0)
    track_width: float = _rover(0.685, 'm', 'lateral distance between left and right wheel '
                                'centres', 0.05, 10.0)
    wheel_input: str = _rover('joint_states', '', 'wheel source: odometry (/wheel/odometry) or '
                              'joint_states (/joint_states)', choices=WHEEL_INPUTS)
    wheel_joint_names: list = _rover(
        ['front_left_wheel_joint', 'front_right_wheel_joint',
         'rear_left_wheel_joint', 'rear_right_wheel_joint'], '',
        'JointState names of the driven wheels; the side is taken from "left"/"right" in the name')
    wheel_latency_s: float = _rover(0.0, 's', 'age of the wheel speed at its stamp (encoder '
                                    'count differences, driver delays); slip compares it with '
                                    'the body speed that long before the stamp', 0.0, 1.0)
    max_wheel_speed_mps: float = _rover(5.0, 'm/s', 'rim speeds above this are rejected as '
                                        'absurd', 0.1, 100.0)
    # --- rover: IMU mounting, pose of imu_link in base_link (static transform base_link->imu) --
    imu_to_base_rpy: list = _rover([0.0, 0.0, 0.0], 'rad', 'roll, pitch, yaw of the IMU frame in '
                                   'base_link', -math.pi, math.pi, length=3)
    imu_to_base_xyz: list = _rover([0.0, 0.0, 0.0], 'm', 'position of the IMU in base_link',
                                   -10.0, 10.0, length=3)
    # --- rover: initial pose and planet --------------------------------------------------------
    initial_latitude_deg: float = _rover(39.65, 'deg', 'geodetic latitude at start', -89.0, 89.0)
    initial_longitude_deg: float = _rover(-79.95, 'deg', 'longitude at start', -180.0, 180.0)
    initial_height_m: float = _rover(300.0, 'm', 'ellipsoidal height at start', -1.0e4, 1.0e5)
    initial_heading_deg: float = _rover(0.0, 'deg', 'heading of base_link x, clockwise from '
                                        'true north', -360.0, 360.0)
    planet: str = _rover('earth', '', 'planet model (shape, rotation, gravity)',
                         choices=PLANETS)
    # --- IMU noise model (Groves 2013 sec. 4.4, 14.2.6) and range -------------------------------
    accel_noise_density_mps2_rthz: float = _imu(2.0e-3, 'm/s^2/sqrt(Hz)', 'accelerometer white '
                                                'noise (velocity random walk)', 1e-6, 1.0)
    gyro_noise_density_rps_rthz: float = _imu(2.0e-4, 'rad/s/sqrt(Hz)', 'gyro white noise '
                                              '(angle random walk)', 1e-7, 0.1)
    accel_bias_psd_m2ps5: float = _imu(1.0e-7, 'm^2/s^5', 'accelerometer bias variation PSD '
                                       'S_bad', 0.0, 1.0)
    gyro_bias_psd_rad2ps3: float = _imu(1.0e-11, 'rad^2/s^3', 'gyro bias variation PSD S_bgd',
                                        0.0, 1.0)
    vibration_noise_fraction: float = _imu(0.5, '', 'fraction of the IMU window spread '
                                           '(vibration) added to the white-noise model',
                                           0.0, 10.0)
    accel_range_mps2: float = _imu(0.0, 'm/s^2', 'accelerometer measurement range, for '
                                   'clipping detection (0 = unknown)', 0.0, 10000.0)
    gyro_range_rps: float = _imu(0.0, 'rad/s', 'gyro measurement range, for clipping detection '
                                 '(0 = unknown)', 0.0, 1000.0)
    # --- filter: initial covariance (initial_* keep their interface names) ---------------------
    initial_accel_bias_std: float = _filter(0.05, 'm/s^2', 'initial accelerometer bias 1-sigma',
                                            1e-6, 10.0)
    initial_gyro_bias_std: float = _filter(5.0e-3, 'rad/s', 'initial gyro bias 1-sigma',
                                           1e-7, 1.0)
    initial_attitude_std: float = _filter(1e-3, 'rad', 'roll/pitch 1-sigma after alignment, '
                                          'apart from the part explained by the accelerometer '
                                          'bias', 1e-6, 1.0)
    initial_heading_std: float = _filter(0.05, 'rad', 'initial heading 1-sigma', 1e-6, 3.2)
    initial_velocity_std: float = _filter(0.01, 'm/s', 'initial velocity 1-sigma', 1e-6, 10.0)
    # --- filter: alignment --------------------------------------------------------------------
    alignment_duration_s: float = _filter(2.0, 's', 'stationary time used for initial '
                                          'alignment', 0.1, 600.0)
    motion_alignment_after_s: float = _filter(1.5, 's', 'without a stationary window for this '
                                              'long (and with wheel data), align in motion',
                                              0.5, 3600.0)
    # --- filter: pseudo-measurements ----------------------------------------------------------
    zupt_velocity_std_mps: float = _filter(0.01, 'm/s', 'ZUPT measurement 1-sigma', 1e-5, 1.0)
    zaru_rate_std_rps: float = _filter(1.0e-5, 'rad/s', 'ZARU measurement 1-sigma (added to the '
                                       'gyro noise of the averaging window)', 1e-8, 0.1)
    nhc_lateral_std_mps: float = _filter(0.05, 'm/s', 'non-holonomic lateral velocity 1-sigma',
                                         1e-4, 2.0)
    nhc_vertical_std_mps: float = _filter(0.03, 'm/s', 'non-holonomic vertical velocity '
                                          '1-sigma', 1e-4, 2.0)
    wheel_yaw_rate_std_rps: float = _filter(0.005, 'rad/s', 'yaw rate of the body the wheel '
                                            'differential does not show while driving (one '
                                            'side on softer ground, a side slope), 1-sigma; it '
                                            'bounds the wheel yaw-rate aid of the gyro z bias',
                                            1e-4, 10.0)
    wheel_yaw_rate_correlation_s: float = _filter(1.0, 's', 'how long that yaw rate and a '
                                                  "turn's scrub persist (a patch of ground "
                                                  'crossed)', 0.01, 600.0)
    update_rate_hz: float = _filter(10.0, 'Hz', 'rate of pseudo-measurement updates (ZUPT, '
                                    'ZARU, non-holonomic)', 0.5, 1000.0)
    innovation_gate_probability: float = _filter(0.9999, '', 'chi-square gate probability for '
                                                 'pseudo-measurements (1 disables the gate)',
                                                 0.9, 1.0)
    covariance_decimation: int = _filter(10, '', 'IMU samples per covariance propagation (1 = '
                                         'every sample, the reference path)', 1, 50)
    # --- filter: gaps and recovery ------------------------------------------------------------
    max_imu_gap_s: float = _filter(0.1, 's', 'IMU gaps longer than this are reported',
                                   0.004, 60.0)
    recovery_gap_s: float = _filter(1.0, 's', 'after an IMU gap longer than this the velocity '
                                    'is re-initialised (not integrated across the gap)',
                                    0.01, 600.0)
    recovery_s: float = _filter(3.0, 's', 'after a gap or divergence reset slip is unknown for '
                                'this long while the velocity re-anchors', 0.0, 60.0)
    # --- detectors ----------------------------------------------------------------------------
    stationary_window_s: float = _detector(0.5, 's', 'IMU window of the stationarity detector',
                                           0.05, 10.0)
    stationary_wheel_speed_mps: float = _detector(0.005, 'm/s', 'all wheels below this rim '
                                                  'speed count as stopped', 0.0, 1.0)
    stationary_accel_std_mps2: float = _detector(0.05, 'm/s^2', 'max accelerometer std per '
                                                 'axis in the window when stationary',
                                                 1e-4, 10.0)
    stationary_gyro_std_rps: float = _detector(0.01, 'rad/s', 'max gyro std per axis in the '
                                               'window when stationary', 1e-6, 1.0)
    turn_rate_threshold_rps: float = _detector(0.25, 'rad/s', 'above this yaw rate the lateral '
                                               'non-holonomic constraint is suspended '
                                               '(skid-steer turn)', 0.0, 10.0)
    wheel_timeout_s: float = _detector(0.5, 's', 'without wheel data for this long slip is '
                                       'STALE', 0.05, 60.0)
    # --- slip model: wheel aid, hold mode, slip output ----------------------------------------
    wheel_aid: str = _slip('hold', '', 'forward-velocity aid from the rim speed: off (the '
                           'paper) or hold (the slip model: slip changes detected on the wheel '
                           'or the body side, measured by the INS, then held)',
                           choices=('off', 'hold'))
    wheel_aid_std_mps: float = _slip(0.02, 'm/s', 'wheel-aid measurement 1-sigma', 1e-3, 1.0)
    slip_measure_s: float = _slip(0.5, 's', 'hold mode: unaided INS time to measure a new slip',
                                  0.1, 30.0)
    slip_continuity_sigma: float = _slip(2.0, '', 'hold mode: a body-speed change across a slip '
                                         'change within this many wheel-aid innovation sigmas '
                                         '(measured online) is taken as none', 0.0, 10.0)
    slip_baseline: str = _slip('snap', '', 'hold mode: snap (a re-measured slip within the '
                               'change threshold of the slip measured after the last start '
                               'from rest is that baseline) or off', choices=('snap', 'off'))
    slip_change_fraction: float = _slip(0.1, '', 'hold mode: a discrepancy beyond this fraction '
                                        'of the rim speed can signal a slip change', 0.01, 1.0)
    slip_change_sigma: float = _slip(3.5, '', 'hold mode: the slip-change threshold is at least '
                                     'this many 1-s spreads of the free wheel/INS residual '
                                     '(measured online)', 0.0, 20.0)
    wheel_speed_std_mps: float = _slip(0.01, 'm/s', 'rim-speed measurement 1-sigma', 0.0, 1.0)
    moving_speed_threshold_mps: float = _slip(0.02, 'm/s', 'below this rim and body speed the '
                                              'rover is "not moving" (slip class 0)', 0.0, 1.0)
    # --- node: outputs ------------------------------------------------------------------------
    odometry_rate_hz: float = _node(25.0, 'Hz', 'rate of /slip_estimator/odometry (0 = every '
                                    'IMU sample)', 0.0, 1000.0)
    diagnostics_period_s: float = _node(1.0, 's', 'period of /diagnostics (data time)',
                                        0.1, 60.0)
    imu_topic: str = _node('/imu/data', '', 'bag/robot topic of the IMU (sensor_msgs/Imu), read '
                           'as /imu/data (a --ros-args -r remap wins)')
    joint_states_topic: str = _node('/joint_states', '', 'topic of the wheel joint states '
                                    '(wheel_input joint_states), read as /joint_states')
    wheel_odometry_topic: str = _node('/wheel/odometry', '', 'topic of the wheel odometry '
                                      '(wheel_input odometry), read as /wheel/odometry')
    odom_frame: str = _node('odom', '', 'frame_id of the odometry output')
    base_frame: str = _node('base_link', '', 'child_frame_id of the odometry output')

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            _validate(f, getattr(self, f.name))

    @classmethod
    def from_dict(cls, values: dict[str, Any], *, ignore_unknown: bool = False) -> Params:
        """Build from a flat mapping; unknown keys raise unless ``ignore_unknown``. Keys of
        :data:`REMOVED_PARAMETERS` are ignored and keys of :data:`RENAMED_PARAMETERS` stand for
        their new names (files written before the change load; :func:`renamed_in` names them
        for a warning); a new name set too wins."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names - set(REMOVED_PARAMETERS) - set(RENAMED_PARAMETERS))
        if unknown and not ignore_unknown:
            raise ParameterError(f'unknown parameter(s): {", ".join(unknown)}')
        values = {**{RENAMED_PARAMETERS[k]: v for k, v in values.items()
                     if k in RENAMED_PARAMETERS}, **values}
        return cls(**{k: v for k, v in values.items() if k in names})

    def to_dict(self) -> dict[str, Any]:
        """Flat mapping of every parameter."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def replace(self, **changes: Any) -> Params:
        """A copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def group(self, name: str) -> Any:
        """The frozen view of one group (:data:`GROUPS`): only the fields its reader needs."""
        view = _GROUP_TYPES[name]
        return view(**{f.name: getattr(self, f.name) for f in dataclasses.fields(view)})

    rover = _view('rover', 'Rover geometry, wheel input, IMU mounting, initial pose, planet.')
    imu_noise = _view('imu_noise', 'IMU white noise, bias variation, vibration share, range.')
    filter = _view('filter', 'Initial covariance, alignment, pseudo-measurements, gaps, recovery.')
    detectors = _view('detectors', 'Stationarity, turning and stale-wheel thresholds.')
    slip_model = _view('slip_model', 'Wheel aid, hold mode, slip output and moving threshold.')
    node = _view('node', "The node's outputs (rates, frames).")


def _group_type(group: str, class_name: str) -> type:
    """A frozen dataclass with the fields of ``group``, in schema order (no defaults: a view
    is always made from a validated :class:`Params`)."""
    fields = [(f.name, f.type) for f in dataclasses.fields(Params)
              if f.metadata['group'] == group]
    view = dataclasses.make_dataclass(class_name, fields, frozen=True)
    view.__module__ = __name__
    view.__doc__ = f'The {group} parameters of :class:`Params` (frozen).'
    return view


RoverParams = _group_type('rover', 'RoverParams')
ImuNoiseParams = _group_type('imu_noise', 'ImuNoiseParams')
FilterParams = _group_type('filter', 'FilterParams')
DetectorParams = _group_type('detectors', 'DetectorParams')
SlipModelParams = _group_type('slip_model', 'SlipModelParams')
NodeParams = _group_type('node', 'NodeParams')
_GROUP_TYPES = dict(zip(GROUPS, (RoverParams, ImuNoiseParams, FilterParams, DetectorParams,
                                 SlipModelParams, NodeParams)))


REMOVED_PARAMETERS = {
    'max_wheel_latency_s': 'never read (the wheel latency is wheel_latency_s; late wheel '
                           'samples are those older than the 2 s forward-speed history)',
}
"""Parameters that no longer exist, with the reason; a file that still sets one loads."""

RENAMED_PARAMETERS = {
    'accel_noise_density': 'accel_noise_density_mps2_rthz',
    'gyro_noise_density': 'gyro_noise_density_rps_rthz',
    'accel_bias_psd': 'accel_bias_psd_m2ps5',
    'gyro_bias_psd': 'gyro_bias_psd_rad2ps3',
    'zupt_velocity_std': 'zupt_velocity_std_mps',
    'zaru_rate_std': 'zaru_rate_std_rps',
    'nhc_lateral_std': 'nhc_lateral_std_mps',
    'nhc_vertical_std': 'nhc_vertical_std_mps',
    'wheel_aid_std': 'wheel_aid_std_mps',
    'stationary_accel_std': 'stationary_accel_std_mps2',
    'stationary_gyro_std': 'stationary_gyro_std_rps',
    'turn_rate_threshold': 'turn_rate_threshold_rps',
    'wheel_speed_std': 'wheel_speed_std_mps',
    'moving_speed_threshold': 'moving_speed_threshold_mps',
}
"""Old name -> new name of parameters renamed to carry their unit; a file that still sets an
old name loads (the value goes to the new name) with a one-line warning (:func:`renamed_in`)."""


def renamed_in(names: Any) -> list[str]:
    """One-line deprecation warnings for the old names among ``names``, each naming the new."""
    return [f'parameter {old} is renamed {RENAMED_PARAMETERS[old]} (the old name still loads; '
            f'rename it)' for old in sorted(set(names) & set(RENAMED_PARAMETERS))]


def describe(name: str) -> str:
    """One-line description of a parameter with its unit and allowed range."""
    f = {f.name: f for f in dataclasses.fields(Params)}[name]
    m = f.metadata
    rng = ''
    if m['choices']:
        rng = f' one of {"|".join(m["choices"])}'
    elif m['lo'] is not None:
        rng = f' in [{m["lo"]}, {m["hi"]}]'
    unit = f' [{m["unit"]}]' if m['unit'] else ''
    return f'{m["doc"]}{unit}{rng}'


def _validate(f: dataclasses.Field, value: Any) -> None:
    m = f.metadata
    name = f.name
    if m['choices'] is not None:
        if value not in m['choices']:
            raise ParameterError(f'parameter {name}={value!r}: must be one of '
                                 f'{", ".join(m["choices"])}')
        return
    if isinstance(f.default, str) or f.type == 'str':
        if not isinstance(value, str) or not value:
            raise ParameterError(f'parameter {name}={value!r}: must be a non-empty string')
        return
    if m['length'] is not None or isinstance(value, (list, tuple)):
        if not isinstance(value, (list, tuple)):
            raise ParameterError(f'parameter {name}={value!r}: must be a list')
        if m['length'] is not None and len(value) != m['length']:
            raise ParameterError(f'parameter {name}={value!r}: must have {m["length"]} elements')
        items = value
    else:
        items = [value]
    for v in items:
        if m['lo'] is None:
            if not isinstance(v, str) or not v:
                raise ParameterError(f'parameter {name}: elements must be non-empty strings')
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ParameterError(f'parameter {name}={value!r}: must be a finite number in '
                                 f'[{m["lo"]}, {m["hi"]}] {m["unit"]}')
        if not m['lo'] <= v <= m['hi']:
            raise ParameterError(f'parameter {name}={value!r}: out of range, allowed '
                                 f'[{m["lo"]}, {m["hi"]}] {m["unit"]}')


def with_message_noise(params: Params, accel_var_mps2_2: float, gyro_var_rps2: float,
                       dt_s: float, raise_only: bool = False) -> Params | None:
    """``params`` with the IMU white-noise densities taken from per-sample variances
    (density = sqrt(variance x sample interval), within the parameters' bounds) when the
    parameters leave both at their defaults (not configured); None when they are configured.

    ``raise_only``: never below the defaults (a spread measured over a short window at rest
    misses vibration and drift; it can only tell that an IMU is noisier than the defaults).

    The gyro's turn-on bias prior ``initial_gyro_bias_std``, when left at its default too,
    grows with the grade: a gyro ``r`` times noisier than the default density gets the default
    times ``sqrt(r)`` (a consumer MEMS gyro, 0.02 rad/s per sample at 30 Hz: r = 18, 0.021
    rad/s, within consumer datasheets' 1-5 deg/s turn-on ranges, against 0.5 deg/s simulated).
    A robot that starts moving learns its z bias from the wheel yaw-rate aid alone, as fast as
    this prior lets it: at the default 0.005 rad/s a 0.5-deg/s bias took 30 s and left 4-6 deg
    of heading (simulated vibrating no-slip robot, seeds 3 and 4: 7.4 and 10.8 m at the end
    of 395 s; 5.0 and 3.8 m with it)."""
    fields = Params.__dataclass_fields__
    accel, gyro = 'accel_noise_density_mps2_rthz', 'gyro_noise_density_rps_rthz'
    if getattr(params, accel) != fields[accel].default \
            or getattr(params, gyro) != fields[gyro].default:
        return None
    densities = {}
    for name, var in ((accel, accel_var_mps2_2), (gyro, gyro_var_rps2)):
        meta = fields[name].metadata
        floor = fields[name].default if raise_only else meta['lo']
        densities[name] = min(max(math.sqrt(var * dt_s), floor), meta['hi'])
    bias = 'initial_gyro_bias_std'
    if getattr(params, bias) == fields[bias].default:
        grade = max(1.0, densities[gyro] / fields[gyro].default)
        densities[bias] = min(fields[bias].default * math.sqrt(grade), fields[bias].metadata['hi'])
    return dataclasses.replace(params, **densities)
