"""Initial heading from the GNSS track of the first straight drive (pure: numpy).

Shared by the Pathfinder importer (:func:`slip_estimator.pathfinder.facts.estimate_initial_
heading`) and ``slip-estimator setup``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class HeadingEstimate:
    """Initial heading from the GNSS track of the first straight drive.

    Attributes
    ----------
    heading_deg : heading of base_link x at ``t_ref``, clockwise from north, deg [0, 360).
    course_deg : GNSS course of the fitted segment, deg.
    gyro_heading_change_deg : gyro heading change from ``t_ref`` to the segment midpoint, deg.
    t_start_s, t_end_s : fitted segment (same time base as the inputs).
    distance_m : GNSS distance covered by the segment, m.
    n_fixes : number of GNSS fixes in the fit.
    """

    heading_deg: float
    course_deg: float
    gyro_heading_change_deg: float
    t_start_s: float
    t_end_s: float
    distance_m: float
    n_fixes: int


def heading_from_track(t_imu_s: np.ndarray, heading_rate_cw_rps: np.ndarray,
                       t_gnss_s: np.ndarray, enu_m: np.ndarray, t_motion_s: float,
                       t_ref_s: float | None = None, max_turn_deg: float = 2.0,
                       min_distance_m: float = 1.0, max_distance_m: float = 10.0
                       ) -> HeadingEstimate:
    """Heading at ``t_ref_s`` (default ``t_motion_s``) from the GNSS track after
    ``t_motion_s``.

    The segment starts at ``t_motion_s`` and ends when the gyro heading has changed by
    ``max_turn_deg`` (or at ``max_distance_m``, but not before ``min_distance_m``). Its course
    is the principal direction of the ENU fixes (sign from the displacement); the heading is
    that course minus the gyro heading change between ``t_ref_s`` and the segment midpoint
    (``heading_rate_cw_rps``: bias-corrected, clockwise positive). Skid-steer crab on the
    straight is assumed zero.
    """
    t0 = t_motion_s
    t_ref = t0 if t_ref_s is None else t_ref_s
    ti, gz = t_imu_s, heading_rate_cw_rps
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (gz[1:] + gz[:-1]) * np.diff(ti))])
    psi -= np.interp(t0, ti, psi)
    tg = t_gnss_s
    after = np.where(tg >= t0)[0]
    i_end = after[0]
    for i in after:
        d = np.linalg.norm(enu_m[i, :2] - enu_m[after[0], :2])
        turned = abs(math.degrees(np.interp(tg[i], ti, psi))) > max_turn_deg
        if d > max_distance_m or (turned and d >= min_distance_m):
            break
        i_end = i
    seg = after[after <= i_end]
    xy = enu_m[seg, :2]
    _, _, vt = np.linalg.svd(xy - xy.mean(axis=0))
    direction = vt[0] if np.dot(xy[-1] - xy[0], vt[0]) >= 0 else -vt[0]
    course = math.degrees(math.atan2(direction[0], direction[1])) % 360.0
    t_mid = 0.5 * (tg[seg[0]] + tg[seg[-1]])
    dpsi = math.degrees(float(np.interp(t_mid, ti, psi) - np.interp(t_ref, ti, psi)))
    return HeadingEstimate((course - dpsi) % 360.0, course, dpsi, float(tg[seg[0]]),
                           float(tg[seg[-1]]), float(np.linalg.norm(xy[-1] - xy[0])), len(seg))
