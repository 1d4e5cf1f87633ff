"""Sensor models of the seeded rover simulator, applied to the fine-grid truth of :mod:`.truth`.

Sensors (noise seed): constant biases, bias random walks, white noise, optional scale factor
and misalignment, speed-dependent vibration; optionally (:func:`_real_imu_mechanisms`, each
off by default) Gauss-Markov bias instability, gyro g-sensitivity, a vibration-rectified gyro
error that makes the integrated tilt wander while driving, fixed-frequency resonances
sampled without an anti-alias filter (folded to ``|f - k rate|``), a differenced broadband
(no power at 0 Hz) and a motion-bound low-frequency accelerometer error; encoder counts
quantised at ``encoder_pulses_per_m`` with a random initial phase; GNSS from truth with white
noise.

The wheel slip truth at the encoder stamps and a 2-D wheel odometry from the measured encoders
are computed here too. Only the standard library and numpy are imported here.
"""
from __future__ import annotations

import math

import numpy as np

from slip_estimator.core.planet import PLANETS, radii_of_curvature
from slip_estimator.sim.scenario import WHEEL_IS_LEFT, ScenarioConfig
from slip_estimator.sim.kinematics import cumtrapz
from slip_estimator.sim.truth import _Truth, slip_class, slip_ratio


def _imu_errors(cfg: ScenarioConfig, f_true: np.ndarray, w_true: np.ndarray,
                rng_bias: np.random.Generator, rng_rw: np.random.Generator,
                rng_white: np.random.Generator, rng_sf: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Measured specific force and angular rate (imu_link, without vibration) and the true
    accelerometer and gyro biases: turn-on biases, bias random walks, scale factor and
    misalignment, white noise."""
    n = len(f_true)
    e = cfg.imu
    dt_imu = 1.0 / cfg.rate_imu_hz
    ba0 = rng_bias.normal(0.0, 1.0, 3) * e.accel_bias_sigma_mps2
    bg0 = rng_bias.normal(0.0, 1.0, 3) * e.gyro_bias_sigma_rps
    ba = ba0 + np.cumsum(rng_rw.normal(0.0, 1.0, (n, 3)), axis=0) \
        * math.sqrt(e.accel_bias_psd_m2ps5 * dt_imu)
    bg = bg0 + np.cumsum(rng_rw.normal(0.0, 1.0, (n, 3)), axis=0) \
        * math.sqrt(e.gyro_bias_psd_rad2ps3 * dt_imu)
    M_a = np.eye(3) + np.diag(rng_sf.normal(0.0, 1.0, 3) * e.accel_scale_factor_sigma)
    M_g = np.eye(3) + np.diag(rng_sf.normal(0.0, 1.0, 3) * e.gyro_scale_factor_sigma)
    off = ~np.eye(3, dtype=bool)
    M_a[off] += rng_sf.normal(0.0, 1.0, 6) * e.accel_misalignment_sigma_rad
    M_g[off] += rng_sf.normal(0.0, 1.0, 6) * e.gyro_misalignment_sigma_rad
    f_meas = f_true @ M_a.T + ba + rng_white.normal(0.0, 1.0, (n, 3)) \
        * e.accel_noise_density_mps2_rthz * math.sqrt(cfg.rate_imu_hz)
    w_meas = w_true @ M_g.T + bg + rng_white.normal(0.0, 1.0, (n, 3)) \
        * e.gyro_noise_density_rps_rthz * math.sqrt(cfg.rate_imu_hz)
    return f_meas, w_meas, ba, bg


def _vibration_speed(tr: _Truth, i_imu: np.ndarray) -> np.ndarray:
    """Speed the vibration scales with at the IMU samples: max(|body speed|, mean |rim|), m/s."""
    return np.maximum(np.abs(tr.v_mps[i_imu]), np.abs(tr.rim_mps[i_imu]).mean(axis=1))


def _add_sinusoid(rng: np.random.Generator, f_meas: np.ndarray, w_meas: np.ndarray,
                  phase_rad: np.ndarray, amp_accel_mps2: np.ndarray,
                  amp_gyro_rps: np.ndarray) -> None:
    """Add one vibration line, ``amp * sin(phase + random phase)`` along a random unit
    direction (its own for the accelerometer and the gyro), to the measured arrays in place."""
    ph_a, ph_g = rng.uniform(0.0, 2.0 * math.pi, 2)
    dir_a, dir_g = rng.normal(0.0, 1.0, (2, 3))
    dir_a /= np.linalg.norm(dir_a)
    dir_g /= np.linalg.norm(dir_g)
    f_meas += (amp_accel_mps2 * np.sin(phase_rad + ph_a))[:, None] * dir_a
    w_meas += (amp_gyro_rps * np.sin(phase_rad + ph_g))[:, None] * dir_g


def _add_vibration(cfg: ScenarioConfig, tr: _Truth, i_imu: np.ndarray, f_meas: np.ndarray,
                   w_meas: np.ndarray, rng_vib: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Adds the zero-mean vibration (wheel harmonics and broadband noise, scaling with how fast
    the wheels or the body move) to ``f_meas`` and ``w_meas`` in place and returns them."""
    vib = cfg.imu.vibration
    rim = tr.rim_mps
    vib_speed = _vibration_speed(tr, i_imu)
    wheel_phase = cumtrapz(np.abs(rim).mean(axis=1) / cfg.rover.wheel_radius_m,
                            tr.grid.h_s)[i_imu]
    for mult, amp_a, amp_g in zip(vib.harmonic_multipliers, vib.accel_harmonic_mps2_per_mps,
                                  vib.gyro_harmonic_rps_per_mps):
        _add_sinusoid(rng_vib, f_meas, w_meas, mult * wheel_phase, amp_a * vib_speed,
                      amp_g * vib_speed)
    n = len(i_imu)
    f_meas += rng_vib.normal(0.0, 1.0, (n, 3)) \
        * (vib.accel_broadband_mps2_per_mps * vib_speed)[:, None]
    w_meas += rng_vib.normal(0.0, 1.0, (n, 3)) \
        * (vib.gyro_broadband_rps_per_mps * vib_speed)[:, None]
    return f_meas, w_meas


def gauss_markov(rng: np.random.Generator, n: int, dt_s: float, tau_s: float,
                 sigma: float, axes: int = 3) -> np.ndarray:
    """``n`` samples (spacing ``dt_s``) of a stationary first-order Gauss-Markov process per
    axis, x_k+1 = phi x_k + sigma sqrt(1 - phi^2) w_k with phi = exp(-dt/tau) (the exact
    discretisation of dx/dt = -x/tau + white noise), started from its stationary
    N(0, sigma^2)."""
    phi = math.exp(-dt_s / tau_s)
    w = rng.normal(0.0, 1.0, (n, axes)) * sigma * math.sqrt(1.0 - phi * phi)
    w[0] = rng.normal(0.0, 1.0, axes) * sigma
    x = np.empty_like(w)
    acc = w[0]
    x[0] = acc
    for k in range(1, n):  # a first-order recursion: n small vector steps
        acc = phi * acc + w[k]
        x[k] = acc
    return x


def differenced_white(rng: np.random.Generator, n: int, sigma: float, axes: int = 3
                      ) -> np.ndarray:
    """``n`` samples per axis of ``sigma (w_k - w_k-1) / sqrt(2)`` (``w`` unit white): per-sample
    variance sigma^2, lag-1 correlation -1/2, none beyond; its running sum is
    ``sigma (w_k - w_-1) / sqrt(2)``, bounded (no power at 0 Hz)."""
    w = rng.normal(0.0, 1.0, (n + 1, axes))
    return (w[1:] - w[:-1]) * (sigma / math.sqrt(2.0))


def _motion_bound_errors(cfg: ScenarioConfig, speed_mps: np.ndarray, f_meas: np.ndarray,
                         w_meas: np.ndarray, rng: np.random.Generator) -> None:
    """Adds, in place, the differenced broadband (accelerometer and gyro) and the
    accelerometer's motion-bound low-frequency (Gauss-Markov) error, each times the vibration
    speed ``speed_mps`` (:class:`~.imu_grades.VibrationConfig`); draws nothing when all are
    off."""
    vib = cfg.imu.vibration
    n, dt = len(f_meas), 1.0 / cfg.rate_imu_hz
    for x, sigma in ((f_meas, vib.accel_broadband_differenced_mps2_per_mps),
                     (w_meas, vib.gyro_broadband_differenced_rps_per_mps)):
        if sigma > 0.0:
            x += differenced_white(rng, n, sigma) * speed_mps[:, None]
    if vib.accel_lowband_mps2_per_mps > 0.0:
        f_meas += gauss_markov(rng, n, dt, vib.accel_lowband_correlation_s,
                               vib.accel_lowband_mps2_per_mps) * speed_mps[:, None]


def _real_imu_mechanisms(cfg: ScenarioConfig, tr: _Truth, i_imu: np.ndarray,
                         f_true: np.ndarray, f_vib: np.ndarray, f_meas: np.ndarray,
                         w_meas: np.ndarray, ba: np.ndarray, bg: np.ndarray,
                         rngs: list[np.random.Generator]) -> None:
    """Adds, in place, the mechanisms a real vibrating IMU shows that are off by default:
    Gauss-Markov bias instability (also into the true biases ``ba``, ``bg``), gyro
    g-sensitivity on the sensed acceleration ``f_true + f_vib``, the vibration-rectified gyro
    error (Gauss-Markov times the vibration speed) and fixed-frequency resonances sampled at the
    IMU instants, the differenced broadband and the accelerometer's motion-bound low-frequency
    error (:func:`_motion_bound_errors`). Each draws from its own generator of ``rngs``, so
    switching one on leaves the others' draws alone."""
    e, vib = cfg.imu, cfg.imu.vibration
    rng_gm, rng_gs, rng_rect, rng_res, rng_accel = rngs
    n, dt = len(f_meas), 1.0 / cfg.rate_imu_hz
    if e.accel_bias_instability_mps2 > 0.0 or e.gyro_bias_instability_rps > 0.0:
        gm = gauss_markov(rng_gm, n, dt, e.bias_correlation_time_s, 1.0, axes=6)
        ba += gm[:, :3] * e.accel_bias_instability_mps2
        bg += gm[:, 3:] * e.gyro_bias_instability_rps
        f_meas += gm[:, :3] * e.accel_bias_instability_mps2
        w_meas += gm[:, 3:] * e.gyro_bias_instability_rps
    if e.gyro_g_sensitivity_rps_per_mps2 > 0.0:
        G = rng_gs.normal(0.0, 1.0, (3, 3)) * e.gyro_g_sensitivity_rps_per_mps2
        w_meas += (f_true + f_vib) @ G.T
    speed = _vibration_speed(tr, i_imu)
    if vib.gyro_rectified_rps_per_mps > 0.0:
        w_meas += gauss_markov(rng_rect, n, dt, vib.rectified_correlation_time_s,
                               vib.gyro_rectified_rps_per_mps) * speed[:, None]
    t = tr.grid.t_s[i_imu]
    for f_hz, amp_a, amp_g in zip(vib.resonance_hz, vib.accel_resonance_mps2_per_mps,
                                  vib.gyro_resonance_rps_per_mps):
        _add_sinusoid(rng_res, f_meas, w_meas, 2.0 * math.pi * f_hz * t, amp_a * speed,
                      amp_g * speed)
    _motion_bound_errors(cfg, speed, f_meas, w_meas, rng_accel)


def _wheel_encoders(cfg: ScenarioConfig, rim: np.ndarray, i_wheel: np.ndarray, h: float,
                    rng_enc: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cumulative encoder counts of rim travel (random initial phase), joint angle (rad) from
    the counts and joint rate (rad/s) from count differences over the wheel period."""
    rover = cfg.rover
    dist = cumtrapz(rim, h)
    dist = dist - dist[1]
    ppm = rover.encoder_pulses_per_m
    phase0 = rng_enc.uniform(0.0, 1.0, 4)
    counts = np.floor(dist[i_wheel] * ppm + phase0).astype(np.int64)
    dt_wheel = 1.0 / cfg.rate_wheel_hz
    prev = np.vstack([counts[:1], counts[:-1]])
    wheel_rate = (counts - prev) / (ppm * dt_wheel * rover.wheel_radius_m)
    if cfg.start_moving:  # no count before the first: its rate is the rim speed then
        wheel_rate[0] = rim[i_wheel[0]] / rover.wheel_radius_m
    angle = counts / (ppm * rover.wheel_radius_m)
    return counts, angle, wheel_rate


def _wheel_slip_truth(tr: _Truth, i_wheel: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Slip of the mean wheel (eq. 1), its class, and the per-side slips at the wheel stamps."""
    rim_w = tr.rim_mps[i_wheel]
    v_w = tr.v_mps[i_wheel]
    rim_mean_w = rim_w.mean(axis=1)
    s_true = slip_ratio(v_w, rim_mean_w)
    cls = slip_class(s_true, v_w, rim_mean_w)
    left = np.array(WHEEL_IS_LEFT)
    s_left = slip_ratio(tr.v_left_mps[i_wheel], rim_w[:, left].mean(axis=1))
    s_right = slip_ratio(tr.v_right_mps[i_wheel], rim_w[:, ~left].mean(axis=1))
    return s_true, cls, s_left, s_right


def _wheel_odometry(cfg: ScenarioConfig, wheel_rate: np.ndarray, yaw0: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """2-D dead reckoning from the measured encoders (what a rover's odometry would publish):
    position (m), yaw (rad), speed (m/s) and yaw rate (rad/s) in odom."""
    rover = cfg.rover
    dt_wheel = 1.0 / cfg.rate_wheel_hz
    left = np.array(WHEEL_IS_LEFT)
    rim_meas = wheel_rate * rover.wheel_radius_m
    wo_speed = rim_meas.mean(axis=1)
    wo_rate = (rim_meas[:, ~left].mean(axis=1) - rim_meas[:, left].mean(axis=1)) \
        / rover.track_width_m
    wo_yaw = yaw0 + np.cumsum(wo_rate * dt_wheel)
    yaw_mid = wo_yaw - 0.5 * wo_rate * dt_wheel
    wo_xy = np.cumsum(wo_speed[:, None] * np.stack([np.cos(yaw_mid), np.sin(yaw_mid)], axis=1)
                      * dt_wheel, axis=0)
    return wo_xy, wo_yaw, wo_speed, wo_rate


def _gnss_llh(cfg: ScenarioConfig, p_o: np.ndarray, rng_gnss: np.random.Generator
              ) -> np.ndarray:
    """GNSS fixes (latitude deg, longitude deg, height m) of the antenna at base_link from the
    true odom positions ``p_o`` plus white noise, by a small-offset geodetic conversion."""
    site = cfg.site
    L0 = math.radians(site.latitude_deg)
    R_N, R_E = radii_of_curvature(PLANETS[site.planet], L0)
    noise = rng_gnss.normal(0.0, 1.0, (len(p_o), 3)) * np.array(
        [cfg.gnss.horizontal_std_m, cfg.gnss.horizontal_std_m, cfg.gnss.vertical_std_m])
    pg = p_o + noise
    lat = site.latitude_deg + np.degrees(pg[:, 1] / (R_N + site.height_m))
    lon = site.longitude_deg + np.degrees(pg[:, 0] / ((R_E + site.height_m) * math.cos(L0)))
    alt = site.height_m + pg[:, 2]
    return np.column_stack([lat, lon, alt])
