"""Vectorised kinematics on the simulator's fine grid (arrays over time, first axis): integrals,
derivatives, attitude matrices and quaternions (numpy only)."""
from __future__ import annotations

import numpy as np


def cumtrapz(y: np.ndarray, dt: float) -> np.ndarray:
    """Cumulative trapezoidal integral of ``y`` (first axis) at step ``dt``, starting at 0."""
    out = np.zeros_like(y)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * dt, axis=0)
    return out


def attitude_dcm(psi: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Vectorised ``Rz(psi) Ry(pitch) Rx(roll)`` (frames.rpy_to_dcm), shape (N, 3, 3)."""
    cy, sy = np.cos(psi), np.sin(psi)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    C = np.empty((len(psi), 3, 3))
    C[:, 0, 0] = cy * cp
    C[:, 0, 1] = cy * sp * sr - sy * cr
    C[:, 0, 2] = cy * sp * cr + sy * sr
    C[:, 1, 0] = sy * cp
    C[:, 1, 1] = sy * sp * sr + cy * cr
    C[:, 1, 2] = sy * sp * cr - cy * sr
    C[:, 2, 0] = -sp
    C[:, 2, 1] = cp * sr
    C[:, 2, 2] = cp * cr
    return C


def dcm_to_quat_wxyz(C: np.ndarray) -> np.ndarray:
    """Vectorised rotation matrix -> unit quaternion (w, x, y, z), w >= 0."""
    tr = np.trace(C, axis1=1, axis2=2)
    # Stable for all rotations: pick the largest of the four squared components.
    q2 = np.stack([1.0 + tr, 1.0 + 2.0 * C[:, 0, 0] - tr, 1.0 + 2.0 * C[:, 1, 1] - tr,
                   1.0 + 2.0 * C[:, 2, 2] - tr], axis=1) / 4.0
    i = np.argmax(q2, axis=1)
    q = np.empty((len(C), 4))
    n = np.arange(len(C))
    qi = np.sqrt(q2[n, i])
    d = 4.0 * qi
    m = C
    comb = {
        0: (qi, (m[:, 2, 1] - m[:, 1, 2]) / d, (m[:, 0, 2] - m[:, 2, 0]) / d,
            (m[:, 1, 0] - m[:, 0, 1]) / d),
        1: ((m[:, 2, 1] - m[:, 1, 2]) / d, qi, (m[:, 0, 1] + m[:, 1, 0]) / d,
            (m[:, 0, 2] + m[:, 2, 0]) / d),
        2: ((m[:, 0, 2] - m[:, 2, 0]) / d, (m[:, 0, 1] + m[:, 1, 0]) / d, qi,
            (m[:, 1, 2] + m[:, 2, 1]) / d),
        3: ((m[:, 1, 0] - m[:, 0, 1]) / d, (m[:, 0, 2] + m[:, 2, 0]) / d,
            (m[:, 1, 2] + m[:, 2, 1]) / d, qi),
    }
    for k, comps in comb.items():
        sel = i == k
        q[sel] = np.stack([c[sel] for c in comps], axis=1)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0.0] *= -1.0
    return q


def vee_rel(Ca: np.ndarray, Cb: np.ndarray) -> np.ndarray:
    """Rotation vector of Ca^T Cb (small angles), shape (N, 3)."""
    R = np.einsum('nji,njk->nik', Ca, Cb)
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                        R[:, 1, 0] - R[:, 0, 1]], axis=1)
    s = np.linalg.norm(v, axis=1)
    # asin correction keeps the rate exact to O(h^2) even for fast turns.
    scale = np.where(s > 1e-12, np.arcsin(np.minimum(s, 1.0)) / np.maximum(s, 1e-300), 1.0)
    return v * scale[:, None]


def central_diff(y: np.ndarray, h: float) -> np.ndarray:
    """Derivative of ``y`` (first axis) at step ``h``: central inside, one-sided at the ends."""
    d = np.empty_like(y)
    d[1:-1] = (y[2:] - y[:-2]) / (2.0 * h)
    d[0] = (y[1] - y[0]) / h
    d[-1] = (y[-1] - y[-2]) / h
    return d
