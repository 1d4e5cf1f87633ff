"""Seeded skid-steer rover simulator: exact truth kinematics, IMU, wheel encoders and GNSS.

:func:`simulate` runs the fine-grid truth of :mod:`.truth` (profiles, terrain, surface path,
attitude, inertial truth, wheel speeds; its docstring gives the maths) and then the sensor
models of :mod:`.sensors` (IMU errors and vibration, encoders, GNSS, wheel odometry), and
samples everything into a :class:`SimResult`.

Only the standard library and numpy are imported here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.sim.scenario import ScenarioConfig
from slip_estimator.sim.kinematics import dcm_to_quat_wxyz
from slip_estimator.sim.sensors import (
    _add_vibration,
    _gnss_llh,
    _imu_errors,
    _real_imu_mechanisms,
    _wheel_encoders,
    _wheel_odometry,
    _wheel_slip_truth,
)
from slip_estimator.sim.truth import (  # noqa: F401 (slip maths re-exported from here)
    MOVING_SPEED_THRESHOLD_MPS,
    Terrain,
    _truth,
    slip_class,
    slip_ratio,
)


@dataclass(frozen=True)
class SimResult:
    """Truth and sensor samples of one simulation run (SI units, times from t = 0).

    Truth at the IMU sample times (``imu_t_s``), base_link in odom (ENU, origin at start):

    * ``p_ob_o`` (N, 3) position, m; ``q_ob_wxyz`` (N, 4) attitude of base_link (FLU) in odom;
      ``C_base_o`` (N, 3, 3) the same as DCM; ``v_ob_o`` (N, 3) velocity in odom, m/s;
      ``v_ob_b`` (N, 3) velocity in base_link (FLU), m/s; ``omega_eb_b`` (N, 3) angular rate
      w.r.t. the planet in base_link, rad/s; ``speed_mps`` (N,) forward body speed v.

    IMU in imu_link: ``f_ib_imu_true`` / ``omega_ib_imu_true`` (N, 3) error-free values;
    ``f_ib_imu`` / ``omega_ib_imu`` (N, 3) measured; ``accel_bias_imu`` / ``gyro_bias_imu``
    (N, 3) the true biases.

    Wheels at ``wheel_t_s`` (M,), columns in ``scenario.WHEEL_JOINT_NAMES`` order:
    ``rim_speed_true_mps`` (M, 4) true rim speeds r*w; ``wheel_counts`` (M, 4) cumulative
    encoder counts; ``wheel_angle_rad`` (M, 4) joint position from the counts;
    ``wheel_rate_rps`` (M, 4) joint velocity from count differences over the wheel period;
    ``wheel_speed_true_mps`` (M,) forward body speed v at the stamp; ``slip_true`` (M,) slip
    s of the mean wheel (eq. 1); ``slip_class`` (M,) class index 0..4; ``slip_left_true``,
    ``slip_right_true`` (M,) per-side slip from the side speeds; ``yaw_rate_true_rps`` (M,).

    Wheel dead reckoning (from the measured encoders, 2-D, odom): ``wheel_odom_xy_m`` (M, 2),
    ``wheel_odom_yaw_rad`` (M,), ``wheel_odom_speed_mps`` (M,), ``wheel_odom_yaw_rate_rps`` (M,).

    GNSS at ``gnss_t_s`` (G,): ``gnss_llh`` (G, 3) latitude deg, longitude deg, height m.

    ``gravity_mps2`` magnitude of gravity used; ``omega_ie_o`` planet rate in odom (ENU), rad/s;
    ``yaw0_rad`` initial ENU yaw of base_link; ``terrain`` the terrain surface.
    """

    config: ScenarioConfig
    imu_t_s: np.ndarray
    p_ob_o: np.ndarray
    q_ob_wxyz: np.ndarray
    C_base_o: np.ndarray
    v_ob_o: np.ndarray
    v_ob_b: np.ndarray
    omega_eb_b: np.ndarray
    speed_mps: np.ndarray
    f_ib_imu_true: np.ndarray
    omega_ib_imu_true: np.ndarray
    f_ib_imu: np.ndarray
    omega_ib_imu: np.ndarray
    accel_bias_imu: np.ndarray
    gyro_bias_imu: np.ndarray
    wheel_t_s: np.ndarray
    rim_speed_true_mps: np.ndarray
    wheel_counts: np.ndarray
    wheel_angle_rad: np.ndarray
    wheel_rate_rps: np.ndarray
    wheel_speed_true_mps: np.ndarray
    slip_true: np.ndarray
    slip_class: np.ndarray
    slip_left_true: np.ndarray
    slip_right_true: np.ndarray
    yaw_rate_true_rps: np.ndarray
    wheel_odom_xy_m: np.ndarray
    wheel_odom_yaw_rad: np.ndarray
    wheel_odom_speed_mps: np.ndarray
    wheel_odom_yaw_rate_rps: np.ndarray
    gnss_t_s: np.ndarray
    gnss_llh: np.ndarray
    gravity_mps2: float
    omega_ie_o: np.ndarray
    yaw0_rad: float
    terrain: Terrain

    def stamps_ns(self, t_s: np.ndarray) -> np.ndarray:
        """Integer-nanosecond stamps (epoch + t) of sample times ``t_s``."""
        return self.config.epoch_ns + np.round(np.asarray(t_s) * 1e9).astype(np.int64)

    def class_durations_s(self) -> dict[int, float]:
        """Time spent in each slip class (wheel samples times the wheel period), s."""
        dt = 1.0 / self.config.rate_wheel_hz
        return {c: float(np.count_nonzero(self.slip_class == c) * dt) for c in range(5)}


def simulate(config: ScenarioConfig) -> SimResult:
    """Run the scenario: exact truth, then IMU, wheel encoders and GNSS with seeded errors."""
    cfg = config
    tr = _truth(cfg)
    seeds = np.random.SeedSequence(cfg.noise_seed).spawn(8)
    rng_bias, rng_rw, rng_white, rng_vib, rng_enc, rng_gnss, rng_sf = [
        np.random.default_rng(s) for s in seeds[:7]]
    rngs_real = [np.random.default_rng(s) for s in seeds[7].spawn(5)]
    # sample indices (fine index 1 is t = 0)
    grid = tr.grid
    i_imu = 1 + np.arange(0, grid.n, cfg.oversample)
    i_wheel = 1 + np.arange(0, grid.n, int(round(grid.rate_hz / cfg.rate_wheel_hz)))
    i_gnss = 1 + np.arange(0, grid.n, int(round(grid.rate_hz / cfg.gnss.rate_hz)))

    C_imu_base = rpy_to_dcm(*cfg.rover.imu_to_base_rpy_rad)
    f_true = tr.inertial.f_ib_b[i_imu] @ C_imu_base  # C_imu_base^T f, row-wise
    w_true = tr.inertial.omega_ib_b[i_imu] @ C_imu_base
    f_meas, w_meas, ba, bg = _imu_errors(cfg, f_true, w_true, rng_bias, rng_rw, rng_white,
                                         rng_sf)
    f_before_vib = f_meas.copy()
    f_meas, w_meas = _add_vibration(cfg, tr, i_imu, f_meas, w_meas, rng_vib)
    _real_imu_mechanisms(cfg, tr, i_imu, f_true, f_meas - f_before_vib, f_meas, w_meas, ba, bg,
                         rngs_real)
    counts, angle, wheel_rate = _wheel_encoders(cfg, tr.rim_mps, i_wheel, grid.h_s, rng_enc)
    s_true, cls, s_left, s_right = _wheel_slip_truth(tr, i_wheel)
    wo_xy, wo_yaw, wo_speed, wo_rate = _wheel_odometry(cfg, wheel_rate, tr.yaw0_rad)

    C_imu = tr.C_base_o[i_imu]
    v_imu = tr.v_o[i_imu]
    return SimResult(
        config=cfg, imu_t_s=grid.t_s[i_imu], p_ob_o=tr.p_o[i_imu],
        q_ob_wxyz=dcm_to_quat_wxyz(C_imu), C_base_o=C_imu, v_ob_o=v_imu,
        v_ob_b=np.einsum('nji,nj->ni', C_imu, v_imu), omega_eb_b=tr.omega_eb_b[i_imu],
        speed_mps=tr.v_mps[i_imu],
        f_ib_imu_true=f_true, omega_ib_imu_true=w_true, f_ib_imu=f_meas, omega_ib_imu=w_meas,
        accel_bias_imu=ba, gyro_bias_imu=bg,
        wheel_t_s=grid.t_s[i_wheel], rim_speed_true_mps=tr.rim_mps[i_wheel],
        wheel_counts=counts, wheel_angle_rad=angle, wheel_rate_rps=wheel_rate,
        wheel_speed_true_mps=tr.v_mps[i_wheel], slip_true=s_true, slip_class=cls,
        slip_left_true=s_left, slip_right_true=s_right,
        yaw_rate_true_rps=tr.omega_eb_b[i_wheel, 2],
        wheel_odom_xy_m=wo_xy, wheel_odom_yaw_rad=wo_yaw, wheel_odom_speed_mps=wo_speed,
        wheel_odom_yaw_rate_rps=wo_rate,
        gnss_t_s=grid.t_s[i_gnss], gnss_llh=_gnss_llh(cfg, tr.p_o[i_gnss], rng_gnss),
        gravity_mps2=float(tr.inertial.g_n[2]), omega_ie_o=tr.inertial.omega_ie_o,
        yaw0_rad=tr.yaw0_rad, terrain=tr.terrain)
