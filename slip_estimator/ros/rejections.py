"""Why an input message gives no record: the rejection reasons the input converters return
(:mod:`slip_estimator.ros.convert`) and the node counts per topic. Serialized input that does not
decode has two more, :data:`slip_estimator.ros.cdr.REASON_MALFORMED` and
:data:`~slip_estimator.ros.cdr.REASON_BIG_ENDIAN`."""

REASON_ZERO_STAMP = 'zero_stamp'
REASON_NON_FINITE = 'non_finite'
REASON_ABSURD_IMU = 'absurd_imu'
REASON_ABSURD_SPEED = 'absurd_wheel_speed'
REASON_NO_WHEEL_JOINTS = 'no_wheel_joints'
REASON_NO_VELOCITY = 'no_velocity'
REASON_FIRST_POSITION = 'first_position'  # positions only: a rate needs the next message
REASON_POSITION_RESET = 'position_reset'  # positions only: a jump no wheel can turn
