"""Truth from GNSS (paper eq. 30) and the attitude helpers it needs (numpy only).

What this truth is worth (RTK vs single point, course vs estimate projection, the wheel time
offset) is explained in :mod:`slip_estimator.evaluation`, which uses it.
Conventions: wheel stamps in integer nanoseconds, GNSS times in seconds, positions and
velocities in ENU (m, m/s), quaternions (w, x, y, z).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slip_estimator.core.slip import slip_class_array, slip_ratio_array


# --------------------------------------------------------------------------------------------
# Slip maths (paper eq. 1 and 30)
# --------------------------------------------------------------------------------------------
# The slip maths is the core's (paper eq. 1; eq. 30 with GNSS truth speed), vectorised.
slip_ratio = slip_ratio_array
slip_class = slip_class_array


# --------------------------------------------------------------------------------------------
# GNSS truth (paper eq. 30)
# --------------------------------------------------------------------------------------------
def gnss_velocity_enu(gnss_t_s: np.ndarray, p_enu_m: np.ndarray, t_query_s: np.ndarray,
                      window_s: float = 1.0, min_fixes: int = 3) -> np.ndarray:
    """ENU velocity (m/s) at the query times by a local linear fit of the GNSS positions.

    A least-squares line through the fixes within ``+-window_s/2`` of each query time (lag-free
    for constant acceleration). On test17run the RTK position noise is ~2 mm at rest but ~1.3 cm
    while driving, so the speed noise (std of GNSS minus rim speed on the steady drive) is
    0.075 / 0.043 / 0.022 / 0.014 m/s for windows of 0.3 / 0.5 / 1 / 2 s; 1 s (slip noise
    ~0.03, well below the 0.2 class step, still resolving 1 Hz slip changes) is the default.
    Queries with fewer than ``min_fixes`` fixes, or whose fixes do not straddle the query time
    (a gap), give NaN: the record is aligned by time, never by index.
    """
    tg = np.asarray(gnss_t_s, dtype=float)
    p = np.asarray(p_enu_m, dtype=float)
    tq = np.asarray(t_query_s, dtype=float)
    out = np.full((len(tq), 3), np.nan)
    i0 = np.searchsorted(tg, tq - window_s / 2, side='left')
    i1 = np.searchsorted(tg, tq + window_s / 2, side='right')
    for k, (a, b) in enumerate(zip(i0, i1)):
        if b - a < min_fixes:
            continue
        dt = tg[a:b] - tq[k]
        if dt[0] > -0.25 * window_s or dt[-1] < 0.25 * window_s:
            continue
        A = np.column_stack([np.ones(b - a), dt])
        coef, *_ = np.linalg.lstsq(A, p[a:b], rcond=None)
        out[k] = coef[1]
    return out


def quat_wxyz_to_x_axis(q_wxyz: np.ndarray) -> np.ndarray:
    """First column of the rotation matrix of each quaternion: base_link x in odom (ENU)."""
    q = np.asarray(q_wxyz, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])


def quat_wxyz_to_yaw(q_wxyz: np.ndarray) -> np.ndarray:
    """ENU yaw (rad, counter-clockwise from east) of each quaternion."""
    ax = quat_wxyz_to_x_axis(q_wxyz)
    return np.arctan2(ax[:, 1], ax[:, 0])


@dataclass(frozen=True)
class GnssTruth:
    """Forward speed and slip truth from GNSS at the wheel sample times (paper eq. 30).

    Attributes
    ----------
    stamp_ns : wheel sample times, ns.
    v_forward_mps : truth forward speed ``v_xTR``, m/s (NaN where GNSS has a gap).
    v_rim_mps : rim speed r*omega used, m/s.
    s : truth slip ratio ``s_TR``; 0 when not moving; NaN where unknown.
    slip_class : truth class (0 not moving, 1..4, -1 unknown).
    projection : 'estimate' (body x axis of the estimated attitude) or 'course'.
    """

    stamp_ns: np.ndarray
    v_forward_mps: np.ndarray
    v_rim_mps: np.ndarray
    s: np.ndarray
    slip_class: np.ndarray
    projection: str


def gnss_slip_truth(wheel_stamp_ns: np.ndarray, v_rim_mps: np.ndarray, gnss_t_s: np.ndarray,
                    p_enu_m: np.ndarray, moving_threshold_mps: float = 0.02,
                    x_axis_enu: np.ndarray | None = None, window_s: float = 1.0,
                    wheel_time_offset_s: float = 0.0,
                    gnss_moving_threshold_mps: float = 0.1) -> GnssTruth:
    """Truth slip ``s_TR`` (eq. 30) from GNSS velocity and the wheel rim speed.

    ``x_axis_enu`` (N, 3): base_link x axis in ENU at each wheel time (from the estimated
    attitude); the GNSS velocity is projected on it. Without it the 3-D GNSS speed is
    used with the sign of the rim speed (course projection: assumes no crab). A wheel stamp
    ``t`` is compared with the GNSS velocity at ``t + wheel_time_offset_s`` (use a negative
    offset when the wheel stamps lag).

    Moving (class != 0) means rim speed above ``moving_threshold_mps`` or GNSS forward speed
    above ``gnss_moving_threshold_mps``: GNSS alone needs the higher threshold because RTK
    solutions jitter by 2-3 cm at rest (test17run 68-72 s, IMU still), i.e. ~0.1 m/s.
    """
    ts = np.asarray(wheel_stamp_ns, dtype=np.int64) * 1e-9 + wheel_time_offset_s
    v_rim = np.asarray(v_rim_mps, dtype=float)
    v_enu = gnss_velocity_enu(gnss_t_s, p_enu_m, ts, window_s)
    if x_axis_enu is not None:
        v_fwd = np.einsum('ij,ij->i', v_enu, np.asarray(x_axis_enu, dtype=float))
        projection = 'estimate'
    else:
        sign = np.where(v_rim < 0, -1.0, 1.0)
        v_fwd = sign * np.linalg.norm(v_enu, axis=1)
        projection = 'course'
    moving = (np.abs(v_rim) > moving_threshold_mps) | (np.abs(v_fwd) > gnss_moving_threshold_mps)
    s = np.where(moving, slip_ratio(v_fwd, v_rim), 0.0)
    s = np.where(np.isnan(v_fwd), np.nan, s)
    cls = np.where(np.isnan(v_fwd), -1, slip_class(s, moving))
    return GnssTruth(np.asarray(wheel_stamp_ns, dtype=np.int64), v_fwd, v_rim, s, cls,
                     projection)

