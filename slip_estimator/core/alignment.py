"""Initial alignment: levelling at rest, and an in-motion start for robots that never stop.

:class:`AlignmentCollector` gathers the samples and decides when to align (a stationary
window, or ``motion_alignment_after_s`` without one) and when to re-level after a recovery;
the filter's starting point from its :class:`AlignmentStart` is
:mod:`~slip_estimator.core.filter_start`'s.

At rest the mean specific force is minus gravity in the body frame (Groves sec. 5.6.2). In
motion it also carries the body's acceleration: along track the rate of change of the wheel
speed, across track the centripetal term (yaw rate x speed; FRD: a_y = omega_z v). Removing
both leaves minus gravity to within the wheels' error (slip changes, bumps), so roll and pitch
come out to a degree or so instead of the tens of degrees a 0.5 m/s^2 acceleration would tilt a
naive levelling by. Heading stays the configured one; the gyro bias cannot be separated from
the turn rate in motion and starts at zero with its prior uncertainty.

Accuracy of the in-motion start (measured in ``test/unit/test_alignment.py`` on a simulated drive
joined while cruising): tilt within 1 deg. The velocity starts from the rim speed at zero slip,
so until the first stop's ZUPT the speed carries the slip of the ground it started on (+0.03 to
0.04 m/s at s = 0.05; 0.07 m/s RMS over the next 20 s through an uphill patch, against 0.02
for a start from rest); after the stop it is as good as a start from rest. On the simulated
robots of ``test/system/test_other_robots.py`` (docs/other-robots.md): tilt 0.2-0.3 deg (industrial
MEMS, 50 Hz) and 0.3-0.7 deg (consumer MEMS, 30 Hz); forward speed +3 to +16 % over the first
10 s.

Only the standard library and numpy are used.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from slip_estimator.core.params import Params
from slip_estimator.core.planet import Planet, gravity_n

_NS = 1_000_000_000
_MAX_TILT_DISAGREEMENT_RAD = math.radians(10.0)
"""An IMU orientation further than this from the wheel-corrected levelling is not used."""


def specific_force_problem(f_mean_b: np.ndarray, gravity_mps2: float) -> str | None:
    """What is wrong with an IMU whose mean specific force at alignment is ``f_mean_b`` (body
    FRD after the declared mounting), or None. REP-145 asks for the specific force in m/s^2
    with gravity in it: at rest or cruising it points up, with the planet's gravity as its
    magnitude (an acceleration moves it by a small fraction)."""
    f = np.asarray(f_mean_b, dtype=float)
    norm = float(np.linalg.norm(f))
    if abs(norm / gravity_mps2 - 1.0) <= 0.3:
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, -f[2] / norm))))
        if tilt > 45.0:
            return (f'gravity is {tilt:.0f} deg off the declared body z axis (specific force '
                    f'{f[0]:+.2f}, {f[1]:+.2f}, {f[2]:+.2f} m/s^2 in FRD): imu_to_base_rpy does '
                    'not describe how the IMU is mounted')
        return None
    if abs(norm - 1.0) <= 0.3:
        return (f'specific force magnitude {norm:.2f}: acceleration in g, not m/s^2 (REP-145); '
                'scale it by 9.81 in the driver')
    if norm < 0.3 * gravity_mps2:
        return (f'specific force magnitude {norm:.2f} m/s^2 where gravity is '
                f'{gravity_mps2:.2f}: gravity removed (linear acceleration, not REP-145 '
                'specific force); publish the raw accelerometer')
    return (f'specific force magnitude {norm:.2f} m/s^2 where gravity is {gravity_mps2:.2f}: '
            'wrong units or scale')


def tilt_from_orientation(q_imu_w_wxyz: tuple[float, float, float, float],
                          C_imu_b: np.ndarray) -> tuple[float, float] | None:
    """Roll and pitch (rad, FRD body in NED) from an IMU's orientation quaternion of imu_link in
    a z-up world frame (REP-103/145), given the mounting ``C_imu_b`` (imu -> body FRD); None
    for a quaternion that is not one (zero, non-finite, norm off by > 10 %). The heading is
    not used (a magnetometer's yaw is not the configured one)."""
    w, x, y, z = q_imu_w_wxyz
    n2 = w * w + x * x + y * y + z * z
    if not (math.isfinite(n2) and 0.81 <= n2 <= 1.21):
        return None
    # World up in imu_link (third row of C_world_imu, normalised), then down in body FRD.
    up_imu = np.array([2.0 * (x * z - w * y), 2.0 * (y * z + w * x),
                       w * w - x * x - y * y + z * z]) / n2
    down_b = -(C_imu_b @ up_imu)
    pitch = -math.asin(max(-1.0, min(1.0, float(down_b[0]))))
    roll = math.atan2(float(down_b[1]), float(down_b[2]))
    return roll, pitch


def level(f_b: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (rad, FRD body in NED) from a specific force that is minus gravity."""
    roll = math.atan2(-f_b[1], -f_b[2])
    pitch = math.atan2(f_b[0], math.hypot(f_b[1], f_b[2]))
    return roll, pitch


def gravity_specific_force(f_mean_b: np.ndarray, speed_mps: float, accel_mps2: float,
                           yaw_rate_b_rps: float) -> np.ndarray:
    """The mean specific force less the body's own acceleration (along track from the wheels,
    across track the centripetal term): what remains is minus gravity, body FRD, m/s^2."""
    return np.asarray(f_mean_b, dtype=float) - np.array(
        [accel_mps2, yaw_rate_b_rps * speed_mps, 0.0])


class MotionStart:
    """The last ``window_s`` of IMU and wheel samples, for an in-motion alignment.

    ``ready`` once the IMU window is full and a wheel sample is recent; ``specific_force``
    then gives minus gravity in the body frame and ``speed_mps`` the rim speed to start from.
    """

    def __init__(self, window_s: float = 1.0) -> None:
        self.window_ns = int(window_s * _NS)
        self._imu: deque = deque()  # (t, f_b, w_b)
        self._wheel: deque = deque()  # (t, rim speed)
        self.first_ns: int | None = None
        self.message_tilt_rp_rad: tuple[float, float] | None = None
        """Roll and pitch from the IMU's own orientation, latest sample (None: not provided)."""

    def add_imu(self, stamp_ns: int, f_b: list[float], w_b: list[float],
                tilt_rp_rad: tuple[float, float] | None = None) -> None:
        if self.first_ns is None:
            self.first_ns = stamp_ns
        self.message_tilt_rp_rad = tilt_rp_rad
        imu = self._imu
        imu.append((stamp_ns, f_b, w_b))
        while imu[0][0] < stamp_ns - self.window_ns:
            imu.popleft()

    def add_wheel(self, stamp_ns: int, rim_speed_mps: float) -> None:
        wheel = self._wheel
        wheel.append((stamp_ns, rim_speed_mps))
        while wheel[0][0] < stamp_ns - self.window_ns:
            wheel.popleft()

    def ready(self, stamp_ns: int) -> bool:
        return (len(self._imu) > 2 and self._imu[-1][0] - self._imu[0][0] >= 0.9 * self.window_ns
                and len(self._wheel) >= 2 and stamp_ns - self._wheel[-1][0] <= self.window_ns)

    def speed_and_accel(self) -> tuple[float, float]:
        """Latest rim speed (m/s) and its least-squares slope over the window (m/s^2)."""
        t = np.array([x[0] for x in self._wheel], dtype=float) * 1e-9
        v = np.array([x[1] for x in self._wheel])
        slope = float(np.polyfit(t - t[-1], v, 1)[0]) if np.ptp(t) > 0.0 else 0.0
        return float(v[-1]), slope

    def mean_imu(self) -> tuple[np.ndarray, np.ndarray]:
        f = np.array([x[1] for x in self._imu]).mean(axis=0)
        w = np.array([x[2] for x in self._imu]).mean(axis=0)
        return f, w

    def tilt(self) -> tuple[float, float]:
        """Roll and pitch (rad, FRD in NED) to start from: the IMU's own orientation when it
        provides one that agrees with the wheel-corrected levelling to
        ``_MAX_TILT_DISAGREEMENT_RAD`` (an identity quaternion left in the message by a driver
        that has none does not), else the levelling."""
        roll, pitch = level(self.specific_force())
        msg = self.message_tilt_rp_rad
        if msg is not None and max(abs(msg[0] - roll), abs(msg[1] - pitch)) \
                <= _MAX_TILT_DISAGREEMENT_RAD:
            return msg
        return roll, pitch

    def specific_force(self) -> np.ndarray:
        f, w = self.mean_imu()
        speed, accel = self.speed_and_accel()
        return gravity_specific_force(f, speed, accel, float(w[2]))


@dataclass(frozen=True)
class AlignmentStart:
    """The collector's decision: align now on this mean specific force (body FRD, m/s^2)."""

    f_b: np.ndarray
    """minus gravity in the body frame, m/s^2"""
    omega_ib_b: np.ndarray | None
    """mean gyro rate at rest (rad/s), None in motion (gyro bias starts at zero)"""
    speed_mps: float | None = None
    """in motion: the rim speed to start the velocity from, m/s; None at rest"""
    tilt_rp_rad: tuple[float, float] | None = None
    """in motion: roll and pitch to start from (:meth:`MotionStart.tilt`); None: levelling"""


class AlignmentCollector:
    """Collects the samples an alignment needs and says when and how to align.

    At rest: a stationary window of ``alignment_duration_s``. Without one for
    ``motion_alignment_after_s``: in motion (:class:`MotionStart`). An IMU that does not follow
    REP-145 is named (:attr:`imu_problem`) and not aligned on: no estimate beats a wrong one.
    """

    def __init__(self, p: Params, planet: Planet) -> None:
        self._duration_s = p.alignment_duration_s
        self._motion_after_ns = p.motion_alignment_after_s * _NS
        g_n = gravity_n(planet, math.radians(p.initial_latitude_deg), p.initial_height_m)
        self._gravity_mps2 = float(np.linalg.norm(g_n))
        self._rows: list[np.ndarray] = []
        self.motion = MotionStart()
        self.imu_problem: str | None = None
        self.releveling = False

    def start_relevel(self) -> None:
        """After a recovery: collect a fresh window for :meth:`relevel` (the attitude the INS
        kept across a long IMU gap may be tilted by the terrain it drove over since)."""
        if not self.releveling:
            self.motion, self.releveling = MotionStart(), True

    def relevel(self, f_b: np.ndarray, w_b: np.ndarray, stamp_ns: int) -> AlignmentStart | None:
        """One IMU sample while re-levelling; the in-motion levelling once the window is full
        (wheel samples go to :meth:`add_wheel`)."""
        motion = self.motion
        motion.add_imu(stamp_ns, f_b, w_b)
        if not motion.ready(stamp_ns):
            return None
        self.releveling = False
        speed, _ = motion.speed_and_accel()
        return AlignmentStart(motion.specific_force(), None, speed)

    def add_wheel(self, stamp_ns: int, rim_speed_mps: float) -> None:
        self.motion.add_wheel(stamp_ns, rim_speed_mps)

    def add_imu(self, f_b: np.ndarray, w_b: np.ndarray, stamp_ns: int, stationary: bool,
                nominal_dt_s: float,
                tilt_rp_rad: tuple[float, float] | None = None) -> AlignmentStart | None:
        """One IMU sample (``stationary``: the detector's verdict now; ``tilt_rp_rad``: roll
        and pitch from the IMU's own orientation, if provided); the alignment to do, if any."""
        motion = self.motion
        motion.add_imu(stamp_ns, f_b, w_b, tilt_rp_rad)
        if not stationary:
            self._rows.clear()
            if (stamp_ns - motion.first_ns >= self._motion_after_ns
                    and motion.ready(stamp_ns)
                    and not self._refused(motion.mean_imu()[0])):
                f = motion.specific_force()
                speed, _ = motion.speed_and_accel()
                return AlignmentStart(f, None, speed, motion.tilt())
            return None
        self._rows.append(np.concatenate([f_b, w_b]))
        if len(self._rows) * nominal_dt_s >= self._duration_s:
            rows = np.array(self._rows)
            if not self._refused(rows[:, :3].mean(axis=0)):
                return AlignmentStart(rows[:, :3].mean(axis=0), rows[:, 3:].mean(axis=0))
        return None

    def _refused(self, f_mean_b: np.ndarray) -> bool:
        self.imu_problem = specific_force_problem(f_mean_b, self._gravity_mps2)
        return self.imu_problem is not None
