"""Exact truth kinematics of the seeded skid-steer rover on a fine time grid.

Truth (all on a flat local tangent plane, ENU axes at the start = ROS ``odom``):

1. Profiles of forward body speed v(t), heading rate, slip s(t) and wheel spin are blended
   from the segment targets with C2 smootherstep ramps, on a fine grid (rate_imu * oversample).
2. Heading psi = integral of the heading rate. The horizontal position integrates
   v / sqrt(1 + g_f^2) (cos psi, sin psi), where g_f is the terrain gradient along the heading,
   so the rover travels at speed v along the surface; z = terrain(x, y). This is solved by a
   fixed-point iteration (the gradient depends on the position) to < 1e-9 m.
   A grade-driven run-ahead (``Segment.grade_driven``) is gravity's: under wheel control a
   negative scripted slip s_c (the body running ahead of held wheels) develops only as far
   as the local downhill grade of the terrain under the rover (hills + undulation, the slope
   the IMU sees), sin(theta) = -g_f / sqrt(1 + g_f^2), exceeds the rolling resistance:
   s = s_c * S((sin theta - c_rr) / (G_FULL - c_rr)), S the C2 smootherstep clipped to
   [0, 1], c_rr = ROLLING_RESISTANCE (firm soil) and G_FULL the grade at which the scripted
   slip is fully developed. On level or nose-up ground the held wheels hold the body (s = 0).
   The body speed then depends on the position, so the path is solved forward in pieces
   (0.25 s inside such a run-ahead), each by the fixed point above.
3. base_link attitude ``C_base_o = Rz(psi) Ry(pitch) Rx(roll)`` with pitch = -atan(g_f) and
   roll = atan(g_l / sqrt(1 + g_f^2)) (g_l: gradient to the left): x and y of base_link lie
   in the terrain tangent plane, and the base_link velocity is (v, 0, 0) in FLU. Optional
   chassis rocking (``TerrainConfig.rocking_harmonics``, off by default) adds roll and pitch
   about that attitude, and with ``rocking_pivot_depth_m`` the swing of base_link about an
   axis below it to the position and velocity; an optional fore-aft surge
   (``TerrainConfig.surge_harmonics``) moves base_link along its forward axis about the path
   (position and velocity; the rims keep the path's speed).
4. IMU (REP-145, instantaneous values at the sample time): with central differences on the
   fine grid, ``omega_eb_b`` from the DCM, ``a_eb_o`` from the velocity, then
   ``omega_ib_b = omega_eb_b + C_o_b omega_ie_o`` and
   ``f_ib_b = C_o_b (a - g + 2 omega_ie x v)`` (Groves eq. 5.53 in a planet-fixed frame;
   gravity and planet rate constant at the start latitude/height; the curvature of the
   tangent plane, < 1e-4 rad over a few hundred metres, is neglected), plus the lever-arm
   terms ``alpha x r + omega x (omega x r)``, resolved in imu_link.
5. Wheels: side speeds v -/+ omega_z T/2, rim speed r*w = side speed * K(s) + spin with
   K = 1/(1-s) for s >= 0 and 1+s for s < 0 (paper eq. 1 solved for r*w). The slip truth is
   eq. 1 evaluated on the body speed and the mean rim speed at the wheel sample time.

Also the slip maths of paper eq. 1 shared with the sensor models. Only the standard library
and numpy are imported here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slip_estimator.core.frames import C_ENU_NED, heading_to_yaw_enu
from slip_estimator.core.planet import PLANETS, earth_rate_n, gravity_n
from slip_estimator.core.slip import slip_class_array, slip_ratio_array
from slip_estimator.sim.chassis import rocking_rad, surge_m
from slip_estimator.sim.kinematics import attitude_dcm, central_diff, cumtrapz, vee_rel
from slip_estimator.sim.scenario import WHEEL_IS_LEFT, ScenarioConfig

MOVING_SPEED_THRESHOLD_MPS = 0.02
"""Below this body speed and mean rim speed the rover is 'not moving' (slip class 0)."""
ROLLING_RESISTANCE = 0.05
"""Rolling-resistance coefficient of the rover on firm soil: a downhill grade (sine of the
slope) below it does not drive the body ahead of held wheels (module docstring, step 2)."""
G_FULL = 0.15
"""Downhill grade (sine of the slope, ~8.6 deg) at which a scripted run-ahead slip is fully
developed."""


# --- slip maths (paper eq. 1) -------------------------------------------------------------------

def slip_ratio(body_speed_mps: np.ndarray, rim_speed_mps: np.ndarray) -> np.ndarray:
    """Longitudinal slip (paper eq. 1), the core's definition."""
    return slip_ratio_array(body_speed_mps, rim_speed_mps)


def slip_class(slip: np.ndarray, body_speed_mps: np.ndarray, rim_speed_mps: np.ndarray,
               moving_threshold_mps: float = MOVING_SPEED_THRESHOLD_MPS) -> np.ndarray:
    """Class index 0..4 (types.SLIP_CLASS_NAMES); 0 when body and rim speed are both slow."""
    still = (np.abs(body_speed_mps) < moving_threshold_mps) & \
        (np.abs(rim_speed_mps) < moving_threshold_mps)
    return slip_class_array(slip, ~still).astype(np.int64)


def _slip_gain(s: np.ndarray) -> np.ndarray:
    """K(s) = r w / v: 1/(1-s) for s >= 0, 1+s for s < 0 (eq. 1 solved for r w)."""
    return np.where(s >= 0.0, 1.0 / (1.0 - np.minimum(s, 0.99)), 1.0 + np.maximum(s, -0.99))


# --- profiles and terrain ------------------------------------------------------------------------

def _smootherstep(u: np.ndarray) -> np.ndarray:
    # C2 ramp from 0 to 1: finite jerk, so the IMU signal has no spikes.
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (u * (6.0 * u - 15.0) + 10.0)


def _profile(t: np.ndarray, starts: np.ndarray, targets: list[float], ramps: list[float],
             initial: float) -> np.ndarray:
    y = np.full_like(t, initial)
    prev = initial
    for t0, val, tau in zip(starts, targets, ramps):
        if val != prev:
            i0 = np.searchsorted(t, t0)
            y[i0:] += (val - prev) * _smootherstep((t[i0:] - t0) / tau)
        prev = val
    return y


class Terrain:
    """z(x, y) = sum of Gaussian hills + two crossing sinusoids, with its gradient.

    Positions are horizontal odom coordinates (m) *before* the start offset is removed, i.e.
    ``xy_odom + xy_offset_m``; heights are relative to the start (``z - z0_m``).
    """

    def __init__(self, centres: np.ndarray, heights: np.ndarray, sigmas: np.ndarray,
                 und_amp: float, und_k: np.ndarray, und_phase: np.ndarray) -> None:
        self.c = centres.reshape(-1, 2)
        self.h = heights
        self.s = sigmas
        self.amp = und_amp
        self.k = und_k.reshape(-1, 2)
        self.ph = und_phase
        self.z0_m = 0.0
        self.xy_offset_m = np.zeros(2)

    def height_and_gradient(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = np.zeros(len(xy))
        g = np.zeros_like(xy)
        for c, h, s in zip(self.c, self.h, self.s):
            d = xy - c
            e = h * np.exp(-(d * d).sum(axis=1) / (2.0 * s * s))
            z += e
            g += -d / (s * s) * e[:, None]
        for k, ph in zip(self.k, self.ph):
            arg = xy @ k + ph
            z += self.amp * np.sin(arg)
            g += self.amp * np.cos(arg)[:, None] * k[None, :]
        return z, g

    def odom_height_and_normal(self, p_xy_o: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Terrain height (odom z, m) and unit upward normal (ENU) at odom positions (N, 2)."""
        z, g = self.height_and_gradient(np.atleast_2d(p_xy_o) + self.xy_offset_m)
        n = np.column_stack([-g, np.ones(len(z))])
        return z - self.z0_m, n / np.linalg.norm(n, axis=1, keepdims=True)


# --- the simulator: fine-grid truth -------------------------------------------------------------

@dataclass(frozen=True)
class _FineGrid:
    """The fine time grid (rate_imu * oversample) with one extra sample either side for the
    central differences: index 1 is t = 0, ``n`` samples run from t = 0 to the end."""

    t_s: np.ndarray
    h_s: float
    n: int
    rate_hz: float


def _fine_grid(cfg: ScenarioConfig) -> _FineGrid:
    fine_hz = cfg.rate_imu_hz * cfg.oversample
    h = 1.0 / fine_hz
    n_fine = int(round(cfg.total_duration_s * fine_hz)) + 1
    return _FineGrid((np.arange(n_fine + 2) - 1) * h, h, n_fine, fine_hz)


def _drive_profiles(cfg: ScenarioConfig, t: np.ndarray
                    ) -> tuple[_Drive, np.ndarray, np.ndarray]:
    """Commanded speed, control and scripted slip, heading rate (rad/s) and wheel spin (m/s)
    on the fine grid, blended from the segment targets under wheel-rate or body-speed
    control."""
    starts = np.cumsum([0.0] + [s.duration_s for s in cfg.segments[:-1]])
    segs = cfg.segments
    # A log that starts in motion begins at the first segment's targets (no ramp from rest).
    first = segs[0] if cfg.start_moving else None
    cmd = _profile(t, starts, [s.speed_mps for s in segs], [s.speed_ramp_s for s in segs],
                   first.speed_mps if first else 0.0)
    cmd = np.maximum(cmd, 0.0)
    psi_dot = _profile(t, starts, [s.yaw_rate_rps for s in segs], [1.0] * len(segs),
                       first.yaw_rate_rps if first else 0.0)
    s_cmd = _profile(t, starts, [s.slip for s in segs], [s.slip_ramp_s for s in segs],
                     segs[0].slip)
    spin = np.maximum(_profile(t, starts, [s.spin_mps for s in segs], [1.0] * len(segs), 0.0),
                      0.0)
    # Wheel control (weight 1): the controllers hold the commanded rim speed and the terrain's
    # slip sets the body speed; body control (0): the body speed is scripted.
    wheel_ctl = np.clip(_profile(t, starts, [float(s.control == 'wheel') for s in segs],
                                 [1.0] * len(segs), float(segs[0].control == 'wheel')), 0.0, 1.0)
    spin = (1.0 - wheel_ctl) * spin
    # a negative slip follows the grade if the segment that set it says so (from its start)
    grade_w = np.zeros_like(t)
    for t0, seg in zip(starts, segs):
        if seg.slip < 0.0:
            grade_w[t >= t0] = float(seg.grade_driven)
    return _Drive(cmd, wheel_ctl * grade_w, wheel_ctl, s_cmd), psi_dot, spin


@dataclass(frozen=True)
class _Drive:
    """Commanded speed ``cmd`` (m/s), weights of grade-driven run-ahead and of wheel control,
    and scripted slip on the fine grid; the slip and body speed that the terrain's grade lets
    develop (module docstring, step 2)."""

    cmd: np.ndarray
    grade_w: np.ndarray
    wheel_ctl: np.ndarray
    s_cmd: np.ndarray

    @property
    def grade_driven(self) -> np.ndarray:
        """Where the body speed depends on the grade: a grade-driven run-ahead."""
        return (self.s_cmd < 0.0) & (self.grade_w > 0.0)

    def slip(self, g_f: np.ndarray, sl: slice = slice(None)) -> np.ndarray:
        """Slip on ``sl`` given the forward gradient there: a run-ahead scaled by the downhill
        grade beyond the rolling resistance, zero on level or nose-up ground."""
        sin_down = -g_f / np.sqrt(1.0 + g_f * g_f)
        drive = _smootherstep((sin_down - ROLLING_RESISTANCE) / (G_FULL - ROLLING_RESISTANCE))
        held = np.minimum(self.s_cmd[sl], 0.0) * self.grade_w[sl]
        return self.s_cmd[sl] - held * (1.0 - drive)

    def speed(self, g_f: np.ndarray | None, sl: slice = slice(None)) -> np.ndarray:
        """Body speed on ``sl``: held rim speed / K(s) under wheel control, else scripted;
        ``g_f`` None: at the scripted slip (the path planned on flat ground)."""
        w = self.wheel_ctl[sl]
        s = self.s_cmd[sl] if g_f is None else self.slip(g_f, sl)
        return w * self.cmd[sl] / _slip_gain(s) + (1.0 - w) * self.cmd[sl]


def _place_terrain(cfg: ScenarioConfig, t: np.ndarray, xy_flat: np.ndarray,
                   u_fwd: np.ndarray, u_left: np.ndarray,
                   truth_rng: np.random.Generator) -> Terrain:
    """Hills placed on the flat-ground path ``xy_flat`` by time, with seeded jitter, and the
    undulations in seeded directions and phases (draws in this order from ``truth_rng``)."""
    terr = cfg.terrain
    centres, heights, sigmas = [], [], []
    for hill in terr.hills:
        i = int(np.clip(np.searchsorted(t, hill.t_center_s), 0, len(t) - 1))
        jitter = truth_rng.normal(0.0, terr.hill_jitter_m, 2)
        centres.append(xy_flat[i] + (hill.lateral_offset_m + jitter[1]) * u_left[i]
                       + jitter[0] * u_fwd[i])
        heights.append(hill.height_m)
        sigmas.append(hill.sigma_m)
    k_mag = 2.0 * math.pi / terr.undulation_wavelength_m
    und_dirs = truth_rng.uniform(0.0, 2.0 * math.pi, 2)
    return Terrain(np.array(centres).reshape(-1, 2), np.array(heights), np.array(sigmas),
                   terr.undulation_amplitude_m,
                   k_mag * np.stack([np.cos(und_dirs), np.sin(und_dirs)], axis=1),
                   truth_rng.uniform(0.0, 2.0 * math.pi, 2))


def _pieces(coupled: np.ndarray, piece_n: int) -> list[tuple[int, int]]:
    """Index ranges [i0, i1] (sharing their ends) that split the grid where ``coupled``
    changes and every ``piece_n`` samples inside it."""
    n = len(coupled)
    cuts = {0, n - 1}
    cuts.update((np.flatnonzero(np.diff(coupled.astype(np.int8))) + 1).tolist())
    cuts.update(np.flatnonzero(coupled & (np.arange(n) % piece_n == 0)).tolist())
    b = sorted(cuts)
    return list(zip(b[:-1], b[1:]))


def _surface_path(terrain: Terrain, drive: _Drive, u_fwd: np.ndarray, u_left: np.ndarray,
                  xy_flat: np.ndarray, h: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Odom position ``p_o`` (N, 3) of the rover driving at its body speed along the surface,
    the terrain gradients forward ``g_f`` and to the left ``g_l``, and the body speed v.
    Anchors ``terrain`` at the start (sets its ``z0_m`` and ``xy_offset_m``)."""
    # fixed point: horizontal speed depends on the slope, the slope on the position; where
    # the body speed depends on the grade (a run-ahead) in pieces short enough to contract
    xy = xy_flat.copy()
    for i0, i1 in _pieces(drive.grade_driven, max(1, int(round(0.25 / h)))):
        sl = slice(i0, i1 + 1)
        xy[i0 + 1:i1 + 1] += xy[i0] - xy_flat[i0]
        for _ in range(40):
            _, grad = terrain.height_and_gradient(xy[sl])
            g_f = (grad * u_fwd[sl]).sum(axis=1)
            v = drive.speed(g_f, sl)
            xy_new = xy[i0] + cumtrapz((v / np.sqrt(1.0 + g_f * g_f))[:, None] * u_fwd[sl], h)
            change = np.max(np.abs(xy_new - xy[sl]))
            xy[sl] = xy_new
            if change < 1e-10:
                break
    z, grad = terrain.height_and_gradient(xy)
    g_f = (grad * u_fwd).sum(axis=1)
    g_l = (grad * u_left).sum(axis=1)
    z0 = z[1]  # sample at t = 0; odom origin at the start position
    p_o = np.column_stack([xy - xy[1], z - z0])
    terrain.z0_m = float(z0)
    terrain.xy_offset_m = xy[1].copy()
    return p_o, g_f, g_l, drive.speed(g_f)


@dataclass(frozen=True)
class _Inertial:
    """IMU truth of base_link on the fine grid: specific force ``f_ib_b`` (m/s^2) at the IMU
    position and angular rate ``omega_ib_b`` (rad/s), both in base_link; gravity ``g_n`` (NED)
    and planet rate ``omega_ie_o`` (ENU) at the start."""

    f_ib_b: np.ndarray
    omega_ib_b: np.ndarray
    g_n: np.ndarray
    omega_ie_o: np.ndarray


def _inertial_truth(cfg: ScenarioConfig, C: np.ndarray, v_o: np.ndarray,
                    omega_eb_b: np.ndarray, h: float) -> _Inertial:
    """Specific force and angular rate w.r.t. inertial space (module docstring, step 4)."""
    site = cfg.site
    planet = PLANETS[site.planet]
    a_o = central_diff(v_o, h)
    L0 = math.radians(site.latitude_deg)
    g_n = gravity_n(planet, L0, site.height_m)
    g_o = C_ENU_NED @ g_n  # (0, 0, -g)
    omega_ie_o = C_ENU_NED @ earth_rate_n(planet, L0)
    f_o = a_o - g_o[None, :] + 2.0 * np.cross(omega_ie_o[None, :], v_o)
    f_b = np.einsum('nji,nj->ni', C, f_o)
    omega_ib_b = omega_eb_b + np.einsum('nji,j->ni', C, omega_ie_o)
    r_b = np.asarray(cfg.rover.imu_to_base_xyz_m, dtype=float)
    if np.any(r_b != 0.0):
        alpha_b = central_diff(omega_ib_b, h)
        f_b = f_b + np.cross(alpha_b, r_b) + np.cross(omega_ib_b, np.cross(omega_ib_b, r_b))
    return _Inertial(f_b, omega_ib_b, g_n, omega_ie_o)


@dataclass(frozen=True)
class _Truth:
    """Truth on the fine grid (module docstring, steps 1-5); odom is ENU at the start."""

    grid: _FineGrid
    v_mps: np.ndarray
    yaw0_rad: float
    p_o: np.ndarray
    C_base_o: np.ndarray
    v_o: np.ndarray
    omega_eb_b: np.ndarray
    inertial: _Inertial
    v_left_mps: np.ndarray
    v_right_mps: np.ndarray
    rim_mps: np.ndarray
    terrain: Terrain


def _truth(cfg: ScenarioConfig) -> _Truth:
    """Exact truth kinematics; draws the terrain from the truth seed."""
    grid = _fine_grid(cfg)
    t, h = grid.t_s, grid.h_s
    drive, psi_dot, spin = _drive_profiles(cfg, t)
    yaw0 = heading_to_yaw_enu(cfg.site.heading_deg)
    psi = yaw0 + cumtrapz(psi_dot, h)
    u_fwd = np.stack([np.cos(psi), np.sin(psi)], axis=1)
    u_left = np.stack([-np.sin(psi), np.cos(psi)], axis=1)
    xy_flat = cumtrapz(drive.speed(None)[:, None] * u_fwd, h)
    terrain = _place_terrain(cfg, t, xy_flat, u_fwd, u_left,
                             np.random.default_rng(cfg.truth_seed))
    p_o, g_f, g_l, v = _surface_path(terrain, drive, u_fwd, u_left, xy_flat, h)

    # attitude and velocity of base_link; angular rate by central differences, O(h^2)
    pitch = -np.arctan(g_f)
    roll = np.arctan(g_l / np.sqrt(1.0 + g_f * g_f))
    C = attitude_dcm(psi, pitch, roll)  # C_base_o
    v_o = v[:, None] * C[:, :, 0]
    if cfg.terrain.rocking_harmonics:  # the body rocks about the path it keeps following
        d_roll, d_pitch = rocking_rad(cfg, v, h)
        C_path = C
        C = attitude_dcm(psi, pitch + d_pitch, roll + d_roll)
        if cfg.terrain.rocking_pivot_depth_m:
            # about an axis below base_link: base_link swings by (C - C_path) (0, 0, depth)
            swing = (C[:, :, 2] - C_path[:, :, 2]) * cfg.terrain.rocking_pivot_depth_m
            p_o = p_o + swing
            v_o = v_o + central_diff(swing, h)
    if cfg.terrain.surge_harmonics:  # base_link surges along its forward axis, the rims do not
        surge = surge_m(cfg, v, h)[:, None] * C[:, :, 0]
        p_o = p_o + surge
        v_o = v_o + central_diff(surge, h)
    omega_eb_b = np.zeros((len(t), 3))
    omega_eb_b[1:-1] = vee_rel(C[:-2], C[2:]) / (2.0 * h)
    omega_eb_b[0] = omega_eb_b[1]
    omega_eb_b[-1] = omega_eb_b[-2]
    inertial = _inertial_truth(cfg, C, v_o, omega_eb_b, h)

    # wheels: side speeds and rim speeds
    K = _slip_gain(drive.slip(g_f))
    half_T = 0.5 * cfg.rover.track_width_m * cfg.rover.effective_track_factor
    # the yaw rate the wheels turn for: less what differential slip adds to the body's
    starts = np.cumsum([0.0] + [s.duration_s for s in cfg.segments[:-1]])
    yaw_wheels = omega_eb_b[:, 2] - _profile(
        t, starts, [s.differential_yaw_rps for s in cfg.segments], [1.0] * len(cfg.segments),
        cfg.segments[0].differential_yaw_rps if cfg.start_moving else 0.0)
    v_left = v - yaw_wheels * half_T
    v_right = v + yaw_wheels * half_T
    rim_left = v_left * K + spin
    rim_right = v_right * K + spin
    rim = np.column_stack([rim_left if left else rim_right for left in WHEEL_IS_LEFT])
    return _Truth(grid, v, yaw0, p_o, C, v_o, omega_eb_b, inertial, v_left, v_right, rim,
                  terrain)
