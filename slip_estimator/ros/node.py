"""The thin rclpy node: declare parameters, subscribe, hand messages to the adapter, publish.

All logic lives in :class:`slip_estimator.ros.adapter.SlipEstimatorAdapter` (shared with the bag
replay); this module only deals with rclpy.

QoS (sensor-data inputs with deep queues, reliable outputs): :mod:`slip_estimator.ros.qos`.
Parameters (declared at start, changed at runtime, applied at a reset):
:mod:`slip_estimator.ros.node_params`.

Receiving
---------
The inputs are subscribed ``raw=True``: rclpy hands over the serialized bytes, which
:mod:`slip_estimator.ros.cdr` decodes straight into the core's records (no Python message
object per sample; malformed or big-endian bytes are counted as rejections). Measured at
250 Hz IMU + 10 Hz wheels (``slip-estimator bench --only live``, docs/performance.md): the
executor and the per-message objects were most of the node's CPU.

Under :func:`~slip_estimator.ros.spin.spin` with batches (``input_batch_period_s`` > 0) the
executor does not see the input subscriptions (:attr:`SlipEstimatorNode.subscriptions`): the
spin loop takes their messages itself (:meth:`SlipEstimatorNode.handle_ready_inputs`) and runs
the same callbacks. How the node spins (the events executor, input batches, the output step,
gc), how every callback is timed and how it stops: :mod:`slip_estimator.ros.spin`.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from operator import itemgetter
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from std_srvs.srv import Trigger

from slip_estimator.core.params import ParameterError
from slip_estimator.paramfile import params_files, read_yaml
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.cdr_out import serialize
from slip_estimator.ros.node_params import change_params, declare_params, reset_applying_changes
from slip_estimator.ros.qos import IMU_QUEUE_DEPTH, WHEEL_QUEUE_DEPTH, input_qos, output_qos
from slip_estimator.ros.spin import CallbackStats, bounded_teardown, spin, timed
from slip_estimator.ros.topics import (
    OUTPUT_TYPES,
    TOPIC_DIAGNOSTICS,
    TOPIC_IMU,
    TOPIC_SLIP,
    TOPIC_SLIP_RATIO,
    Output,
)

NODE_NAME = 'slip_estimator'
STALE_AFTER_S = 1.0
"""The watchdog reports STALE 'no IMU data' when no IMU message arrived for this long (wall)."""


class SlipEstimatorNode(Node):
    """ROS 2 node around :class:`SlipEstimatorAdapter`.

    Raises :class:`ParameterError` from the constructor when a parameter is invalid.
    """

    inputs_taken_by_spin = False
    """True while :func:`spin` takes the input messages itself (:meth:`handle_ready_inputs`):
    the input subscriptions are then not among :attr:`subscriptions`, which executors read."""

    def __init__(self, node_name: str = NODE_NAME, *, param_files: list[str] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        params, self.input_batch_period_s = declare_params(self, param_files or [])
        self.adapter = SlipEstimatorAdapter(params)
        self.get_logger().info('effective parameters: ' + ', '.join(
            f'{k}={v!r}' for k, v in params.to_dict().items()))

        self._stats = CallbackStats()
        self._pubs = {topic: self.create_publisher(
            cls, topic, output_qos(100 if topic in (TOPIC_SLIP, TOPIC_SLIP_RATIO) else 10))
            for topic, cls in OUTPUT_TYPES.items()}
        self._subs: list[Subscription] = []
        for topic, cls in self.adapter.input_types.items():
            depth = IMU_QUEUE_DEPTH if topic == TOPIC_IMU else WHEEL_QUEUE_DEPTH
            self._subs.append(self.create_subscription(
                cls, self.adapter.input_sources[topic], self._callback(topic),
                input_qos(depth), raw=True))
        self.get_logger().info(
            f'subscribed to {", ".join(self.adapter.input_sources.values())}; publishing '
            f'{", ".join(OUTPUT_TYPES)}')

        self._last_imu_wall = time.monotonic()
        self.input_callbacks = 0
        """Input messages handled so far (:func:`spin` drains until it stops growing)."""
        self.output_steps = False
        """True while :func:`spin` runs the node: outputs wait for :meth:`publish_outputs`."""
        self._outputs: list[Output] = []
        self._watchdog = self.create_timer(
            STALE_AFTER_S, self._check_imu_stale, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._reset_service = self.create_service(Trigger, '~/reset', self._on_reset)
        for entity in (*self.timers, *self.services):  # rclpy's parameter services included
            entity.callback = timed(entity.callback, self._stats.all)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        """``~/reset`` (std_srvs/Trigger): restart the estimator now, applying any accepted
        parameter change; the reset is named in the next ``/diagnostics`` report."""
        response.message = reset_applying_changes(self.adapter)
        response.success = True
        self.get_logger().warning(response.message)
        return response

    def _callback(self, topic: str):  # noqa: ANN202 -- rclpy callback
        handle = self.adapter.on_raw
        is_imu = topic == TOPIC_IMU
        durations, imu_durations = self._stats.all, self._stats.imu

        def callback(raw: bytes) -> None:
            t0 = time.perf_counter()
            self.input_callbacks += 1
            if is_imu:
                self._last_imu_wall = time.monotonic()
            try:
                outputs = handle(topic, raw)
                if outputs:
                    self._emit(outputs)
            except Exception as exc:  # noqa: BLE001 -- never die on one message
                self.adapter.count_exception(topic)
                self.get_logger().error(f'{topic} callback failed: {exc!r}',
                                        throttle_duration_sec=5.0)
            seconds = time.perf_counter() - t0
            durations.add(seconds)
            if is_imu:
                imu_durations.add(seconds)
        return callback

    @property
    def subscriptions(self) -> Iterator[Subscription]:
        """The subscriptions an executor handles (rclpy's, without the inputs while
        :attr:`inputs_taken_by_spin`)."""
        if self.inputs_taken_by_spin:
            return (sub for sub in super().subscriptions if sub not in self._subs)
        return super().subscriptions

    def handle_ready_inputs(self) -> None:
        """Take every input message that has arrived (serialized) and run its callback, in
        arrival order over the inputs (the RMW's reception stamps; 0 where it gives none)."""
        batch = []
        for sub in self._subs:
            take, msg_type, callback = sub.handle.take_message, sub.msg_type, sub.callback
            while (taken := take(msg_type, True)) is not None:
                batch.append((taken[1]['received_timestamp'] or 0, callback, taken[0]))
        batch.sort(key=itemgetter(0))
        for _, callback, raw in batch:
            callback(raw)

    def _emit(self, outputs: list[Output]) -> None:
        """Publish ``outputs`` now, or queue them for the output step under :func:`spin`."""
        if self.output_steps:
            self._outputs += outputs
        else:
            self._publish(outputs)

    def publish_outputs(self) -> None:
        """The output step: publish the queued outputs in order (timed as one callback)."""
        if not self._outputs:
            return
        t0 = time.perf_counter()
        outputs, self._outputs = self._outputs, []
        try:
            self._publish(outputs)
        except Exception as exc:  # noqa: BLE001 -- as an input callback: never die on it
            self.adapter.count_exception('output step')
            self.get_logger().error(f'output step failed: {exc!r}', throttle_duration_sec=5.0)
        self._stats.all.add(time.perf_counter() - t0)

    def _publish(self, outputs: list[Output]) -> None:
        if not self.context.ok():  # stopping (a signal shut the context down): nowhere to send
            return
        for topic, msg in outputs:
            if topic == TOPIC_DIAGNOSTICS:
                self._stats.add_to(msg)
            self._pubs[topic].publish(serialize(msg))  # bytes: rclpy's publish_raw

    def _check_imu_stale(self) -> None:
        if time.monotonic() - self._last_imu_wall > STALE_AFTER_S:
            stamp_ns = self.get_clock().now().nanoseconds
            self._emit(self.adapter.stale_diagnostics(stamp_ns, 'no IMU data'))

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        return change_params(self.adapter, parameters, self.get_logger(),
                             self.get_fully_qualified_name())


NODE_HELP = """usage: slip-estimator-node [--ros-args --params-file FILE.yaml -r FROM:=TO ...]

The slip_estimator ROS 2 node (also `ros2 run slip_estimator slip_estimator_node`).
Inputs: /imu/data (sensor_msgs/Imu), /joint_states or /wheel/odometry (parameter
wheel_input). Outputs: /slip_estimator/odometry, /slip_estimator/slip,
/slip_estimator/slip_ratio, /diagnostics. Every parameter, with its unit and range:
`slip-estimator default-config`. A name that is not a parameter of the node refuses the
start unless -p allow_unknown_parameters:=true. Service ~/reset (std_srvs/srv/Trigger):
restart the estimator now, applying accepted runtime parameter changes."""


def main(args: list[str] | None = None) -> int:
    """Entry point of ``slip-estimator-node`` / ``ros2 run slip_estimator slip_estimator_node``.

    Returns 0 on a normal shutdown (Ctrl-C, external shutdown) and 2 when a parameter is
    invalid (the node refuses to start).
    """
    argv = sys.argv[1:] if args is None else list(args)
    if '-h' in argv or '--help' in argv:
        print(NODE_HELP)
        return 0
    files = params_files(argv)
    for path in files:  # rcl would raise a traceback on a file it cannot parse
        try:
            read_yaml(path)
        except ParameterError as exc:
            print(f'slip-estimator-node: {exc}', file=sys.stderr)
            return 2
    rclpy.init(args=args)
    node = None
    try:
        try:
            node = SlipEstimatorNode(param_files=files)
        except ParameterError as exc:
            # rcutils writes to stderr: the message names the parameter and its range.
            rclpy.logging.get_logger(NODE_NAME).fatal(f'invalid parameter, not starting: {exc}')
            return 2
        spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise  # a failure of the node itself: its traceback is the report
        # A stop signal shut rclpy's context down under a half-built node or a running
        # callback (SIGTERM: from rclpy's signal thread): the failed call is the stop.
    finally:
        bounded_teardown(node)
    return 0


if __name__ == '__main__':
    sys.exit(main())
