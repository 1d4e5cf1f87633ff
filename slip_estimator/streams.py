"""Sensor streams as the core's records, and the one loop that feeds them to the core.

Every offline source becomes a :class:`SensorData` (IMU in the body frame, one rim speed per
wheel, the side of each wheel from its joint name): a simulated drive (:func:`from_simulation`)
or a Pathfinder log (:func:`from_pathfinder`). :func:`records` turns it into the core's
:class:`~slip_estimator.core.types.ImuSample` / :class:`~slip_estimator.core.types.WheelSample`
in arrival order and :func:`feed` pushes records through an estimator. Bags (and the live
node) arrive as ROS messages: :mod:`slip_estimator.ros.convert` turns each message into the
same records, checking it there, and :mod:`slip_estimator.ros.adapter` feeds them; the wheel
side of a joint is :func:`wheel_side` on both paths.

Order: a wheel sample goes to the core before the first IMU sample with a later stamp (at
equal stamps the IMU goes first, as in the replay); wheel samples after the last IMU sample
are not fed (they would wait for an IMU sample that never comes).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from slip_estimator.core import frames
from slip_estimator.core.types import ImuSample, SlipEstimate, WheelSample


def wheel_side(joint_name: str) -> str | None:
    """'left', 'right' or None from a joint name (case-insensitive substring)."""
    name = joint_name.lower()
    is_left, is_right = 'left' in name, 'right' in name
    if is_left == is_right:
        return None
    return 'left' if is_left else 'right'


@dataclass(frozen=True)
class SensorData:
    """Sensor streams in the estimator's body frame.

    imu_ns : IMU stamps, ns (N,); f_ib_b, omega_ib_b : (N, 3) in FRD body axes, SI.
    wheel_ns : wheel stamps, ns (M,); rim_mps : (M, K) rim speed of each wheel, m/s.
    wheel_sides : per column of ``rim_mps``, 'left', 'right' or None (:func:`wheel_side` of
    the joint name); without sides only the mean rim speed is known.
    """

    imu_ns: np.ndarray
    f_ib_b: np.ndarray
    omega_ib_b: np.ndarray
    wheel_ns: np.ndarray
    rim_mps: np.ndarray
    wheel_sides: tuple[str | None, ...] = ()

    @property
    def duration_s(self) -> float:
        """Time from the first to the last IMU sample, s."""
        return float(self.imu_ns[-1] - self.imu_ns[0]) * 1e-9

    @property
    def n_imu(self) -> int:
        return len(self.imu_ns)

    def shifted(self, offset_ns: int) -> SensorData:
        """The same streams with every stamp moved by ``offset_ns``."""
        return dataclasses.replace(self, imu_ns=self.imu_ns + offset_ns,
                                   wheel_ns=self.wheel_ns + offset_ns)

    def wheel_samples(self) -> list[WheelSample]:
        """One :class:`WheelSample` per wheel stamp: the mean rim speed of all wheels and of
        each side's wheels (None for a side without wheels)."""
        rim = self.rim_mps
        mean = rim.mean(axis=1).tolist()
        sides = []
        for side in ('left', 'right'):
            cols = [k for k, s in enumerate(self.wheel_sides) if s == side]
            sides.append(rim[:, cols].mean(axis=1).tolist() if cols else [None] * len(rim))
        return [WheelSample(s, v, left, right) for s, v, left, right in zip(
            self.wheel_ns.tolist(), mean, *sides)]


def concatenate(parts: Sequence[SensorData]) -> SensorData:
    """Streams one after the other (stamps as they are: shift the parts first)."""
    cat = np.concatenate
    return SensorData(cat([d.imu_ns for d in parts]), cat([d.f_ib_b for d in parts]),
                      cat([d.omega_ib_b for d in parts]), cat([d.wheel_ns for d in parts]),
                      cat([d.rim_mps for d in parts]), parts[0].wheel_sides)


def _sides(params: Any) -> tuple[str | None, ...]:
    return tuple(wheel_side(n) for n in params.wheel_joint_names)


def from_simulation(result: Any, params: Any) -> SensorData:
    """A simulated drive (``sim.simulate`` result) as the node would see it with ``params``:
    IMU rotated into the body frame, wheel rates times the declared radius."""
    C = frames.imu_to_body_dcm(params.imu_to_base_rpy)
    return SensorData(result.stamps_ns(result.imu_t_s), result.f_ib_imu @ C.T,
                      result.omega_ib_imu @ C.T, result.stamps_ns(result.wheel_t_s),
                      result.wheel_rate_rps * params.wheel_radius, _sides(params))


def from_pathfinder(log: Any, params: Any) -> SensorData:
    """A Pathfinder log (``pathfinder.load_mat``) as the node would see it with ``params``."""
    C = frames.imu_to_body_dcm(params.imu_to_base_rpy)
    return SensorData(np.round(log.imu_t_s * 1e9).astype(np.int64), log.f_ib_imu @ C.T,
                      log.omega_ib_imu @ C.T, np.round(log.wheel_t_s * 1e9).astype(np.int64),
                      log.wheel_rate_rps * params.wheel_radius, _sides(params))


def records(data: SensorData) -> Iterator[ImuSample | WheelSample]:
    """The core's records of ``data`` in arrival order (see the module docstring), made one
    at a time (an hour of IMU records would not fit a list comfortably)."""
    wheels = data.wheel_samples()
    wheel_ns = data.wheel_ns.tolist()
    f, w = data.f_ib_b, data.omega_ib_b
    j, m = 0, len(wheels)
    for i, stamp in enumerate(data.imu_ns.tolist()):
        while j < m and wheel_ns[j] < stamp:
            yield wheels[j]
            j += 1
        yield ImuSample(stamp, f[i], w[i])


def feed(est: Any, recs: Iterable[ImuSample | WheelSample],
         after_imu: Callable[[ImuSample], None] | None = None,
         keep_estimates: bool = True) -> list[SlipEstimate]:
    """Push records through ``est`` (a ``SlipEstimator``); ``after_imu`` is called after each
    IMU sample (odometry sampling, memory probes). Returns every slip estimate (nothing with
    ``keep_estimates=False``: long runs that measure memory or time keep none)."""
    out: list[SlipEstimate] = []
    keep = out.extend if keep_estimates else _discard
    add_imu, add_wheel = est.add_imu, est.add_wheel
    for r in recs:
        if r.__class__ is ImuSample:
            keep(add_imu(r))
            if after_imu is not None:
                after_imu(r)
        else:
            keep(add_wheel(r))
    return out


def _discard(_: list[SlipEstimate]) -> None:
    pass
