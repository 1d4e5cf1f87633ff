"""The estimator facade: IMU and wheel samples in, odometry, slip and health out.

(API fixed first; the implementation follows.)
"""
from __future__ import annotations

from slip_estimator.core.params import Params
from slip_estimator.core.types import Health, ImuSample, OdometryEstimate, SlipEstimate, WheelSample


class SlipEstimator:
    """Strapdown INS + 15-state error-state EKF + detectors + slip computation.

    Samples may be added in any interleaving as they arrive; each call returns the slip
    estimates that became computable (a wheel sample is evaluated once the filter has reached
    its time, so its slip refers to the body velocity at the wheel sample time).
    """

    def __init__(self, params: Params) -> None:
        self.params = params

    def add_imu(self, sample: ImuSample) -> list[SlipEstimate]:
        """Process one IMU sample; return slip estimates that became due."""
        raise NotImplementedError

    def add_wheel(self, sample: WheelSample) -> list[SlipEstimate]:
        """Process one wheel sample; return slip estimates that became due."""
        raise NotImplementedError

    def odometry(self) -> OdometryEstimate | None:
        """Current fused solution, or None before the initial alignment has finished."""
        raise NotImplementedError

    def health(self) -> Health:
        """Current self-diagnosis."""
        raise NotImplementedError
