"""Reading a Pathfinder ``.mat`` log (MATLAB v7.3 = HDF5) into plain arrays, with its time bases
(facts in :mod:`slip_estimator.pathfinder`)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

GPS_EPOCH_UNIX_S = 315964800.0
"""Unix time of the GPS epoch, 1980-01-06 00:00 UTC."""
GPS_UTC_LEAP_S = 18.0
"""GPS - UTC since 2017-01-01 (valid for both logs, 2019 and 2020)."""
SECONDS_PER_WEEK = 604800.0

WHEEL_FIELDS = ('frontLeft', 'frontRight', 'rearLeft', 'rearRight')


@dataclass(frozen=True)
class PathfinderLog:
    """A Pathfinder log as plain arrays (SI units, Unix seconds).

    Attributes
    ----------
    name : log name (file stem).
    imu_t_s : IMU sample times, Unix s, shape (N,).
    f_ib_imu : specific force in the IMU's own frame (x fwd, y right, z down), m/s^2, (N, 3).
    omega_ib_imu : angular rate in the IMU frame, rad/s, (N, 3).
    wheel_t_s : joint-state times, Unix s, (M,).
    wheel_rate_rps : wheel angular velocities, forward positive, rad/s, (M, 4), order
        :data:`~slip_estimator.pathfinder.rover.WHEEL_JOINT_NAMES`.
    wheel_angle_rad : wheel angles, forward positive, rad, (M, 4).
    gnss_t_s : GNSS epoch times, Unix s, (K,).
    gnss_llh : latitude (rad), longitude (rad), ellipsoidal height (m), (K, 3).
    gnss_sigma_enu_m : reported 1-sigma east, north, up (m), (K, 3), or None.
    gnss_time_base : 'gps_tow' or 'unix' (how the file stored the GNSS time).
    """

    name: str
    imu_t_s: np.ndarray
    f_ib_imu: np.ndarray
    omega_ib_imu: np.ndarray
    wheel_t_s: np.ndarray
    wheel_rate_rps: np.ndarray
    wheel_angle_rad: np.ndarray
    gnss_t_s: np.ndarray
    gnss_llh: np.ndarray
    gnss_sigma_enu_m: np.ndarray | None
    gnss_time_base: str


def _vec(h5, key: str) -> np.ndarray:
    return np.asarray(h5[key][()], dtype=float).squeeze()


def read_matlab_table(h5, name: str) -> dict[str, np.ndarray]:
    """Columns of a MATLAB ``table`` saved in a v7.3 file (columns reached through ``#refs#``).

    MATLAB stores the table's data as a cell of column arrays and its variable names as a cell
    of char arrays, both under ``#refs#``; the table object itself is an opaque MCOS handle, so
    the two cells are recognised by shape (same count, numeric columns of one length, char names).
    """
    if name not in h5:
        raise KeyError(f'no variable {name!r}')
    refs = h5['#refs#']
    cells = []
    for key in refs:
        d = refs[key]
        if getattr(d, 'dtype', None) == object and d.attrs.get('MATLAB_class') == b'cell':
            cells.append([h5[r] for r in d[()].ravel()])
    names = data = None
    for cell in cells:
        if all(getattr(i, 'attrs', {}).get('MATLAB_class') == b'char' for i in cell):
            names = [''.join(chr(int(c)) for c in np.asarray(i[()]).ravel()) for i in cell]
    for cell in cells:
        if names and len(cell) == len(names) and all(
                getattr(i, 'attrs', {}).get('MATLAB_class') == b'double' for i in cell):
            data = [np.asarray(i[()], dtype=float).squeeze() for i in cell]
    if names is None or data is None:
        raise ValueError(f'could not decode MATLAB table {name!r}')
    return dict(zip(names, data))


def gps_tow_to_unix(tow_s: np.ndarray, near_unix_s: float) -> np.ndarray:
    """Unix time of GPS times of week; the week is the one containing ``near_unix_s``.

    ``Unix = GPS epoch + week * 604800 + TOW - leap seconds`` (leap = 18 s since 2017).
    """
    gps_s = near_unix_s - GPS_EPOCH_UNIX_S + GPS_UTC_LEAP_S
    week = math.floor(gps_s / SECONDS_PER_WEEK)
    # A run near a week boundary: choose the week that puts the TOW closest to the reference.
    tow_ref = gps_s - week * SECONDS_PER_WEEK
    if np.median(tow_s) - tow_ref > SECONDS_PER_WEEK / 2:
        week -= 1
    elif tow_ref - np.median(tow_s) > SECONDS_PER_WEEK / 2:
        week += 1
    return GPS_EPOCH_UNIX_S + week * SECONDS_PER_WEEK + np.asarray(tow_s) - GPS_UTC_LEAP_S


def read_pathfinder_mat(path: str | Path) -> PathfinderLog:
    """Read a Pathfinder ``.mat`` log into plain arrays (see the module docstring for the facts).

    The GNSS time base is detected from the values: times below one week are GPS time of week
    (test17run), otherwise Unix seconds (s5t1).
    """
    import h5py

    path = Path(path)
    with h5py.File(path, 'r') as h5:
        imu_t = _vec(h5, 'tTimu')
        f = np.column_stack([_vec(h5, k) for k in ('Ax', 'Ay', 'Az')])
        w = np.column_stack([_vec(h5, k) for k in ('Gx', 'Gy', 'Gz')])
        wheel_t = _vec(h5, 'tTodom')
        # Left wheels read negative when driving forward: make every joint forward positive.
        sign = np.array([-1.0, 1.0, -1.0, 1.0])
        rate = np.column_stack([_vec(h5, k + 'Vel') for k in WHEEL_FIELDS]) * sign
        angle = np.column_stack([_vec(h5, k + 'Pos') for k in WHEEL_FIELDS]) * sign
        llh = np.asarray(h5['llhGPS'][()], dtype=float)
        if llh.shape[0] == 3 and llh.shape[1] != 3:
            llh = llh.T
        if 'tTGPS' in h5:
            gnss_t = _vec(h5, 'tTGPS')
        else:
            gnss_t = read_matlab_table(h5, 'gpsECEF')['time']
        sigma = None
        if all(k in h5 for k in ('LatSigma', 'LonSigma', 'HeightSigma')):
            sigma = np.column_stack([_vec(h5, 'LonSigma'), _vec(h5, 'LatSigma'),
                                     _vec(h5, 'HeightSigma')])
    if len(gnss_t) != len(llh):
        raise ValueError(f'{path.name}: {len(gnss_t)} GNSS times for {len(llh)} positions')
    if np.nanmax(gnss_t) < SECONDS_PER_WEEK:
        gnss_t = gps_tow_to_unix(gnss_t, float(imu_t[0]))
        base = 'gps_tow'
    else:
        base = 'unix'
    return PathfinderLog(path.stem, imu_t, f, w, wheel_t, rate, angle, gnss_t, llh, sigma, base)
