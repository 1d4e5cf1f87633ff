"""Input messages to core records with the parameters in force: the IMU mounting
(``imu_to_base_rpy``), the wheel joints, radius and speed limit, the track width. Message objects
or their serialized bytes (CDR) alike, through :mod:`slip_estimator.ros.convert`; a message that
cannot be used gives the reason it is rejected instead of a record."""
from __future__ import annotations

from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core import frames
from slip_estimator.core.params import Params
from slip_estimator.core.types import ImuSample, WheelSample
from slip_estimator.ros import convert


class InputDecoder:
    """Decodes the inputs for one estimator run (the wheel rates derived from joint positions
    keep the previous position: a new run starts a new decoder)."""

    __slots__ = ('_params', '_C_imu_b', '_joint_rates')

    def __init__(self, params: Params) -> None:
        self._params = params
        self._C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)
        self._joint_rates = convert.JointRatesFromPositions(
            params.max_wheel_speed_mps / params.wheel_radius)

    def imu(self, msg: Imu) -> ImuSample | str:
        """A ``sensor_msgs/Imu`` message object."""
        return convert.imu_from_msg(msg, self._C_imu_b)

    def imu_raw(self, raw: bytes | memoryview) -> ImuSample | str:
        """A serialized ``sensor_msgs/Imu``."""
        return convert.imu_from_cdr(raw, self._C_imu_b)

    def imu_batch(self, raws: list[bytes]) -> list[tuple[int, ImuSample | str]]:
        """(stamp ns, sample or rejection reason) of serialized IMU messages, in one batch."""
        return convert.imu_samples_from_cdr(raws, self._C_imu_b)

    def joint_states(self, msg: JointState) -> WheelSample | str:
        """A ``sensor_msgs/JointState`` message object (wheel angular velocities)."""
        p = self._params
        return convert.wheel_from_joint_state(msg, p.wheel_joint_names, p.wheel_radius,
                                              max_speed_mps=p.max_wheel_speed_mps,
                                              from_positions=self._joint_rates)

    def joint_states_raw(self, raw: bytes | memoryview) -> WheelSample | str:
        """A serialized ``sensor_msgs/JointState``."""
        p = self._params
        return convert.wheel_from_cdr_joint_state(
            raw, p.wheel_joint_names, p.wheel_radius, max_speed_mps=p.max_wheel_speed_mps,
            from_positions=self._joint_rates)

    def wheel_odometry(self, msg: Odometry) -> WheelSample | str:
        """A wheel-odometry ``nav_msgs/Odometry`` message object."""
        p = self._params
        return convert.wheel_from_odometry(msg, p.track_width,
                                           max_speed_mps=p.max_wheel_speed_mps)

    def wheel_odometry_raw(self, raw: bytes | memoryview) -> WheelSample | str:
        """A serialized wheel-odometry ``nav_msgs/Odometry``."""
        p = self._params
        return convert.wheel_from_cdr_odometry(raw, p.track_width,
                                               max_speed_mps=p.max_wheel_speed_mps)
