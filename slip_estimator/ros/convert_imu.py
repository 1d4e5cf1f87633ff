"""``sensor_msgs/Imu`` -> :class:`~slip_estimator.core.types.ImuSample` in the core body frame b
(FRD): from a message object, one serialized message, or a batch of serialized messages.

REP-145: ``linear_acceleration`` is the specific force (at rest and level a z-up IMU reads about
+9.81 m/s^2 on z) and ``angular_velocity`` the body rate, both resolved in the IMU frame; they
are rotated into b with ``C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)``. Every path
ends in :func:`imu_from_values` (the checks and the rotation) or is bit-identical to it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from sensor_msgs.msg import Imu

from slip_estimator.core.alignment import tilt_from_orientation
from slip_estimator.core.types import MAX_ANGULAR_RATE_RPS, MAX_SPECIFIC_FORCE_MPS2, ImuSample
from slip_estimator.ros import cdr
from slip_estimator.ros.msgbuild import fields_getter
from slip_estimator.ros.rejections import (REASON_ABSURD_IMU, REASON_NON_FINITE,
                                           REASON_ZERO_STAMP)
from slip_estimator.ros.stamps import NS_PER_S


def imu_from_msg(msg: Imu, C_imu_b: np.ndarray) -> ImuSample | str:
    """Body-frame IMU sample from a REP-145 ``sensor_msgs/Imu``, or a rejection reason
    (:func:`imu_from_values`)."""
    sec, nanosec, *f_w = _IMU_FIELDS(msg)
    cov, *q_wxyz = _IMU_ORIENTATION(msg)
    return imu_from_values(int(sec) * NS_PER_S + int(nanosec), tuple(f_w[:3]), tuple(f_w[3:]),
                           cov[0], q_wxyz, *_IMU_COVARIANCES(msg), C_imu_b)


def imu_from_values(stamp_ns: int, f_ib_imu: tuple[float, float, float],
                    omega_ib_imu: tuple[float, float, float], orientation_cov0: float,
                    q_imu_wxyz: Sequence[float], accel_cov: Sequence[float],
                    gyro_cov: Sequence[float], C_imu_b: np.ndarray) -> ImuSample | str:
    """Body-frame IMU sample from the fields of a REP-145 ``sensor_msgs/Imu`` (however they
    were read: :func:`imu_from_msg`, :func:`imu_from_cdr`, :func:`imu_samples_from_cdr`), or a
    rejection reason.

    ``f_ib_b = C_imu_b @ f_ib_imu`` and ``omega_ib_b = C_imu_b @ omega_ib_imu``: the lever arm
    does not matter for rates, and for the specific force it is ignored (rover body rates are
    small; the mounting offset is the core's business if ever needed).
    """
    if stamp_ns <= 0:  # zero (never set) or before the epoch: not a usable time
        return REASON_ZERO_STAMP
    # A finite sum has finite terms; a non-finite one may be an overflow of finite terms.
    if (not math.isfinite(sum(f_ib_imu) + sum(omega_ib_imu))
            and not all(map(math.isfinite, f_ib_imu + omega_ib_imu))):
        return REASON_NON_FINITE
    if (math.hypot(*f_ib_imu) > MAX_SPECIFIC_FORCE_MPS2
            or math.hypot(*omega_ib_imu) > MAX_ANGULAR_RATE_RPS):
        return REASON_ABSURD_IMU
    # orientation_covariance[0] = -1: no orientation (REP-145); anything else: provided.
    tilt = (None if orientation_cov0 == -1.0
            else tilt_from_orientation(tuple(q_imu_wxyz), C_imu_b))
    return ImuSample(stamp_ns=stamp_ns,
                     f_ib_b=C_imu_b @ np.array(f_ib_imu),
                     omega_ib_b=C_imu_b @ np.array(omega_ib_imu), tilt_rp_rad=tilt,
                     noise_var=_noise_variances(accel_cov, gyro_cov))


def imu_from_cdr(raw: bytes | memoryview, C_imu_b: np.ndarray) -> ImuSample | str:
    """:func:`imu_from_values` of one serialized ``sensor_msgs/Imu`` (the live node's raw
    subscription); a message that does not decode gives its :mod:`cdr` rejection reason."""
    try:
        stamp_ns, start = cdr.imu_start(raw)
    except cdr.CdrError as exc:
        return exc.reason
    return _imu_from_doubles(stamp_ns, cdr.IMU_STRUCT.unpack_from(raw, start), C_imu_b)


_PLAIN_MARGIN = 0.99
"""Rows of :func:`imu_samples_from_cdr` this far inside the absurd-value limits take the
vectorised path; rows nearer a limit, or with anything unusual, take :func:`imu_from_values`."""


def imu_samples_from_cdr(raws: Sequence[bytes | memoryview], C_imu_b: np.ndarray
                         ) -> list[tuple[int, ImuSample | str]]:
    """(stamp ns or 0, :func:`imu_from_values`) of each serialized ``sensor_msgs/Imu``: the
    replay's batch decode, identical to one :func:`imu_from_cdr` per message.

    The rows of usual samples (a positive stamp, finite, well inside the limits, no
    orientation, finite covariance diagonals) are rotated in one stacked ``matmul`` (per row
    the very ``C_imu_b @ v`` product: bit-identical, checked by the tests); the others go
    through :func:`imu_from_values` one by one.
    """
    stamps, A = cdr.imu_values(raws)
    if not raws:
        return []
    f_imu, w_imu = A[:, cdr.IMU_ACCEL], A[:, cdr.IMU_OMEGA]
    diag_a, diag_g = A[:, [28, 32, 36]], A[:, [16, 20, 24]]
    with np.errstate(over='ignore', invalid='ignore'):  # the rows with these take the other path
        F = np.matmul(C_imu_b, np.ascontiguousarray(f_imu)[:, :, None])[:, :, 0]
        W = np.matmul(C_imu_b, np.ascontiguousarray(w_imu)[:, :, None])[:, :, 0]
        plain = (np.isfinite(A[:, 13:28]).all(axis=1)  # omega, its covariance, accel
                 & np.isfinite(diag_a).all(axis=1)
                 & (A[:, cdr.IMU_ORIENTATION_COV0] == -1.0)
                 & ((f_imu * f_imu).sum(axis=1)
                    < (_PLAIN_MARGIN * MAX_SPECIFIC_FORCE_MPS2) ** 2)
                 & ((w_imu * w_imu).sum(axis=1) < (_PLAIN_MARGIN * MAX_ANGULAR_RATE_RPS) ** 2))
        var_a, var_g = diag_a.max(axis=1), diag_g.max(axis=1)
        noise_ok = ((var_a > 0.0) & (var_g > 0.0) & np.isfinite(var_a + var_g)).tolist()
    noise = list(zip(var_a.tolist(), var_g.tolist()))
    out: list[tuple[int, ImuSample | str]] = []
    for i, (stamp_ns, is_plain) in enumerate(zip(stamps, plain.tolist())):
        if isinstance(stamp_ns, str):  # did not decode
            out.append((0, stamp_ns))
        elif is_plain and stamp_ns > 0:
            out.append((stamp_ns, ImuSample(stamp_ns, F[i], W[i], None,
                                            noise[i] if noise_ok[i] else None)))
        else:
            out.append((stamp_ns, _imu_from_doubles(stamp_ns, A[i].tolist(), C_imu_b)))
    return out


def _imu_from_doubles(stamp_ns: int, v: Sequence[float], C_imu_b: np.ndarray
                      ) -> ImuSample | str:
    """:func:`imu_from_values` of the 37 doubles of a serialized ``sensor_msgs/Imu``
    (:data:`cdr.IMU_DOUBLES`: orientation x, y, z, w and the three covariances)."""
    x, y, z, w = v[cdr.IMU_Q_XYZW]
    return imu_from_values(stamp_ns, tuple(v[cdr.IMU_ACCEL]), tuple(v[cdr.IMU_OMEGA]),
                           v[cdr.IMU_ORIENTATION_COV0], (w, x, y, z), v[cdr.IMU_ACCEL_COV],
                           v[cdr.IMU_OMEGA_COV], C_imu_b)


def _noise_variances(accel_cov: Sequence[float], gyro_cov: Sequence[float]
                     ) -> tuple[float, float] | None:
    """The largest diagonal accelerometer and gyro variances of an Imu message, or None when
    either is not given (all zero: unknown; -1: not measured) or not finite."""
    var_a = max(accel_cov[0], accel_cov[4], accel_cov[8])
    var_g = max(gyro_cov[0], gyro_cov[4], gyro_cov[8])
    if var_a > 0.0 and var_g > 0.0 and math.isfinite(var_a + var_g):
        return float(var_a), float(var_g)
    return None


_IMU_FIELDS = fields_getter(Imu, 'header.stamp.sec', 'header.stamp.nanosec',
                            'linear_acceleration.x', 'linear_acceleration.y',
                            'linear_acceleration.z', 'angular_velocity.x', 'angular_velocity.y',
                            'angular_velocity.z')
_IMU_COVARIANCES = fields_getter(Imu, 'linear_acceleration_covariance',
                                 'angular_velocity_covariance')
_IMU_ORIENTATION = fields_getter(Imu, 'orientation_covariance', 'orientation.w', 'orientation.x',
                                 'orientation.y', 'orientation.z')
