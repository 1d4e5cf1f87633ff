"""Import of WVU Pathfinder logs (``.mat``, MATLAB v7.3 = HDF5) into a bag and a params file.

The logs are the seed paper authors' exports (``wvu-navLab/corenav-GP``); see
``shared/data/pathfinder/README.md``. Everything below was checked against the data itself
(``slip-estimator import-pathfinder`` prints the same figures for any log):

Time bases
    * ``tTimu`` and ``tTodom`` are Unix seconds. IMU: 250 Hz (median dt 4.000 ms, min 2.8 ms,
      max 4.95 ms, no gaps). Wheels (joint states): 10 Hz, dt 0.0999-0.1001 s.
    * test17run: the GNSS time (``gpsECEF.time``) is GPS time of week. The GPS week follows from
      the IMU Unix time (week 2068, starts 2019-08-25 00:00 UTC = Unix 1566691200, as in the
      README) and Unix = week start + TOW - 18 s. The record has 705 epochs over 72.4 s
      (8 gaps of 0.2 s, 6 of 0.3 s), so aligning it with the 705 wheel samples by index would be
      off by up to 1.8 s; after conversion GNSS spans [-0.14 s, +1.82 s] around the IMU record.
    * s5t1: ``tTGPS`` (identical to ``gpsECEF.time`` within 1e-5 s) is already Unix time. It is a
      jittery receive time (dt between 0.03 and 0.30 s, mean 0.0999 s, no missing epochs), so
      per-sample GNSS velocities of s5t1 are meaningless even apart from its single-point noise.
    * ``ENUGPS``/``llhGPS`` equal ``gpsECEF`` converted (checked to 5e-5 m, 4e-9 m); ``llhGPS``
      height is ellipsoidal. The Novatel ``Height`` of s5t1 is 33.30 m above it (it is the
      orthometric/MSL height; geoid undulation about -33.3 m), so NavSatFix altitude uses
      ``llhGPS``.
    * Wheel stamps lag the IMU: the cross-correlation of the gyro yaw rate with the wheel
      differential yaw rate peaks at IMU time = wheel stamp - 0.085 s (s5t1, r = 0.97) and
      -0.165 s (test17run, straight drive, r = 0.64); forward acceleration Ax vs d(wheel
      speed)/dt gives -0.13 s / -0.20 s; GNSS speed vs wheel speed (test17run, RTK) gives
      wheel stamp = GNSS time + 0.18 s. IMU and GNSS agree with each other; the joint states are
      about 0.1-0.2 s late. Timestamps are written as recorded; the estimator should allow for
      this latency (``wheel_latency_s``) and may want a wheel time offset.

IMU axes and sign
    Raw axes are the sensor's x forward, y right, z down (FRD). At rest Az = -9.79 / -9.80 m/s^2
    and |f| = 9.810 m/s^2: that is the specific force (reaction to gravity, pointing up) resolved
    in a z-down frame, i.e. REP-145 compliant already; only the frame is not FLU. The mounting is
    therefore declared as ``imu_to_base_rpy = [pi, 0, 0]`` (imu_link = base_link rolled by 180
    deg), after which base z reads +9.80 at rest. Verified: Gz < 0 in the long left (counter-
    clockwise) arcs of s5t1 (GNSS course and wheel differential agree: mean Gz = -0.24 rad/s
    where the right wheels are faster), Ax correlates positively with d(wheel speed)/dt, Ay is
    negatively correlated with v * yaw_rate_FLU (centripetal force to the left, y right).
    At rest the tilt is roll 2.0 / 0.9 deg, pitch -2.8 / -2.1 deg (test17run / s5t1, FRD).
    Gyro turn-on bias up to 1.4e-3 rad/s (s5t1 x). Measured noise at rest (std / sqrt(250 Hz)):
    gyro 5.2e-5 rad/s/sqrt(Hz) (datasheet ARW 2.9e-5), accelerometer 1.0e-3 m/s^2/sqrt(Hz)
    (datasheet VRW 1.3e-4, i.e. ~8x lower): the rover vibrates or its electronics add noise even
    at rest. The params file uses the datasheet values unless ``measured_noise=True``.

Wheels
    The left wheels read negative when driving forward: they are negated here so that every
    joint is forward positive. The four wheels agree within ~0.5-1 rad/s. ``*Vel`` is quantised
    in steps of 0.0075 rad/s and exactly 0 at rest. Integrating ``*Vel`` over time gives 1.9 %
    more rotation than the change of ``*Pos`` on all four wheels of both logs: the velocity field
    is scaled by ~1.019 relative to the positions. test17run (straight, RTK): GNSS speed / (0.12 m
    * mean wheel ``Vel``) = 0.966 (ratio of sums while moving; r_eff = 0.116 m; 0.118 m if based on
    ``Pos``). The rover's own odometry ``lin_x`` corresponds to r = 0.110 m. So "zero slip" with
    the nominal 0.12 m radius reads s = +0.034 on this firm-ground run: part effective radius,
    part genuine longitudinal slip - the two cannot be separated from one run.

Runs and initial heading
    test17run: motion from 5.4 s to 54.6 s (of 70.4 s); the gyro shows the drive is not straight
    (heading wanders by +-6 deg). GNSS (RTK) course over the first 1.7 m: 2.3 deg; net displacement
    34.3 m at 2.8 deg. s5t1: motion from 13.4 s to 146.6 s (of 176.9 s); first straight ~2.7 m,
    GNSS (single point) course 317-318 deg vs the authors' hand-set 313 deg.
    :func:`estimate_initial_heading` fits the GNSS track of the first straight drive and corrects
    by the gyro heading change since standstill.

Layout
    :mod:`~slip_estimator.pathfinder.rover` (the rover's fixed facts), ``log`` (reading the
    ``.mat``), ``facts`` (figures measured on a log), ``params`` (the params file) and ``bag``
    (the bag writer and the whole import). The functions and records below are the public API;
    the constants stay in ``rover`` and ``log``.
"""
from slip_estimator.pathfinder.bag import import_pathfinder, write_bag
from slip_estimator.pathfinder.facts import (
    HeadingEstimate,
    LogFacts,
    estimate_initial_heading,
    format_facts,
    gnss_enu,
    gnss_over_wheel_speed,
    log_facts,
    measured_noise_density,
    motion_interval,
    rim_speed_mps,
    wheel_differential_rps,
    wheel_imu_lag,
)
from slip_estimator.pathfinder.log import (
    PathfinderLog,
    gps_tow_to_unix,
    read_matlab_table,
    read_pathfinder_mat,
)
from slip_estimator.pathfinder.params import params_notes, pathfinder_params

__all__ = [
    'HeadingEstimate', 'LogFacts', 'PathfinderLog', 'estimate_initial_heading', 'format_facts',
    'gnss_enu', 'gnss_over_wheel_speed', 'gps_tow_to_unix', 'import_pathfinder', 'log_facts',
    'measured_noise_density', 'motion_interval', 'params_notes', 'pathfinder_params',
    'read_matlab_table', 'read_pathfinder_mat', 'rim_speed_mps', 'wheel_differential_rps',
    'wheel_imu_lag', 'write_bag',
]
