"""The IMU-floor evidence (``validation.imu_floor``): its closed-form parts."""
from __future__ import annotations

import math

import numpy as np
import pytest

from slip_estimator.core.alignment import level
from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.validation.imu_floor import oracle_recall


@pytest.mark.parametrize('pitch_deg, roll_deg', [(0.0, 0.0), (-2.8, 1.96), (10.0, -25.0)])
def test_levelling_a_resting_imu_returns_its_tilt(pitch_deg: float, roll_deg: float) -> None:
    """A resting FRD IMU measures f = -C_n^b g (g down in NED); levelling it must give back
    the tilt the DCM was built from (the tilt closure compares the two)."""
    C_b_n = rpy_to_dcm(math.radians(roll_deg), math.radians(pitch_deg), 0.0)
    assert C_b_n @ C_b_n.T == pytest.approx(np.eye(3), abs=1e-12)
    f_b = -C_b_n.T @ np.array([0.0, 0.0, 9.81])
    roll, pitch = level(np.tile(f_b, (5, 1)).mean(axis=0))
    assert (math.degrees(pitch), math.degrees(roll)) == pytest.approx((pitch_deg, roll_deg))
    assert f_b[0] * pitch_deg >= 0.0  # nose up: gravity's reaction points forward (FRD)


def test_oracle_recall_is_the_share_of_readings_that_keep_the_class() -> None:
    """s_read = s - e / rim: at rim 1 m/s a truth of 0.30 (medium, (0.2, 0.4]) keeps its
    class for speed errors in [-0.1, 0.1)."""
    assert oracle_recall(np.zeros(7), 0.30, 1.0) == 1.0
    assert oracle_recall(np.full(3, -0.15), 0.30, 1.0) == 0.0  # read 0.45: high
    assert oracle_recall(np.full(3, 0.15), 0.30, 1.0) == 0.0  # read 0.15: low
    # a body read too fast reads too little slip: 0.25 with +0.08 m/s is 0.17 (low)
    assert oracle_recall(np.full(3, 0.08), 0.25, 1.0) == 0.0
    assert oracle_recall(np.full(3, -0.08), 0.25, 1.0) == 1.0
    e = np.linspace(-0.2, 0.2, 4001)
    assert oracle_recall(e, 0.30, 1.0) == pytest.approx(0.5, abs=1e-3)
    # the same speed error costs more at a lower rim speed
    assert oracle_recall(e, 0.30, 0.5) == pytest.approx(0.25, abs=1e-3)


def test_class_recall_bound_averages_the_oracle_per_truth_class() -> None:
    """Per moving class, the mean of the oracle's recall over that class's truth samples;
    NaN for a class the truth lacks; samples at rest or without a rim speed are not read."""
    from slip_estimator.validation.imu_floor import class_recall_bound

    slip = np.array([0.10, 0.10, 0.30, 0.25, 0.0, 0.5])
    cls = np.array([1, 1, 2, 2, 0, 3])
    rim = np.array([1.0, 1.0, 1.0, 1.0, 0.0, 0.01])  # the high sample has no rim speed
    assert class_recall_bound(np.zeros(5), slip, cls, rim)[:2] == [1.0, 1.0]
    e = np.array([0.0, 0.08])  # +0.08 m/s: 0.30 reads 0.22 (kept), 0.25 reads 0.17 (lost)
    low, medium, high, extreme = class_recall_bound(e, slip, cls, rim)
    assert low == 1.0 and medium == pytest.approx(0.75)
    assert math.isnan(high) and math.isnan(extreme)
