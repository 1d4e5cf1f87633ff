"""The estimator parameters for a Pathfinder log and the notes the params file carries."""
from __future__ import annotations

import math

from slip_estimator.core.params import Params
from slip_estimator.pathfinder.facts import (
    LogFacts,
    estimate_initial_heading,
    measured_noise_density,
)
from slip_estimator.pathfinder.log import PathfinderLog
from slip_estimator.pathfinder.rover import (
    ACCEL_BIAS_INSTABILITY_MPS2,
    ACCEL_VRW_MPS_PER_SQRT_S,
    BIAS_CORRELATION_TIME_S,
    GYRO_ARW_RAD_PER_SQRT_S,
    GYRO_BIAS_INSTABILITY_RPS,
    IMU_TO_BASE_RPY,
    TRACK_WIDTH_M,
    WHEEL_JOINT_NAMES,
    WHEEL_RADIUS_M,
)


def pathfinder_params(log: PathfinderLog, heading_deg: float | None = None,
                      measured_noise: bool = False) -> Params:
    """Estimator parameters for a Pathfinder log (geometry, mounting, start pose, IMU noise).

    IMU noise is the ADIS16495-2 datasheet (ARW, VRW; bias PSDs from the in-run bias
    instability reached over :data:`BIAS_CORRELATION_TIME_S`) unless ``measured_noise``, then
    the white-noise densities measured at rest are used.
    """
    if heading_deg is None:
        heading_deg = estimate_initial_heading(log).heading_deg
    gyro_n, accel_n = GYRO_ARW_RAD_PER_SQRT_S, ACCEL_VRW_MPS_PER_SQRT_S
    if measured_noise:
        gyro_n, accel_n = measured_noise_density(log)
    lat, lon, h = log.gnss_llh[0]
    return Params(
        wheel_radius=WHEEL_RADIUS_M, track_width=TRACK_WIDTH_M, wheel_input='joint_states',
        wheel_joint_names=list(WHEEL_JOINT_NAMES), imu_to_base_rpy=list(IMU_TO_BASE_RPY),
        initial_latitude_deg=math.degrees(lat), initial_longitude_deg=math.degrees(lon),
        initial_height_m=float(h), initial_heading_deg=float(heading_deg) % 360.0,
        planet='earth', gyro_noise_density_rps_rthz=gyro_n,
        accel_noise_density_mps2_rthz=accel_n,
        gyro_bias_psd_rad2ps3=GYRO_BIAS_INSTABILITY_RPS ** 2 / BIAS_CORRELATION_TIME_S,
        accel_bias_psd_m2ps5=ACCEL_BIAS_INSTABILITY_MPS2 ** 2 / BIAS_CORRELATION_TIME_S)


def params_notes(facts: LogFacts, measured_noise: bool = False,
                 measured_lag: bool = False) -> list[str]:
    """What the params file takes from the measurements of the log, and why not where it keeps
    a default (written as comments at the top of the file)."""
    lag = facts.wheel_lag_s
    notes = [f'Wheel stamps lag the IMU by {lag:.3f} s on this log (yaw-rate cross-correlation '
             f'r = {facts.wheel_lag_corr:.2f}).']
    if measured_lag:
        notes.append(f'wheel_latency_s = {lag:.3f}: that measured lag.')
    else:
        notes.append('wheel_latency_s stays 0: compensating a constant lag did not improve the '
                     'model on the Pathfinder logs (the lag drifts through a log, 0.095-0.165 s '
                     'on s5t1; docs/validation.md, effect E); the node measures it online and '
                     'names it in /diagnostics. import-pathfinder --measured-lag writes it.')
    measured = (f'gyro {facts.gyro_noise_density_rps_rthz:.2e} rad/s/sqrt(Hz), accel '
                f'{facts.accel_noise_density_mps2_rthz:.2e} m/s^2/sqrt(Hz)')
    names = 'gyro_noise_density_rps_rthz, accel_noise_density_mps2_rthz'
    if measured_noise:
        notes.append(f'{names}: measured at rest ({measured}).')
    else:
        notes.append(f'{names}: ADIS16495-2 datasheet, not the '
                     f'values measured at rest ({measured}): the excess at rest is vibration, '
                     'carried by vibration_noise_fraction (docs/validation.md, effect B). '
                     'import-pathfinder --measured-noise writes the measured values.')
    return notes
