"""Bag side of ``setup``: find the input topics, their rates, gaps and stamps, and read them
into the plain series of :mod:`~slip_estimator.robot_setup.signals` (the only ROS part).

Messages are converted with the node's own functions (:mod:`slip_estimator.ros.convert`), so
the wheel speeds ``setup`` measures on are the ones the estimator will see.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from slip_estimator.bagio import bag_topics, read_messages
from slip_estimator.core.params import Params
from slip_estimator.core.planet import PLANETS, llh_to_local_enu
from slip_estimator.robot_setup.signals import GnssSeries, ImuSeries, WheelSeries
from slip_estimator.ros import convert
from slip_estimator.streams import wheel_side

IMU, JOINTS, ODOM, TWIST, FIX = ('sensor_msgs/msg/Imu', 'sensor_msgs/msg/JointState',
                                 'nav_msgs/msg/Odometry', 'geometry_msgs/msg/TwistStamped',
                                 'sensor_msgs/msg/NavSatFix')
NOT_WHEELS = ('truth', 'ground_truth', 'filtered', 'slip_estimator', 'gps', 'gnss', 'ekf',
              'global', 'visual', 'lidar')
"""Odometry topics whose name holds one of these are not the wheels' own."""
GAP_FACTOR = 3.0
"""A stamp step this many median periods long is a gap."""


@dataclass(frozen=True)
class TopicStats:
    """One input topic: messages, rate from the median stamp step, gaps, stamp sanity."""

    topic: str
    msgtype: str
    count: int
    rate_hz: float
    gaps: int
    max_gap_s: float
    zero_stamps: int
    backwards: int
    stamp_minus_log_s: float

    def line(self) -> str:
        bad = []
        if self.zero_stamps:
            bad.append(f'{self.zero_stamps} zero stamps')
        if self.backwards:
            bad.append(f'{self.backwards} stamps going back')
        if abs(self.stamp_minus_log_s) > 0.5:
            bad.append(f'stamps {self.stamp_minus_log_s:+.1f} s from the log time')
        gaps = f'{self.gaps} gaps (max {self.max_gap_s:.2f} s)' if self.gaps else 'no gaps'
        return (f'{self.topic} [{self.msgtype.split("/")[-1]}] {self.count} msgs, '
                f'{self.rate_hz:.1f} Hz, {gaps}' + (', ' + ', '.join(bad) if bad else ''))


@dataclass
class Scan:
    """The chosen inputs, their series, and the stats of every candidate topic."""

    imu_topic: str
    wheel_topic: str
    wheel_input: str
    joint_names: list[str]
    imu: ImuSeries
    wheels: WheelSeries
    gnss: GnssSeries | None
    gnss_topic: str | None
    stats: list[TopicStats]
    notes: list[str] = field(default_factory=list)


class SetupError(ValueError):
    """The bag lacks what setup needs (one line for the user)."""


def _stats(topic: str, msgtype: str, stamps: list[int], logs: list[int]) -> TopicStats:
    s = np.array(stamps, dtype=np.int64)
    valid = s[s > 0]
    d = np.diff(valid) * 1e-9
    fwd = d[d > 0]
    med = float(np.median(fwd)) if len(fwd) else float('nan')
    gaps = fwd > GAP_FACTOR * med if len(fwd) else np.zeros(0, bool)
    offset = (float(np.median((s[s > 0] - np.array(logs, dtype=np.int64)[s > 0]) * 1e-9))
              if len(valid) else float('nan'))
    return TopicStats(topic, msgtype, len(s), 1.0 / med if med > 0 else 0.0, int(gaps.sum()),
                      float(fwd[gaps].max()) if gaps.any() else 0.0, int(np.sum(s <= 0)),
                      int(np.sum(d < 0)), offset)


def _pick_wheels(topics: dict[str, str], declared: Params, joint_msg: dict[str, object],
                 keys: set[str] | None) -> tuple[str, str]:
    """(wheel topic, wheel_input): the declared one when the bag has it; else joint states
    naming left and right wheels when the wheel radius is declared (they need it), the wheels'
    odometry (in m/s already), joint states whatever the radius (``keys``: the parameters
    declared, None: all)."""
    want = (declared.joint_states_topic if declared.wheel_input == 'joint_states'
            else declared.wheel_odometry_topic)
    input_declared = keys is None or bool(keys & {'wheel_input', 'joint_states_topic',
                                                  'wheel_odometry_topic'})
    if input_declared and topics.get(want) == (JOINTS if declared.wheel_input == 'joint_states'
                                               else ODOM):
        return want, declared.wheel_input
    joints = [t for t, m in joint_msg.items() if {'left', 'right'} <= set(map(wheel_side,
                                                                             m.name))]
    odoms = sorted((t for t, ty in topics.items() if ty == ODOM
                    and not any(w in t.lower() for w in NOT_WHEELS)),
                   key=lambda t: ('wheel' not in t, t))
    if joints and (keys is None or 'wheel_radius' in keys or not odoms):
        return joints[0], 'joint_states'
    if odoms:
        return odoms[0], 'odometry'
    have = ', '.join(f'{t} [{ty}]' for t, ty in sorted(topics.items()))
    raise SetupError(f'no wheel topic (JointState naming left/right wheel joints, or wheel '
                     f'Odometry) in the bag; it has: {have}')


def joint_names(msg: object, declared: list[str]) -> list[str]:
    """The declared joints when the message names them, else its joints with a side (those
    named 'wheel' when some are)."""
    if any(n in msg.name for n in declared):
        return [n for n in declared if n in msg.name]
    sided = [n for n in msg.name if wheel_side(n)]
    wheels = [n for n in sided if 'wheel' in n.lower()]
    return wheels or sided


def scan_bag(path: str | Path, declared: Params, declared_keys: set[str] | None = None
             ) -> Scan:
    """Find and read the IMU, wheel and GNSS topics of a bag (``declared_keys``: the
    parameters the user set; None: all of them)."""
    topics = bag_topics(path)
    imus = [t for t, ty in topics.items() if ty == IMU]
    if not imus:
        have = ', '.join(f'{t} [{ty}]' for t, ty in sorted(topics.items())) or 'no topics'
        raise SetupError(f'no sensor_msgs/Imu topic in the bag; it has: {have}')
    wanted = {t for t, ty in topics.items() if ty in (IMU, JOINTS, ODOM, TWIST, FIX)}
    stamps: dict[str, list[int]] = {t: [] for t in wanted}
    logs: dict[str, list[int]] = {t: [] for t in wanted}
    msgs: dict[str, list] = {t: [] for t in wanted}
    for m in read_messages(path, wanted):
        stamps[m.topic].append(convert.header_stamp_ns(m.msg))
        logs[m.topic].append(m.log_time_ns)
        msgs[m.topic].append(m.msg)
    stats = [_stats(t, topics[t], stamps[t], logs[t]) for t in sorted(wanted) if stamps[t]]
    imu_topic = (declared.imu_topic if declared.imu_topic in imus
                 else max(imus, key=lambda t: len(msgs[t])))
    first_joint = {t: msgs[t][0] for t in wanted if topics[t] == JOINTS and msgs[t]}
    wheel_topic, wheel_input = _pick_wheels(topics, declared, first_joint, declared_keys)
    notes = [f'{t} [TwistStamped]: wheel twist is not an input of the estimator (publish '
             'nav_msgs/Odometry or JointState)' for t, ty in topics.items() if ty == TWIST]
    imu = _imu_series(msgs[imu_topic])
    names: list[str] = []
    if wheel_input == 'joint_states':
        names = joint_names(first_joint[wheel_topic], list(declared.wheel_joint_names))
        if not names:
            raise SetupError(f'{wheel_topic}: no joint names with left/right in them')
    if len(imu.t_s) < 100:
        raise SetupError(f'{imu_topic}: fewer than 100 usable IMU messages ({len(imu.t_s)})')
    t0_ns = int(imu.t_s[0])
    imu = ImuSeries((imu.t_s - t0_ns) * 1e-9, imu.f_imu_mps2, imu.omega_imu_rps)
    wheels = _wheel_series(msgs[wheel_topic], wheel_input, names, declared, t0_ns)
    fixes = [t for t, ty in topics.items() if ty == FIX and msgs[t]]
    gnss_topic = max(fixes, key=lambda t: len(msgs[t])) if fixes else None
    gnss = _gnss_series(msgs[gnss_topic], t0_ns) if gnss_topic else None
    return Scan(imu_topic, wheel_topic, wheel_input, names, imu, wheels, gnss, gnss_topic,
                stats, notes)


def _imu_series(msgs: list) -> ImuSeries:
    """Raw IMU arrays (stamps in ns for now), stamp-sorted, invalid stamps dropped."""
    rows = sorted((convert.header_stamp_ns(m), m.linear_acceleration, m.angular_velocity)
                  for m in msgs if convert.header_stamp_ns(m) > 0)
    t = np.array([r[0] for r in rows], dtype=np.int64)
    f = np.array([[r[1].x, r[1].y, r[1].z] for r in rows])
    w = np.array([[r[2].x, r[2].y, r[2].z] for r in rows])
    ok = np.isfinite(f).all(axis=1) & np.isfinite(w).all(axis=1)
    keep = np.concatenate([[True], np.diff(t) > 0]) & ok
    return ImuSeries(t[keep], f[keep], w[keep])


def _wheel_series(msgs: list, wheel_input: str, names: list[str], declared: Params,
                  t0_ns: int) -> WheelSeries:
    """Rim speeds through the node's converters (declared radius and track)."""
    msgs = sorted(msgs, key=convert.header_stamp_ns)
    rates = convert.JointRatesFromPositions(declared.max_wheel_speed_mps / declared.wheel_radius)
    rows = []
    for m in msgs:
        if wheel_input == 'joint_states':
            s = convert.wheel_from_joint_state(m, names, declared.wheel_radius,
                                               from_positions=rates)
        else:
            s = convert.wheel_from_odometry(m, declared.track_width)
        if isinstance(s, str):
            continue
        diff = (s.rim_speed_right_mps - s.rim_speed_left_mps
                if s.rim_speed_left_mps is not None and s.rim_speed_right_mps is not None
                else float('nan'))
        rows.append(((s.stamp_ns - t0_ns) * 1e-9, s.rim_speed_mps, diff))
    if len(rows) < 10:
        raise SetupError(f'fewer than 10 usable wheel messages ({len(rows)}) on the wheel topic')
    a = np.array(rows)
    return WheelSeries(a[:, 0], a[:, 1], a[:, 2])


def _gnss_series(msgs: list, t0_ns: int) -> GnssSeries | None:
    """Valid fixes (status >= 0, finite) in ENU from the first one."""
    fixes = sorted((convert.header_stamp_ns(m), m) for m in msgs
                   if m.status.status >= 0 and math.isfinite(m.latitude + m.longitude
                                                              + m.altitude))
    if len(fixes) < 2:
        return None
    llh = np.array([[math.radians(m.latitude), math.radians(m.longitude), m.altitude]
                    for _, m in fixes])
    enu = np.array([llh_to_local_enu(PLANETS['earth'], x, llh[0]) for x in llh])
    t = np.array([(s - t0_ns) * 1e-9 for s, _ in fixes])
    return GnssSeries(t, tuple(float(x) for x in llh[0]), enu)
