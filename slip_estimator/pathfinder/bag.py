"""Writing a Pathfinder log as a bag (``/imu/data``, ``/joint_states``, ``/gnss/fix``) and the
whole import (bag + params file) behind ``slip-estimator import-pathfinder``."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from slip_estimator.core.params import Params
from slip_estimator.pathfinder.facts import LogFacts, log_facts
from slip_estimator.pathfinder.log import PathfinderLog, read_pathfinder_mat
from slip_estimator.pathfinder.params import params_notes, pathfinder_params
from slip_estimator.pathfinder.rover import (
    ACCEL_VRW_MPS_PER_SQRT_S,
    GYRO_ARW_RAD_PER_SQRT_S,
    RTK_SIGMA_M,
    WHEEL_JOINT_NAMES,
)


def _stamp(msg_header, t_s: float) -> int:
    from slip_estimator.ros.stamps import ns_to_stamp

    ns = round(t_s * 1e9)
    msg_header.stamp = ns_to_stamp(ns)
    return ns


def write_bag(log: PathfinderLog, bag_path: str | Path, progress: bool = False) -> dict[str, int]:
    """Write ``/imu/data``, ``/joint_states`` and ``/gnss/fix`` with the recorded stamps.

    Messages are written in time order; the log time equals the header stamp.
    Returns the message count per topic.
    """
    from sensor_msgs.msg import Imu, JointState, NavSatFix, NavSatStatus

    from slip_estimator.bagio import BagWriter
    from slip_estimator.progress import Progress

    line = Progress(progress)
    dt_imu = float(np.median(np.diff(log.imu_t_s)))
    gyro_var = GYRO_ARW_RAD_PER_SQRT_S ** 2 / dt_imu
    accel_var = ACCEL_VRW_MPS_PER_SQRT_S ** 2 / dt_imu
    events = ([(t, 0, i) for i, t in enumerate(log.imu_t_s)]
              + [(t, 1, i) for i, t in enumerate(log.wheel_t_s)]
              + [(t, 2, i) for i, t in enumerate(log.gnss_t_s)])
    events.sort()
    counts = {'/imu/data': 0, '/joint_states': 0, '/gnss/fix': 0}
    with BagWriter(bag_path) as bag:
        for n, (t, kind, i) in enumerate(events):
            if kind == 0:
                msg = Imu()
                msg.header.frame_id = 'imu_link'
                ns = _stamp(msg.header, t)
                msg.orientation_covariance[0] = -1.0  # no orientation estimate
                w, f = log.omega_ib_imu[i], log.f_ib_imu[i]
                av, la = msg.angular_velocity, msg.linear_acceleration
                av.x, av.y, av.z = (float(x) for x in w)
                la.x, la.y, la.z = (float(x) for x in f)
                for k in (0, 4, 8):
                    msg.angular_velocity_covariance[k] = gyro_var
                    msg.linear_acceleration_covariance[k] = accel_var
                topic = '/imu/data'
            elif kind == 1:
                msg = JointState()
                ns = _stamp(msg.header, t)
                msg.name = list(WHEEL_JOINT_NAMES)
                msg.position = [float(x) for x in log.wheel_angle_rad[i]]
                msg.velocity = [float(x) for x in log.wheel_rate_rps[i]]
                topic = '/joint_states'
            else:
                msg = NavSatFix()
                msg.header.frame_id = 'gnss_link'
                ns = _stamp(msg.header, t)
                msg.status.status = NavSatStatus.STATUS_FIX
                msg.status.service = NavSatStatus.SERVICE_GPS
                lat, lon, h = log.gnss_llh[i]
                msg.latitude, msg.longitude, msg.altitude = (math.degrees(lat),
                                                             math.degrees(lon), float(h))
                if log.gnss_sigma_enu_m is not None:
                    sig = log.gnss_sigma_enu_m[i]
                    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
                else:
                    sig = RTK_SIGMA_M
                    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_APPROXIMATED
                # NavSatFix covariance is in ENU order (east, north, up).
                for k, s in zip((0, 4, 8), sig):
                    msg.position_covariance[k] = float(s) ** 2
                topic = '/gnss/fix'
            bag.write(topic, msg, ns)
            counts[topic] += 1
            if n % 5000 == 0:
                line.show(f'  writing {n}/{len(events)} messages')
    line.done(f'  wrote {len(events)} messages')
    return counts


def import_pathfinder(mat_path: str | Path, bag_path: str | Path,
                      params_path: str | Path | None = None, *, measured_noise: bool = False,
                      measured_lag: bool = False, heading_deg: float | None = None,
                      progress: bool = False) -> tuple[PathfinderLog, LogFacts, Params]:
    """Convert a Pathfinder ``.mat`` log to an MCAP bag (and a params file when requested,
    with :func:`params_notes` as its header comments).

    Returns the log, its checked facts and the parameters written. ``heading_deg`` overrides
    the initial heading estimated from GNSS.
    """
    from slip_estimator.paramfile import save_params

    log = read_pathfinder_mat(mat_path)
    facts = log_facts(log)
    heading = facts.heading.heading_deg if heading_deg is None else heading_deg
    params = pathfinder_params(log, heading, measured_noise)
    if measured_lag:
        params = params.replace(wheel_latency_s=facts.wheel_lag_s)
    write_bag(log, bag_path, progress=progress)
    if params_path is not None:
        save_params(params, params_path,
                    comments=params_notes(facts, measured_noise, measured_lag))
    return log, facts, params
