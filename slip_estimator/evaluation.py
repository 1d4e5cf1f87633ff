"""Evaluation of a whole run against the best truth it carries (numpy only, array based).

The metrics are :mod:`slip_estimator.metrics`'s, the GNSS truth :mod:`slip_estimator.truth`'s.

Truth sources and what each metric rests on
-------------------------------------------
* **Simulation truth** (``/truth/slip``, ``/truth/odometry``): exact; every metric is valid.
* **GNSS truth, RTK grade** (Pathfinder test17run; mm-level at rest, 10 Hz): the forward speed
  ``v_xTR`` is the GNSS velocity (local linear fit of the ENU positions over a window,
  default 1.0 s = ~10 epochs, gaps tolerated) projected on the rover's body x axis, and
  ``s_TR`` follows from it and the wheel rim speed by the paper's eq. 30 (= eq. 1). By default
  the projection is on the GNSS track itself ('course': 3-D GNSS speed with the sign of the
  wheel rotation), so the truth does not depend on the estimate; it assumes no skid-steer crab
  (a 5 deg crab overstates v_x by 0.4 %, far below the 0.2 class step). Alternatively
  ('estimate') the GNSS velocity is projected on the body x axis of the *estimated* attitude
  (odometry orientation interpolated to the wheel time); that is exact for crab but inherits a
  diverged estimate's heading error. The result records which was used. Slip
  classification, speed RMSE, position error/drift and heading error are all meaningful.
  The wheel time offset (joint states lag the IMU/GNSS by ~0.1-0.2 s on Pathfinder) can be
  applied through ``wheel_time_offset_s``.
* **GNSS truth, single point** (s5t1; sigma ~2 m, jittery receive stamps): only coarse whole-run
  figures are valid - final position error, net displacement, trajectory shape. Per-sample
  speed and slip truth from it are noise; the functions still compute them when asked, and
  :func:`evaluate_run` flags them as invalid (``truth_quality='single_point'``).

Conventions: as in :mod:`slip_estimator.metrics`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from slip_estimator.core.types import SLIP_CLASS_NAMES, WheelSample
from slip_estimator.core.wheel_odometry import WheelDeadReckoning
from slip_estimator.metrics import (
    SlipResult,
    SpeedResult,
    TrajectoryResult,
    evaluate_slip,
    evaluate_speed,
    evaluate_trajectory,
    match_nearest,
)
from slip_estimator.truth import (
    GnssTruth,
    gnss_slip_truth,
    gnss_velocity_enu,
    quat_wxyz_to_x_axis,
    quat_wxyz_to_yaw,
)


# --------------------------------------------------------------------------------------------
# Whole run
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """Arrays extracted from an input bag and an estimator output bag (see report.load_run).

    Absent series are None. Times are ns; positions are odom ENU m; quaternions (w, x, y, z).
    """

    est_slip_stamp_ns: np.ndarray
    est_slip: np.ndarray
    est_slip_std: np.ndarray
    est_slip_class: np.ndarray
    est_body_speed_mps: np.ndarray
    est_wheel_speed_mps: np.ndarray
    est_odom_stamp_ns: np.ndarray | None = None
    est_odom_p_m: np.ndarray | None = None
    est_odom_q_wxyz: np.ndarray | None = None
    est_odom_v_mps: np.ndarray | None = None
    truth_slip_stamp_ns: np.ndarray | None = None
    truth_slip: np.ndarray | None = None
    truth_slip_class: np.ndarray | None = None
    truth_odom_stamp_ns: np.ndarray | None = None
    truth_odom_p_m: np.ndarray | None = None
    truth_odom_q_wxyz: np.ndarray | None = None
    truth_odom_v_mps: np.ndarray | None = None
    gnss_stamp_ns: np.ndarray | None = None
    gnss_llh: np.ndarray | None = None
    """(K, 3): latitude rad, longitude rad, ellipsoidal height m."""
    gnss_sigma_h_m: np.ndarray | None = None
    """(K,) horizontal 1-sigma from the NavSatFix covariance, m."""
    wheel_stamp_ns: np.ndarray | None = None
    wheel_rim_speed_mps: np.ndarray | None = None


@dataclass(frozen=True)
class RunEvaluation:
    """Everything :func:`evaluate_run` computed, with the truth it rests on.

    ``truth_source`` is 'simulation', 'gnss_rtk' or 'gnss_single_point'; ``valid`` lists which
    metric groups are meaningful with that truth.
    """

    truth_source: str
    slip: SlipResult | None
    speed: SpeedResult | None
    trajectory: TrajectoryResult | None
    valid: dict[str, bool]
    notes: tuple[str, ...] = field(default_factory=tuple)
    gnss_truth: GnssTruth | None = None
    truth_p_m: np.ndarray | None = None
    truth_stamp_ns: np.ndarray | None = None
    wheels_gyro: TrajectoryResult | None = None
    """The same trajectory figures for wheels + gyro dead reckoning (:func:`wheels_gyro_track`),
    the baseline the fused odometry must not be worse than where the wheels are right."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            'wheels_gyro': self.wheels_gyro.to_dict() if self.wheels_gyro else None,
            'truth_source': self.truth_source, 'valid': dict(self.valid),
            'notes': list(self.notes),
            'gnss_projection': self.gnss_truth.projection if self.gnss_truth else None,
            'slip': self.slip.to_dict() if self.slip else None,
            'speed': self.speed.to_dict() if self.speed else None,
            'trajectory': self.trajectory.to_dict() if self.trajectory else None,
        }


def gnss_quality(sigma_h_m: np.ndarray | None, p_enu_m: np.ndarray | None = None,
                 rtk_sigma_m: float = 0.1) -> str:
    """'gnss_rtk' when the median horizontal sigma is below ``rtk_sigma_m``, else
    'gnss_single_point'."""
    if sigma_h_m is not None and np.isfinite(sigma_h_m).any() and np.nanmax(sigma_h_m) > 0:
        return 'gnss_rtk' if float(np.nanmedian(sigma_h_m)) < rtk_sigma_m else \
            'gnss_single_point'
    return 'gnss_single_point'


def _estimated_x_axis(run: RunData) -> np.ndarray | None:
    """The estimated body x axis (odom, unit vectors) at the slip stamps, interpolated from
    the estimated odometry; None without at least two odometry samples."""
    if run.est_odom_stamp_ns is None or len(run.est_odom_stamp_ns) <= 1:
        return None
    x_axes = quat_wxyz_to_x_axis(run.est_odom_q_wxyz)
    to = (run.est_odom_stamp_ns - run.est_odom_stamp_ns[0]) * 1e-9
    tw = (run.est_slip_stamp_ns - run.est_odom_stamp_ns[0]) * 1e-9
    x_axis = np.column_stack([np.interp(tw, to, x_axes[:, k]) for k in range(3)])
    return x_axis / np.linalg.norm(x_axis, axis=1, keepdims=True)


def wheels_gyro_track(run: RunData) -> tuple[np.ndarray, np.ndarray] | None:
    """Wheels + gyro dead reckoning: the published rim speed of every slip sample integrated
    along the estimated heading (the gyro's, integrated and bias-corrected by the filter),
    from the estimated position at the first sample; (stamps ns, (N, 3) odom ENU m), or None
    without two odometry samples. Only the forward speed differs from the fused odometry."""
    if run.est_odom_stamp_ns is None or len(run.est_odom_stamp_ns) < 2 \
            or len(run.est_slip_stamp_ns) < 2:
        return None
    to, tw = run.est_odom_stamp_ns, run.est_slip_stamp_ns
    inside = (tw >= to[0]) & (tw <= to[-1])
    tw, rim = tw[inside], np.nan_to_num(run.est_wheel_speed_mps[inside])
    if len(tw) < 2:
        return None
    rel = lambda t: (t - to[0]) * 1e-9  # noqa: E731
    yaw = np.interp(rel(tw), rel(to), np.unwrap(quat_wxyz_to_yaw(run.est_odom_q_wxyz)))
    p0 = [np.interp(rel(tw[0]), rel(to), run.est_odom_p_m[:, k]) for k in range(3)]
    dr = WheelDeadReckoning(float(yaw[0]))
    p = np.empty((len(tw), 3))
    for k, (t, v, y) in enumerate(zip(tw.tolist(), rim.tolist(), yaw.tolist())):
        dr.add(WheelSample(t, v), 1.0, y)
        p[k] = (p0[0] + dr.x_m, p0[1] + dr.y_m, p0[2])
    return tw, p


def evaluate_run(run: RunData, llh0: np.ndarray | None = None,
                 moving_threshold_mps: float = 0.02, tol_s: float = 0.05,
                 gnss_window_s: float = 1.0, wheel_time_offset_s: float = 0.0,
                 projection: str = 'course',
                 truth_source: str | None = None) -> RunEvaluation:
    """Evaluate a run against the best truth it carries (simulation truth, else GNSS).

    ``llh0`` (rad, rad, m) is the odom origin for the GNSS truth (default: the first fix);
    with ``align_origin`` the trajectory comparison is insensitive to it anyway.
    """
    from slip_estimator.core.planet import EARTH, llh_to_local_enu

    notes: list[str] = []
    gnss_truth = None
    slip = speed = traj = wheels_gyro = None
    truth_p = truth_t = None
    if run.truth_slip_stamp_ns is not None and len(run.truth_slip_stamp_ns):
        source = truth_source or 'simulation'
        slip = evaluate_slip(run.est_slip_stamp_ns, run.est_slip, run.est_slip_class,
                             run.truth_slip_stamp_ns, run.truth_slip, run.truth_slip_class, tol_s,
                             run.est_slip_std)
        if run.truth_odom_stamp_ns is not None and len(run.truth_odom_stamp_ns) > 1:
            speed = evaluate_speed(run.est_slip_stamp_ns, run.est_body_speed_mps,
                                   run.truth_odom_stamp_ns, run.truth_odom_v_mps[:, 0])
            truth_t, truth_p = run.truth_odom_stamp_ns, run.truth_odom_p_m
            if run.est_odom_stamp_ns is not None and len(run.est_odom_stamp_ns):
                traj = evaluate_trajectory(
                    run.est_odom_stamp_ns, run.est_odom_p_m, truth_t, truth_p,
                    quat_wxyz_to_yaw(run.est_odom_q_wxyz), quat_wxyz_to_yaw(
                        run.truth_odom_q_wxyz), 'odometry', align_origin=False)
                wg = wheels_gyro_track(run)
                if wg is not None:
                    wheels_gyro = evaluate_trajectory(*wg, truth_t, truth_p,
                                                      align_origin=False)
        valid = {'slip': True, 'speed': speed is not None, 'trajectory': traj is not None,
                 'heading': traj is not None}
    elif run.gnss_stamp_ns is not None and len(run.gnss_stamp_ns) > 3:
        source = truth_source or gnss_quality(run.gnss_sigma_h_m)
        llh0 = run.gnss_llh[0] if llh0 is None else np.asarray(llh0, dtype=float)
        truth_p = np.array([llh_to_local_enu(EARTH, p, llh0) for p in run.gnss_llh])
        truth_t = run.gnss_stamp_ns
        tg = truth_t * 1e-9
        x_axis = _estimated_x_axis(run) if projection == 'estimate' else None
        v_rim = run.est_wheel_speed_mps
        if run.wheel_stamp_ns is not None and len(run.wheel_stamp_ns) > 1:
            idx = match_nearest(run.est_slip_stamp_ns, run.wheel_stamp_ns, int(tol_s * 1e9))
            v_rim = np.where(idx >= 0, run.wheel_rim_speed_mps[np.maximum(idx, 0)], v_rim)
            notes.append('rim speed for s_TR from the input /joint_states and the params radius')
        gnss_truth = gnss_slip_truth(run.est_slip_stamp_ns, v_rim, tg, truth_p,
                                     moving_threshold_mps, x_axis, gnss_window_s,
                                     wheel_time_offset_s)
        notes.append(f'GNSS forward speed projected on the {gnss_truth.projection} '
                     f'({"estimated body x axis" if x_axis is not None else "GNSS course"}), '
                     f'fit window {gnss_window_s} s, wheel time offset {wheel_time_offset_s} s')
        slip = evaluate_slip(run.est_slip_stamp_ns, run.est_slip, run.est_slip_class,
                             gnss_truth.stamp_ns, gnss_truth.s, gnss_truth.slip_class, tol_s,
                             run.est_slip_std)
        speed = evaluate_speed(run.est_slip_stamp_ns, run.est_body_speed_mps,
                               gnss_truth.stamp_ns, gnss_truth.v_forward_mps)
        if run.est_odom_stamp_ns is not None and len(run.est_odom_stamp_ns):
            v_enu = gnss_velocity_enu(tg, truth_p, tg, gnss_window_s)
            sp = np.linalg.norm(v_enu[:, :2], axis=1)
            course = np.where(sp > 0.1, np.arctan2(v_enu[:, 1], v_enu[:, 0]), np.nan)
            rtk = source == 'gnss_rtk'
            traj = evaluate_trajectory(
                run.est_odom_stamp_ns, run.est_odom_p_m, truth_t, truth_p,
                quat_wxyz_to_yaw(run.est_odom_q_wxyz), course, 'gnss_course',
                align_origin=True, distance_smooth_s=1.0 if rtk else 5.0)
            wg = wheels_gyro_track(run)
            if wg is not None:
                wheels_gyro = evaluate_trajectory(*wg, truth_t, truth_p, align_origin=True,
                                                  distance_smooth_s=1.0 if rtk else 5.0)
        rtk = source == 'gnss_rtk'
        valid = {'slip': rtk, 'speed': rtk, 'trajectory': traj is not None,
                 'heading': rtk and traj is not None}
        if not rtk:
            notes.append('single-point GNSS: only the final position error and the shape of '
                         'the track are meaningful; slip/speed/heading figures are NOT valid')
        notes.append('heading truth = GNSS course while moving (> 0.1 m/s); it includes '
                     'skid-steer crab in turns')
    else:
        raise ValueError('no truth in the run: neither /truth/slip nor /gnss/fix')
    valid = follow_data(valid, notes, slip, speed)
    return RunEvaluation(source, slip, speed, traj, valid, tuple(notes), gnss_truth,
                         truth_p, truth_t, wheels_gyro)


SMALL_CLASS_SAMPLES = 30
"""A truth class with fewer matched samples than this is named in the notes: the balanced
accuracy (a mean of per-class recalls) rests on it as heavily as on a full class."""


def follow_data(valid: dict[str, bool], notes: list[str], slip: SlipResult | None,
                speed: SpeedResult | None) -> dict[str, bool]:
    """Validity that also follows the data: no slip figure is valid without a matched
    estimate/truth pair with both classes known, no speed figure without a compared sample;
    small truth classes are named in ``notes`` (appended)."""
    valid = dict(valid)
    if slip is not None and int(slip.counts.sum()) == 0:
        valid['slip'] = False
        notes.append(f'no estimate matched a truth sample with both classes known '
                     f'({slip.n_matched} matched in time): slip figures are NOT valid')
    if speed is not None and speed.n == 0:
        valid['speed'] = False
        notes.append('no estimate fell inside the speed truth: speed figures are NOT valid')
    if slip is not None and valid.get('slip'):
        small = [f'{SLIP_CLASS_NAMES[c]} {int(n)}' for c, n in enumerate(slip.n_truth)
                 if c >= 1 and 0 < n < SMALL_CLASS_SAMPLES]
        if small:
            notes.append('balanced accuracy rests on few samples in class(es): '
                         + ', '.join(small) + f' (fewer than {SMALL_CLASS_SAMPLES} each)')
    return valid

