"""Initial alignment: levelling at rest, and an in-motion start for robots that never stop.

At rest the mean specific force is minus gravity in the body frame (Groves sec. 5.6.2). In
motion it also carries the body's acceleration: along track the rate of change of the wheel
speed, across track the centripetal term (yaw rate x speed; FRD: a_y = omega_z v). Removing
both leaves minus gravity to within the wheels' error (slip changes, bumps), so roll and pitch
come out to a degree or so instead of the tens of degrees a 0.5 m/s^2 acceleration would tilt a
naive levelling by. Heading stays the configured one; the gyro bias cannot be separated from
the turn rate in motion and starts at zero with its prior uncertainty.

Accuracy of the in-motion start (measured in ``test/test_alignment.py`` on a simulated drive
joined while cruising): tilt within 1 deg. The velocity starts from the rim speed at zero slip,
so until the first stop's ZUPT the speed carries the slip of the ground it started on (+0.03 to
0.04 m/s at s = 0.05; 0.07 m/s RMS over the next 20 s through an uphill patch, against 0.02
for a start from rest); after the stop it is as good as a start from rest.

Only the standard library and numpy are used.
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

_NS = 1_000_000_000


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

    def add_imu(self, stamp_ns: int, f_b: list[float], w_b: list[float]) -> None:
        if self.first_ns is None:
            self.first_ns = stamp_ns
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

    def specific_force(self) -> np.ndarray:
        f, w = self.mean_imu()
        speed, accel = self.speed_and_accel()
        return gravity_specific_force(f, speed, accel, float(w[2]))
