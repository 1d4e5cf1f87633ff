"""Write a simulation run to an MCAP rosbag2 bag with real ROS 2 messages, and the sim CLI.

Topics (log time = header stamp, integer ns from ``ScenarioConfig.epoch_ns``):

* ``/imu/data`` sensor_msgs/Imu in ``imu_link`` (REP-145: no orientation,
  ``orientation_covariance[0] = -1``; rate and acceleration covariances from the noise
  densities: variance per sample = density^2 * rate).
* ``/joint_states`` sensor_msgs/JointState: the four wheel joints, position (rad) and
  velocity (rad/s, forward positive) from the quantised encoder counts.
* ``/wheel/odometry`` nav_msgs/Odometry ``odom`` -> ``base_link``: linear.x = mean rim speed,
  angular.z = (v_right - v_left) / track, pose = 2-D wheel dead reckoning.
* ``/gnss/fix`` sensor_msgs/NavSatFix (DIAGONAL_KNOWN covariance).
* ``/truth/odometry`` nav_msgs/Odometry of base_link in ``odom`` (ENU at the start), twist in
  base_link (FLU), at ``rate_truth_hz``.
* ``/truth/slip`` geometry_msgs/Vector3Stamped at every wheel sample: x = true slip of the
  mean wheel, y = 0, z = true class index (same layout as ``/slip_estimator/slip_ratio``).

This module imports ROS (through :mod:`slip_estimator.bagio`); the simulator itself does not.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.sim.robots import ROBOTS, RobotProfile
from slip_estimator.sim.rover import SimResult, simulate
from slip_estimator.sim.drives import (
    default_scenario,
    measured_ground,
    mixed_scenario,
    no_slip,
    patch_scenario,
    short_scenario,
)
from slip_estimator.sim.scenario import WHEEL_JOINT_NAMES

TOPIC_IMU = '/imu/data'
TOPIC_JOINTS = '/joint_states'
TOPIC_WHEEL_ODOM = '/wheel/odometry'
TOPIC_GNSS = '/gnss/fix'
TOPIC_TRUTH_ODOM = '/truth/odometry'
TOPIC_TRUTH_SLIP = '/truth/slip'
ALL_TOPICS = (TOPIC_IMU, TOPIC_JOINTS, TOPIC_WHEEL_ODOM, TOPIC_GNSS, TOPIC_TRUTH_ODOM,
              TOPIC_TRUTH_SLIP)


def _stamp(msg_header: object, stamp_ns: int) -> None:
    from slip_estimator.ros.stamps import ns_to_stamp

    msg_header.stamp = ns_to_stamp(stamp_ns)  # type: ignore[attr-defined]


def _yaw_quat_wxyz(yaw: float) -> tuple[float, float, float, float]:
    return math.cos(0.5 * yaw), 0.0, 0.0, math.sin(0.5 * yaw)


def sim_params(result: SimResult, wheel_input: str = 'joint_states',
               joint_columns: tuple[int, ...] = (0, 1, 2, 3)) -> object:
    """:class:`slip_estimator.core.params.Params` matching the simulated rover and IMU (the
    declared parameters: the geometric track, not a skid-steer's effective one)."""
    from slip_estimator.core.params import Params

    cfg = result.config
    rover, site, imu = cfg.rover, cfg.site, cfg.imu
    return Params(
        wheel_radius=rover.wheel_radius_m, track_width=rover.track_width_m,
        wheel_input=wheel_input,
        wheel_joint_names=[WHEEL_JOINT_NAMES[k] for k in joint_columns],
        imu_to_base_rpy=[float(a) for a in rover.imu_to_base_rpy_rad],
        imu_to_base_xyz=[float(a) for a in rover.imu_to_base_xyz_m],
        initial_latitude_deg=site.latitude_deg, initial_longitude_deg=site.longitude_deg,
        initial_height_m=site.height_m, initial_heading_deg=site.heading_deg,
        planet=site.planet,
        # Params lower bounds are > 0: an ideal IMU maps to the smallest allowed values.
        accel_noise_density_mps2_rthz=max(imu.accel_noise_density_mps2_rthz, 1e-6),
        gyro_noise_density_rps_rthz=max(imu.gyro_noise_density_rps_rthz, 1e-7),
        accel_bias_psd_m2ps5=imu.accel_bias_psd_m2ps5,
        gyro_bias_psd_rad2ps3=imu.gyro_bias_psd_rad2ps3,
        initial_accel_bias_std=max(imu.accel_bias_sigma_mps2, 1e-6),
        initial_gyro_bias_std=max(imu.gyro_bias_sigma_rps, 1e-7),
        # The encoder speed is a count difference over the last wheel period: its mean age.
        wheel_latency_s=0.5 / cfg.rate_wheel_hz)


class _SimMessages:
    """The messages of a simulated drive, one maker per topic (index into its stream)."""

    def __init__(self, result: SimResult, imu_ns: np.ndarray, wheel_ns: np.ndarray,
                 gnss_ns: np.ndarray, truth_idx: np.ndarray,
                 profile: RobotProfile | None = None) -> None:
        cfg = result.config
        var_w = cfg.imu.gyro_noise_density_rps_rthz ** 2 * cfg.rate_imu_hz
        var_f = cfg.imu.accel_noise_density_mps2_rthz ** 2 * cfg.rate_imu_hz
        self.result = result
        self.imu_ns, self.wheel_ns, self.gnss_ns, self.truth_idx = \
            imu_ns, wheel_ns, gnss_ns, truth_idx
        self.half_T = 0.5 * cfg.rover.track_width_m
        self.gnss_var = np.array([cfg.gnss.horizontal_std_m ** 2,
                                  cfg.gnss.horizontal_std_m ** 2, cfg.gnss.vertical_std_m ** 2])
        self.imu_diag_w = [var_w, 0.0, 0.0, 0.0, var_w, 0.0, 0.0, 0.0, var_w]
        self.imu_diag_f = [var_f, 0.0, 0.0, 0.0, var_f, 0.0, 0.0, 0.0, var_f]
        self.wheel_speed_var = (1.0 / (cfg.rover.encoder_pulses_per_m / cfg.rate_wheel_hz)) ** 2
        self.columns = profile.joint_columns if profile else tuple(range(len(WHEEL_JOINT_NAMES)))
        self.joint_velocities = profile is None or profile.joint_velocities
        self.f_imu = result.f_ib_imu
        if profile is not None and profile.imu_gravity_removed:
            # A driver that subtracts gravity with its own attitude: linear acceleration.
            C_imu_base = rpy_to_dcm(*cfg.rover.imu_to_base_rpy_rad)
            up_imu = np.einsum('ij,nkj,k->ni', C_imu_base.T, result.C_base_o,
                               np.array([0, 0, 1.0]))
            self.f_imu = self.f_imu - result.gravity_mps2 * up_imu

    def imu(self, i: int) -> Imu:
        from sensor_msgs.msg import Imu

        m = Imu()
        _stamp(m.header, int(self.imu_ns[i]))
        m.header.frame_id = 'imu_link'
        m.orientation_covariance[0] = -1.0
        f, w = self.f_imu[i], self.result.omega_ib_imu[i]
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = map(float, w)
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = \
            map(float, f)
        m.angular_velocity_covariance = self.imu_diag_w
        m.linear_acceleration_covariance = self.imu_diag_f
        return m

    def joints(self, j: int) -> JointState:
        from sensor_msgs.msg import JointState

        m = JointState()
        _stamp(m.header, int(self.wheel_ns[j]))
        m.header.frame_id = 'base_link'
        m.name = [WHEEL_JOINT_NAMES[k] for k in self.columns]
        m.position = [float(self.result.wheel_angle_rad[j, k]) for k in self.columns]
        if self.joint_velocities:
            m.velocity = [float(self.result.wheel_rate_rps[j, k]) for k in self.columns]
        return m

    def wheel_odom(self, j: int) -> Odometry:
        from nav_msgs.msg import Odometry

        m = Odometry()
        _stamp(m.header, int(self.wheel_ns[j]))
        m.header.frame_id = 'odom'
        m.child_frame_id = 'base_link'
        x, y = self.result.wheel_odom_xy_m[j]
        m.pose.pose.position.x, m.pose.pose.position.y = float(x), float(y)
        w, qx, qy, qz = _yaw_quat_wxyz(float(self.result.wheel_odom_yaw_rad[j]))
        o = m.pose.pose.orientation
        o.w, o.x, o.y, o.z = w, qx, qy, qz
        m.twist.twist.linear.x = float(self.result.wheel_odom_speed_mps[j])
        m.twist.twist.angular.z = float(self.result.wheel_odom_yaw_rate_rps[j])
        cov = [0.0] * 36
        cov[0] = self.wheel_speed_var
        cov[35] = self.wheel_speed_var / self.half_T ** 2
        for k in (7, 14, 21, 28):
            cov[k] = 1e6  # vy, vz, wx, wy are not measured by the wheels
        m.twist.covariance = cov
        pcov = [0.0] * 36
        for k in (0, 7, 35):
            pcov[k] = 1.0  # dead reckoning: unbounded in principle, nominal 1 m / 1 rad
        for k in (14, 21, 28):
            pcov[k] = 1e6
        m.pose.covariance = pcov
        return m

    def truth_slip(self, j: int) -> Vector3Stamped:
        from geometry_msgs.msg import Vector3Stamped

        m = Vector3Stamped()
        _stamp(m.header, int(self.wheel_ns[j]))
        m.header.frame_id = 'base_link'
        m.vector.x = float(self.result.slip_true[j])
        m.vector.y = 0.0
        m.vector.z = float(self.result.slip_class[j])
        return m

    def gnss(self, g: int) -> NavSatFix:
        from sensor_msgs.msg import NavSatFix, NavSatStatus

        m = NavSatFix()
        _stamp(m.header, int(self.gnss_ns[g]))
        m.header.frame_id = 'base_link'
        m.status.status = NavSatStatus.STATUS_FIX
        m.status.service = NavSatStatus.SERVICE_GPS
        lat, lon, alt = self.result.gnss_llh[g]
        m.latitude, m.longitude, m.altitude = float(lat), float(lon), float(alt)
        var = self.gnss_var
        m.position_covariance = [float(var[0]), 0.0, 0.0, 0.0, float(var[1]), 0.0,
                                 0.0, 0.0, float(var[2])]
        m.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        return m

    def truth_odom(self, k: int) -> Odometry:
        from nav_msgs.msg import Odometry

        i = int(self.truth_idx[k])
        m = Odometry()
        _stamp(m.header, int(self.imu_ns[i]))
        m.header.frame_id = 'odom'
        m.child_frame_id = 'base_link'
        p = self.result.p_ob_o[i]
        m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = map(float, p)
        q = self.result.q_ob_wxyz[i]
        o = m.pose.pose.orientation
        o.w, o.x, o.y, o.z = map(float, q)
        vb, wb = self.result.v_ob_b[i], self.result.omega_eb_b[i]
        t = m.twist.twist
        t.linear.x, t.linear.y, t.linear.z = map(float, vb)
        t.angular.x, t.angular.y, t.angular.z = map(float, wb)
        return m


_IMU_NOISE_PARAMS = ('accel_noise_density_mps2_rthz', 'gyro_noise_density_rps_rthz',
                     'accel_bias_psd_m2ps5', 'gyro_bias_psd_rad2ps3', 'initial_accel_bias_std',
                     'initial_gyro_bias_std')


def profile_params(profile: RobotProfile, result: SimResult) -> object:
    """The parameters a user of that robot declares: geometry, mounting, start pose and wheel
    input; the IMU noise model is left at its defaults (the node takes it from the messages)."""
    import dataclasses

    from slip_estimator.core.params import Params

    params = sim_params(result, profile.wheel_input, profile.joint_columns)
    defaults = Params()
    return dataclasses.replace(params, **{k: getattr(defaults, k) for k in _IMU_NOISE_PARAMS})


def write_sim_bag(result: SimResult, bag_path: str | Path,
                  params_path: str | Path | None = None, *,
                  profile: RobotProfile | None = None) -> dict[str, int]:
    """Write ``result`` to a new MCAP bag at ``bag_path``; return the message count per topic.

    If ``params_path`` is given, also write a ROS 2 params file for the estimator that matches
    the simulated rover geometry, mounting, start pose, planet and IMU noise. A robot
    ``profile`` (:mod:`slip_estimator.sim.robots`) makes the drivers publish as that robot's
    do: joint states of some wheels only, positions without velocities, an IMU without
    gravity, and the params file names its wheel input.
    """
    from slip_estimator.bagio import BagWriter

    cfg = result.config
    imu_ns = result.stamps_ns(result.imu_t_s)
    wheel_ns = result.stamps_ns(result.wheel_t_s)
    gnss_ns = result.stamps_ns(result.gnss_t_s)
    truth_step = int(round(cfg.rate_imu_hz / cfg.rate_truth_hz))
    if abs(truth_step * cfg.rate_truth_hz - cfg.rate_imu_hz) > 1e-9:
        raise ValueError('rate_truth_hz must divide rate_imu_hz')
    truth_idx = np.arange(0, len(result.imu_t_s), truth_step)
    truth_ns = imu_ns[truth_idx]

    # Merge all streams by stamp (ties: IMU first, then wheels, then the rest) so the bag is
    # written in log-time order.
    streams = [(TOPIC_IMU, imu_ns), (TOPIC_JOINTS, wheel_ns), (TOPIC_WHEEL_ODOM, wheel_ns),
               (TOPIC_TRUTH_SLIP, wheel_ns), (TOPIC_GNSS, gnss_ns),
               (TOPIC_TRUTH_ODOM, truth_ns)]
    stamps = np.concatenate([s for _, s in streams])
    which = np.concatenate([np.full(len(s), k) for k, (_, s) in enumerate(streams)])
    index = np.concatenate([np.arange(len(s)) for _, s in streams])
    order = np.lexsort((index, which, stamps))
    counts = {name: 0 for name, _ in streams}
    msgs = _SimMessages(result, imu_ns, wheel_ns, gnss_ns, truth_idx, profile)
    makers = [msgs.imu, msgs.joints, msgs.wheel_odom, msgs.truth_slip, msgs.gnss, msgs.truth_odom]
    with BagWriter(bag_path) as writer:
        for o in order:
            k = int(which[o])
            topic = streams[k][0]
            writer.write(topic, makers[k](int(index[o])), int(stamps[o]))
            counts[topic] += 1
    if params_path is not None:
        from slip_estimator.paramfile import save_params

        params = (sim_params(result) if profile is None
                  else profile_params(profile, result))
        save_params(params, params_path)  # type: ignore[arg-type]
    return counts


SCENARIOS = {
    'default': default_scenario, 'short': short_scenario, 'mixed': mixed_scenario,
    'patches': patch_scenario,
    'rough': lambda seed=0, noise_seed=None: patch_scenario(seed, rough=True,
                                                            noise_seed=noise_seed),
    'no_slip': lambda seed=0, noise_seed=None: no_slip(patch_scenario(
        seed, noise_seed=noise_seed)),
    'rough_no_slip': lambda seed=0, noise_seed=None: no_slip(patch_scenario(
        seed, rough=True, noise_seed=noise_seed)),
    'measured': lambda seed=0, noise_seed=None: measured_ground(patch_scenario(
        seed, noise_seed=noise_seed)),
    'measured_no_slip': lambda seed=0, noise_seed=None: no_slip(measured_ground(
        patch_scenario(seed, noise_seed=noise_seed))),
    'measured_motion_bound': lambda seed=0, noise_seed=None: measured_ground(patch_scenario(
        seed, noise_seed=noise_seed), motion_bound=True),
    'measured_motion_bound_no_slip': lambda seed=0, noise_seed=None: no_slip(measured_ground(
        patch_scenario(seed, noise_seed=noise_seed), motion_bound=True))}
"""The scenarios ``simulate --scenario`` offers (wheel-rate control unless mixed). The
``*no_slip`` ones are the patches drive over ground that shows no slip at all (the
false-alarm rate); ``measured*`` have the IMU mechanisms and chassis rocking measured on the
real Pathfinder (``docs/sim-vs-real.md``), ``measured_motion_bound*`` with its vibration
without white content at 0 Hz (:meth:`~.imu_grades.VibrationConfig.pathfinder_measured`)."""


def simulate_main(argv: list[str] | None = None) -> int:
    """``slip-estimator simulate``: run a seeded scenario and write the bag (and params)."""
    ap = argparse.ArgumentParser(prog='slip-estimator simulate',
                                 description='Simulate a skid-steer rover (IMU, wheels, GNSS, '
                                 'truth) and write an MCAP rosbag2 bag.',
                                 epilog='example: slip-estimator simulate --robot fifty_hz '
                                        '-o drive --params-out drive.params.yaml')
    ap.add_argument('--seed', type=int, default=0, help='truth (trajectory/terrain) seed')
    ap.add_argument('--noise-seed', type=int, default=None,
                    help='sensor noise seed (default: seed + 1)')
    ap.add_argument('--scenario', choices=tuple(SCENARIOS), default='default',
                    help='default, short, mixed (body- and wheel-side slip), patches (600 s '
                         'random drive), rough (the same on rough ground), no_slip / '
                         'rough_no_slip (patches / rough over ground without slip), measured / '
                         'measured_no_slip (patches with the IMU and rocking measured on the '
                         'real Pathfinder)')
    ap.add_argument('--robot', choices=tuple(ROBOTS), default=None,
                    help='simulate another robot instead (issue 10 profiles: rates, IMU grade, '
                         'mounting, wheel input as that robot publishes them); overrides '
                         '--scenario')
    ap.add_argument('--duration-s', type=float, default=None,
                    help='cut the scenario after this many seconds')
    ap.add_argument('--output', '-o', required=True, help='bag directory to create')
    ap.add_argument('--params-out', default=None, help='write a matching ROS 2 params file')
    args = ap.parse_args(argv)
    profile = ROBOTS[args.robot](args.seed) if args.robot else None
    if profile is not None:
        cfg = profile.scenario
        if args.noise_seed is not None:
            cfg = cfg.replace(noise_seed=args.noise_seed)
    else:
        cfg = SCENARIOS[args.scenario](args.seed, noise_seed=args.noise_seed)
    if args.duration_s is not None:
        if args.duration_s < 10.0:
            ap.error('--duration-s must be >= 10 (the initial stationary period)')
        cfg = cfg.replace(duration_s=args.duration_s)
    if Path(args.output).exists():
        ap.error(f'{args.output} exists; choose a new bag path')
    t0 = time.monotonic()
    result = simulate(cfg)
    t1 = time.monotonic()
    counts = write_sim_bag(result, args.output, args.params_out, profile=profile)
    t2 = time.monotonic()
    print(f'simulated {cfg.total_duration_s:.1f} s ({args.robot or args.scenario}, '
          f'seed {cfg.truth_seed}, '
          f'noise seed {cfg.noise_seed}) in {t1 - t0:.1f} s; wrote {args.output} in '
          f'{t2 - t1:.1f} s')
    for topic, n in counts.items():
        print(f'  {topic}: {n} messages')
    names = ('none', 'low', 'medium', 'high', 'extreme')
    print('  slip class time: ' + ', '.join(
        f'{names[c]} {d:.1f} s' for c, d in result.class_durations_s().items()))
    if args.params_out:
        print(f'  params: {args.params_out}')
    return 0
