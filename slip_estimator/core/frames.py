"""Frame conventions and rotation helpers. The one place where frames are converted.

Conventions of the estimation core (Groves 2013 notation):

* ``i`` inertial, ``e`` planet-centred planet-fixed, ``n`` local-level navigation frame with
  NED axes (north, east, down), ``b`` body frame with FRD axes (forward, right, down).
* ``C_b_n`` is the direction-cosine matrix that takes a vector resolved in b to n
  (``v_n = C_b_n @ v_b``); ``v_eb_n`` is the velocity of b w.r.t. e resolved in n;
  ``omega_ib_b`` the angular rate of b w.r.t. i resolved in b.
* Quaternions are (w, x, y, z), Hamilton, ``q_nb_wxyz`` rotates b vectors into n.

ROS conventions at the boundary (REP-103/105/145): ``base_link`` is FLU, ``odom`` is ENU. The
core body frame b is base_link rotated by 180 deg about x; the IMU frame is given by its pose in
base_link (``imu_to_base_rpy``, the static transform base_link -> imu_link).
"""
from __future__ import annotations

import math

import numpy as np

# FLU <-> FRD and ENU <-> NED are involutions (each matrix is its own inverse and transpose).
C_FLU_FRD = np.diag([1.0, -1.0, -1.0])
"""Takes a vector resolved in an FLU frame to the FRD frame with the same x axis (and back)."""
C_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""Takes a vector resolved in ENU to NED (and back)."""
_EYE_3 = np.eye(3)
_EYE_3.flags.writeable = False


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix ``[v x]`` such that ``skew(a) @ b == cross(a, b)``."""
    # An array's elements as floats: numpy scalars in the list made np.array 3 times slower.
    x, y, z = v.tolist() if isinstance(v, np.ndarray) else v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` for 3-vectors (np.cross costs ~30 us per call on small arrays, this ~2 us)."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def rot_x(a: float) -> np.ndarray:
    """Active rotation matrix about x by ``a`` rad."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Active rotation matrix about y by ``a`` rad."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Active rotation matrix about z by ``a`` rad."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_to_dcm(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """DCM of the child frame in the parent frame from roll, pitch, yaw (ROS / tf convention).

    ``R = Rz(yaw) Ry(pitch) Rx(roll)``; it takes child-frame vectors to the parent frame. With
    NED/FRD frames the same formula gives Groves' ``C_b_n`` from his Euler angles (eq. 2.22).
    """
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def dcm_to_rpy(C: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of a DCM built as in :func:`rpy_to_dcm` (paper eq. 25)."""
    roll = math.atan2(C[2, 1], C[2, 2])
    pitch = -math.asin(max(-1.0, min(1.0, C[2, 0])))
    yaw = math.atan2(C[1, 0], C[0, 0])
    return np.array([roll, pitch, yaw])


def rotvec_to_dcm(phi: np.ndarray) -> np.ndarray:
    """Rodrigues: DCM of the rotation vector ``phi`` (rad), ``exp([phi x])``."""
    x, y, z = np.asarray(phi, dtype=float).tolist()
    angle = math.sqrt(x * x + y * y + z * z)
    K = np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))  # skew(phi)
    if angle < 1e-8:
        return _EYE_3 + K + 0.5 * K @ K
    return (_EYE_3 + (math.sin(angle) / angle) * K
            + ((1.0 - math.cos(angle)) / (angle * angle)) * K @ K)


def orthonormalize(C: np.ndarray) -> np.ndarray:
    """Removes the numerical drift of an integrated DCM: ``C - (C C^T - I) C / 2``, the
    first-order step towards the nearest rotation (Savage; exact to O(e^2) for an error e)."""
    return C - 0.5 * (C @ C.T - _EYE_3) @ C


def dcm_to_quat_wxyz(C: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    return np.array(dcm_to_quat_wxyz_floats(*np.asarray(C, dtype=float).ravel().tolist()))


def dcm_to_quat_wxyz_floats(c11: float, c12: float, c13: float, c21: float, c22: float,
                            c23: float, c31: float, c32: float,
                            c33: float) -> tuple[float, float, float, float]:
    """:func:`dcm_to_quat_wxyz` of the matrix entries (row-major), on floats."""
    tr = c11 + c22 + c33
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = (0.25 * s, (c32 - c23) / s, (c13 - c31) / s, (c21 - c12) / s)
    elif c11 > c22 and c11 > c33:
        s = 2.0 * math.sqrt(1.0 + c11 - c22 - c33)
        q = ((c32 - c23) / s, 0.25 * s, (c12 + c21) / s, (c13 + c31) / s)
    elif c22 > c33:
        s = 2.0 * math.sqrt(1.0 + c22 - c11 - c33)
        q = ((c13 - c31) / s, (c12 + c21) / s, 0.25 * s, (c23 + c32) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + c33 - c11 - c22)
        q = ((c21 - c12) / s, (c13 + c31) / s, (c23 + c32) / s, 0.25 * s)
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return w / n, x / n, y / n, z / n


def quat_wxyz_to_dcm(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z); normalises the input."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def imu_to_body_dcm(imu_to_base_rpy: np.ndarray | list[float]) -> np.ndarray:
    """``C_imu_b``: takes IMU-frame vectors to the core body frame b (FRD).

    ``imu_to_base_rpy`` is the orientation of imu_link in base_link (static transform
    base_link -> imu_link), so ``C_imu_base = rpy_to_dcm(*rpy)`` and b is base_link in FRD.
    """
    return C_FLU_FRD @ rpy_to_dcm(*imu_to_base_rpy)


def heading_to_yaw_enu(heading_deg: float) -> float:
    """ROS yaw (rad, counter-clockwise from east) of a heading (deg, clockwise from north)."""
    return math.pi / 2.0 - math.radians(heading_deg)
