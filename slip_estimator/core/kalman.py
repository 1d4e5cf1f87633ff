"""Kalman filter steps with textbook names (paper eq. 13, 15-16, 28).

Copy-in / return-out: the functions never modify their inputs. The covariance update uses the
Joseph form (paper eq. 28 prints the short form, which loses symmetry and positive
definiteness in floating point) and the gain comes from ``solve``, not an explicit inverse.
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

try:  # the LAPACK gufuncs behind np.linalg.solve (present in numpy 1.x and 2.x)
    from numpy.linalg import _umath_linalg as _lapack
except ImportError:  # pragma: no cover -- then np.linalg.solve itself is used
    _lapack = None

# Chi-square quantiles for the innovation gate: {dof: {probability: threshold}} (no scipy).
_CHI2 = {
    1: {0.9: 2.706, 0.95: 3.841, 0.99: 6.635, 0.999: 10.828, 0.9999: 15.137},
    2: {0.9: 4.605, 0.95: 5.991, 0.99: 9.210, 0.999: 13.816, 0.9999: 18.421},
    3: {0.9: 6.251, 0.95: 7.815, 0.99: 11.345, 0.999: 16.266, 0.9999: 21.108},
}


def chi2_threshold(dof: int, probability: float) -> float:
    """Gate threshold for ``dof`` degrees of freedom; ``probability >= 1`` disables the gate.

    Uses the tabulated quantile at the largest tabulated probability not above ``probability``.
    """
    if probability >= 1.0:
        return float('inf')
    table = _CHI2[dof]
    keys = [p for p in sorted(table) if p <= probability + 1e-12]
    return table[keys[-1]] if keys else table[min(table)]


@dataclass(frozen=True, slots=True)
class UpdateRecord:
    """What one measurement update did: for diagnostics, consistency tests and residual studies.

    Attributes
    ----------
    name : measurement model name.
    innovation : z - h(x), measurement units.
    S : innovation covariance.
    nis : normalised innovation squared ``innovation^T S^-1 innovation``.
    accepted : False when the chi-square gate rejected the update.
    """

    name: str
    innovation: np.ndarray
    S: np.ndarray
    nis: float
    accepted: bool


_IDENTITY: dict[int, np.ndarray] = {}


def _identity(n: int) -> np.ndarray:
    """A read-only ``np.eye(n)``, made once per size."""
    eye = _IDENTITY.get(n)
    if eye is None:
        eye = _IDENTITY[n] = np.eye(n)
        eye.flags.writeable = False
    return eye


_add_reduce = np.add.reduce


def solve(S: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve(S, b)`` for one square ``S`` and a vector or matrix ``b``.

    The same LAPACK gufunc, called without np.linalg.solve's per-call argument checks and
    error-state context, which cost several times the solve of these small systems. Any
    non-finite result (singular or non-finite S) is redone by np.linalg.solve, so it raises
    LinAlgError exactly where np.linalg.solve would (a singular S, impossible with R > 0,
    also shows numpy's "invalid value" RuntimeWarning first).
    """
    if _lapack is not None:
        x = (_lapack.solve1 if b.ndim == 1 else _lapack.solve)(S, b)
        if math.isfinite(float(_add_reduce(x, None))):  # x.sum() without its wrapper
            return x
    return np.linalg.solve(S, b)


def symmetrize(P: np.ndarray) -> np.ndarray:
    """``(P + P^T) / 2`` (as ``0.5 * (P + P.T)``, halved in place: one array fewer)."""
    S = P + P.T
    S *= 0.5
    return S


def predict(P: np.ndarray, Phi: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Covariance propagation ``Phi P Phi^T + Q`` (eq. 13); the error state itself is zero
    between updates in a closed-loop filter, so only P is propagated."""
    A = Phi @ P @ Phi.T
    A += Q
    return symmetrize(A)


def update(P: np.ndarray, innovation: np.ndarray, H: np.ndarray, R: np.ndarray,
           gate: float = float('inf'), name: str = '',
           consider: list[int] | None = None,
           consider_share: float = 0.0) -> tuple[np.ndarray, np.ndarray, UpdateRecord]:
    """Error-state measurement update.

    ``consider``: error-state indices the update must not correct (Schmidt "consider"
    states: their gain rows are zero; the Joseph form keeps P right for that gain, so their
    uncertainty still enters S and the cross-covariances); ``consider_share`` of their gain is
    kept (0: pure consider states; any gain keeps the Joseph form's P right).
    Returns the error-state estimate ``dx`` (zero when gated out), the updated covariance and
    the update record.
    """
    PHt = P @ H.T
    S = H @ PHt + R
    if len(S) > 1:  # a 1x1 S is symmetric: (s + s) * 0.5 == s exactly (2.3 us saved)
        S = symmetrize(S)
    nis = float(innovation @ solve(S, innovation))
    if not nis <= gate:  # also rejects NaN
        return np.zeros(P.shape[0]), P, UpdateRecord(name, innovation, S, nis, False)
    K = solve(S, PHt.T).T
    if consider is not None:
        if consider_share == 0.0:
            for i in consider:  # one row at a time: 0.2 us each, a fancy index 1.7 us
                K[i] = 0.0
        else:
            K[consider, :] *= consider_share
    dx = K @ innovation
    IKH = _identity(P.shape[0]) - K @ H
    P_new = symmetrize(IKH @ P @ IKH.T + K @ R @ K.T)
    return dx, P_new, UpdateRecord(name, innovation, S, nis, True)
