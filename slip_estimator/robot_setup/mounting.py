"""The IMU as published: gravity (REP-145), units, clipping, and its mounting in base_link.

The mounting ``C_imu_base`` (imu_link vectors to base_link FLU, the static transform of
``imu_to_base_rpy``) is found from two axes the data show in imu_link coordinates:

* **up** (base_link z): the specific force at rest points up with gravity's magnitude
  (REP-145; Groves sec. 5.6.2). Without rest or with gravity removed, the yaw-rate axis: in
  turns the gyro vector regressed on the wheel differential ``v_R - v_L`` (with an intercept
  for the bias) is ``z_base / B_eff`` (a counter-clockwise turn drives the right side faster),
  so its direction is up and its length the inverse effective track. With both, they must
  agree (otherwise the gyro and accelerometer axes disagree: the frame is not right-handed).
* **forward** (base_link x): in the plane normal to up, the horizontal specific force
  ``h`` follows the body's acceleration in base_link, ``(dv/dt, v * omega_up)`` (along track
  from the rim speed, across track centripetal). The rotation angle ``theta`` of
  ``h = R(theta) a`` in least squares (2-D Procrustes) gives x; slow parts (bias, slopes) are
  removed from both by a 10 s high-pass.

A mounting within ``SNAP_DEG`` of one of the 24 axis-aligned rotations is that rotation
exactly; otherwise the measured angles stand if their spread allows, else it is undecided.
Only numpy and the core's frame helpers are used.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from slip_estimator.core.frames import dcm_to_rpy
from slip_estimator.robot_setup.signals import (
    Figure,
    ImuSeries,
    WheelSeries,
    blocks,
    missing,
    window_mean,
)

GRAVITY_MPS2 = 9.80665
SNAP_DEG = 10.0
"""A mounting this close to an axis-aligned rotation is that rotation."""
MAX_YAW_SPREAD_DEG = 3.0
"""A continuous (not axis-aligned) yaw is written only with a spread below this."""
MIN_FORWARD_CORRELATION = 0.3
"""Horizontal specific force vs body acceleration: below this the forward axis is unknown."""
MAX_AXIS_DISAGREEMENT_DEG = 20.0
MIN_TURN_RPS = 0.05
"""Wheel differentials whose yaw rate is below this are not turns (noise)."""
HIGH_PASS_S = 10.0
SMOOTH_S = 0.5


@dataclass(frozen=True)
class ImuCheck:
    """What the IMU's messages say about themselves.

    ``gravity``: 'present', 'removed', 'in g' (units), 'scale?' or 'no rest' (undecided);
    ``f_rest_imu_mps2``: mean specific force at rest (imu_link); ``gyro_units``: 'rad/s',
    'deg/s' or '' (undecided); ``clipping``: one line per clipping axis."""

    gravity: str
    f_rest_imu_mps2: tuple[float, float, float] | None
    rest_samples: int
    gyro_units: str
    clipping: tuple[str, ...] = ()


@dataclass(frozen=True)
class Mounting:
    """The measured mounting: ``rpy_rad`` (None: undecided), ``exact`` (an axis-aligned
    rotation), the sources of up and forward, the angles' figures and what was not decided."""

    rpy_rad: tuple[float, float, float] | None
    exact: bool
    up_from: str
    up_imu: tuple[float, float, float] | None
    yaw_deg: Figure
    track_m: Figure
    notes: tuple[str, ...] = field(default_factory=tuple)


def check_imu(imu: ImuSeries, rest: np.ndarray, track_m: Figure, declared_track_m: float
              ) -> ImuCheck:
    """Gravity, units and clipping of the IMU (``rest``: mask of IMU samples at rest;
    ``track_m``: the effective track from the turn axis, for the gyro units)."""
    f_rest, gravity = None, 'no rest'
    if rest.sum() >= 10:
        f = imu.f_imu_mps2[rest].mean(axis=0)
        f_rest = tuple(float(x) for x in f)
        norm = float(np.linalg.norm(f))
        if abs(norm / GRAVITY_MPS2 - 1.0) <= 0.3:
            gravity = 'present'
        elif abs(norm - 1.0) <= 0.3:
            gravity = 'in g'
        elif norm < 0.3 * GRAVITY_MPS2:
            gravity = 'removed'
        else:
            gravity = 'scale?'
    units = ''
    if track_m.ok:
        ratio = track_m.value / declared_track_m
        units = 'rad/s' if 0.3 <= ratio <= 5.0 else (
            'deg/s' if 0.3 <= ratio * 180.0 / math.pi <= 5.0 else '')
    return ImuCheck(gravity, f_rest, int(rest.sum()), units, clipping(imu))


def clipping(imu: ImuSeries, min_repeats: int = 3) -> tuple[str, ...]:
    """Axes whose largest magnitude repeats (a flat top: the sensor's range)."""
    out = []
    for name, x, unit in (('accel', imu.f_imu_mps2, 'm/s^2'), ('gyro', imu.omega_imu_rps,
                                                               'rad/s')):
        for k, axis in enumerate('xyz'):
            a = np.abs(x[:, k])
            top = float(a.max()) if len(a) else 0.0
            n = int(np.sum(a >= top * (1.0 - 1e-6))) if top > 0 else 0
            if n >= min_repeats:
                out.append(f'{name} {axis} clips at {top:.3g} {unit} ({n} samples)')
    return tuple(out)


def turn_axis(imu: ImuSeries, wheels: WheelSeries, lag_s: float
              ) -> tuple[np.ndarray | None, int]:
    """Gyro vector per unit wheel differential (rad/s per m/s, imu_link), fitted with an
    intercept over the wheel samples (``lag_s``: wheel stamps behind the IMU); None without
    a differential that varies."""
    ok = np.isfinite(wheels.diff_mps)
    t = wheels.t_s[ok] - lag_s
    d = wheels.diff_mps[ok]
    w = window_mean(imu.t_s, imu.omega_imu_rps, t, 0.1)
    good = np.isfinite(w).all(axis=1)
    d, w = d[good], w[good]
    if len(d) < 20 or d.std() <= 0.0:
        return None, 0
    dc = d - d.mean()
    k = (dc @ (w - w.mean(axis=0))) / (dc @ dc)
    return k, int(np.sum(np.abs(d) > 1e-3))


def forward_angle(imu: ImuSeries, wheels: WheelSeries, up_imu: np.ndarray, lag_s: float
                  ) -> tuple[Figure, np.ndarray, np.ndarray]:
    """Angle (deg) of base_link x from ``e1`` in the level plane (basis ``e1, e2`` normal to
    ``up_imu``), and that basis. See the module docstring."""
    up = up_imu / np.linalg.norm(up_imu)
    e1 = np.cross(up, [0.0, 0.0, 1.0] if abs(up[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    t0, t1 = max(imu.t_s[0], wheels.t_s[0]) + 1.0, min(imu.t_s[-1], wheels.t_s[-1]) - 1.0
    if t1 - t0 < HIGH_PASS_S:
        return missing('drive too short for the forward axis'), e1, e2
    tq = np.arange(t0, t1, 0.1)
    v = window_mean(wheels.t_s - lag_s, wheels.v_mps, tq, SMOOTH_S)
    omega = window_mean(imu.t_s, imu.omega_imu_rps @ up, tq, SMOOTH_S)
    f = window_mean(imu.t_s, imu.f_imu_mps2, tq, SMOOTH_S)
    ok = np.isfinite(v) & np.isfinite(omega) & np.isfinite(f).all(axis=1)
    tq, v, omega, f = tq[ok], v[ok], omega[ok], f[ok]
    if len(tq) < 50:
        return missing('too few samples for the forward axis'), e1, e2
    a = np.column_stack([np.gradient(v, tq), v * omega])
    h = np.column_stack([f @ e1, f @ e2])
    a -= window_mean(tq, a, tq, HIGH_PASS_S)
    h -= window_mean(tq, h, tq, HIGH_PASS_S)

    def angle(idx: np.ndarray) -> tuple[float, float]:
        cross = float(np.sum(a[idx, 0] * h[idx, 1] - a[idx, 1] * h[idx, 0]))
        dot = float(np.sum(a[idx, 0] * h[idx, 0] + a[idx, 1] * h[idx, 1]))
        norm = math.sqrt(float(np.sum(a[idx] ** 2) * np.sum(h[idx] ** 2)))
        return math.atan2(cross, dot), (math.hypot(cross, dot) / norm if norm > 0 else 0.0)

    theta, corr = angle(np.arange(len(tq)))
    if corr < MIN_FORWARD_CORRELATION:
        return missing(f'horizontal specific force does not follow the wheel acceleration '
                       f'(r = {corr:.2f})'), e1, e2
    # Jackknife over eighths of the drive (a part without manoeuvres has no angle of its own).
    parts = blocks(len(tq))
    dev = np.array([math.remainder(angle(np.setdiff1d(np.arange(len(tq)), b))[0] - theta,
                                   2 * math.pi) for b in parts])
    spread = float(math.sqrt((len(dev) - 1) / len(dev) * np.sum((dev - dev.mean()) ** 2)))
    return Figure(math.degrees(theta), math.degrees(spread), len(tq)), e1, e2


def axis_aligned_rotations() -> list[np.ndarray]:
    """The 24 proper rotations whose rows are signed unit axes."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            for row, (col, s) in enumerate(zip(perm, signs)):
                R[row, col] = s
            if np.linalg.det(R) > 0:
                out.append(R)
    return out


def snap(C: np.ndarray) -> tuple[np.ndarray, float]:
    """The nearest axis-aligned rotation to ``C`` and the angle between them, deg."""
    best, best_deg = C, 180.0
    for R in axis_aligned_rotations():
        c = max(-1.0, min(1.0, (float(np.trace(R.T @ C)) - 1.0) / 2.0))
        deg = math.degrees(math.acos(c))
        if deg < best_deg:
            best, best_deg = R, deg
    return best, best_deg


def find_mounting(imu: ImuSeries, wheels: WheelSeries, check: ImuCheck,
                  turn_k: np.ndarray | None, turns: int, lag_s: float) -> Mounting:
    """The mounting from the up axis (gravity at rest, else the yaw-rate axis) and the
    forward axis; undecided (``rpy_rad`` None) with the reason in ``notes``."""
    notes = []
    up_turn = None
    track = missing('no turns (the wheel differential never varies)')
    if turn_k is not None and np.linalg.norm(turn_k) > 0:
        up_turn = turn_k / np.linalg.norm(turn_k)
        track = Figure(1.0 / float(np.linalg.norm(turn_k)), n=turns)
    up, up_from = None, ''
    if check.gravity == 'present' and check.f_rest_imu_mps2 is not None:
        up = np.array(check.f_rest_imu_mps2) / np.linalg.norm(check.f_rest_imu_mps2)
        up_from = 'gravity at rest'
        if up_turn is not None:
            off = math.degrees(math.acos(max(-1.0, min(1.0, float(up @ up_turn)))))
            if off > MAX_AXIS_DISAGREEMENT_DEG:
                notes.append(f'the yaw-rate axis in turns is {off:.0f} deg from gravity\'s: '
                             'the gyro and accelerometer axes disagree (sign or order)')
                return Mounting(None, False, '', None, missing('axes disagree'), track,
                                tuple(notes))
    elif up_turn is not None and turns >= 20:
        up, up_from = up_turn, 'yaw-rate axis in turns'
    if up is None:
        notes.append('up axis undecided: no rest with gravity and no turns')
        return Mounting(None, False, '', None, missing('no up axis'), track, tuple(notes))
    yaw, e1, e2 = forward_angle(imu, wheels, up, lag_s)
    if not yaw.ok:
        notes.append(f'forward axis undecided: {yaw.why}')
        return Mounting(None, False, up_from, tuple(map(float, up)), yaw, track, tuple(notes))
    th = math.radians(yaw.value)
    x = math.cos(th) * e1 + math.sin(th) * e2
    C_imu_base = np.vstack([x, np.cross(up, x), up])
    R, off_deg = snap(C_imu_base)
    exact = off_deg <= SNAP_DEG
    if not exact and not yaw.spread <= MAX_YAW_SPREAD_DEG:
        notes.append(f'mounting {off_deg:.0f} deg from any axis-aligned one and its yaw '
                     f'spread {yaw.spread:.1f} deg: undecided')
        return Mounting(None, False, up_from, tuple(map(float, up)), yaw, track, tuple(notes))
    rpy = dcm_to_rpy(R if exact else C_imu_base)
    rpy = tuple(0.0 if abs(a) < 1e-12 else float(a) for a in rpy)
    return Mounting(rpy, exact, up_from, tuple(map(float, up)), yaw, track, tuple(notes))
