"""The thin rclpy node: declare parameters, subscribe, hand messages to the adapter, publish.

All logic lives in :class:`slip_estimator.ros.adapter.SlipEstimatorAdapter` (shared with the bag
replay); this module only deals with rclpy.

QoS
---
Inputs use the sensor-data profile (BEST_EFFORT, VOLATILE, KEEP_LAST) with a deeper queue:
depth 500 for ``/imu/data`` (2 s at 250 Hz) and 100 for the wheel topic. A best-effort
subscription matches both best-effort publishers (the usual IMU driver setting) and reliable
ones (bag players, ``ros2 topic pub``); a reliable subscription would silently not connect to a
best-effort driver. The deep queue absorbs executor stalls (GIL, garbage collection, a burst
from a bag player) so that no sample is overwritten before the callback runs; lost samples
would show up in ``/diagnostics`` as the ``/imu/data stamp_gaps`` counter and as a difference
between the publisher's count and ``/imu/data received``.
Outputs are RELIABLE, VOLATILE, KEEP_LAST: depth 10 for odometry and diagnostics, 100 for the
slip topics (one message per wheel sample, consumers must not miss class changes).

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

Parameters
----------
Declared from :class:`slip_estimator.core.params.Params` (names, defaults, descriptions with
unit and range) with dynamic typing, so that ``wheel_radius:=1`` (an integer) is accepted and
every value is validated once, by Params. An invalid start-up value logs the parameter, value
and allowed range and ``main`` returns 2. Runtime changes are validated the same way (invalid
ones are rejected with that message); valid ones take effect at the next estimator reset: a
sensor clock jump back, or a call of the ``~/reset`` service (``std_srvs/srv/Trigger``, e.g.
``ros2 service call /slip_estimator/reset std_srvs/srv/Trigger``), which restarts the estimator
at once. ``wheel_input`` cannot change at runtime: it decides the subscriptions.

Parameter files: a file with no section for the node's name is reported at ERROR level with
the sections it has (its values do not apply); a name that is not a parameter of the node
(misspelled) makes the node refuse to start (exit 2) unless ``allow_unknown_parameters`` is
true.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from operator import itemgetter
from typing import Any

import rclpy
from diagnostic_msgs.msg import KeyValue
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from std_srvs.srv import Trigger

from slip_estimator.core.params import (
    RENAMED_PARAMETERS,
    ParameterError,
    Params,
    describe,
    renamed_in,
)
from slip_estimator.paramfile import (
    NODE_ONLY_PARAMETERS,
    PARAMETER_NAMES,
    coerce_param_value,
    node_sections,
    params_files,
    read_yaml,
    unknown_parameters,
)
from slip_estimator.ros.cdr_out import serialize
from slip_estimator.ros.spin import CallbackDurations, bounded_teardown, spin, timed
from slip_estimator.ros.qos import IMU_QUEUE_DEPTH, WHEEL_QUEUE_DEPTH, input_qos, output_qos
from slip_estimator.ros.adapter import SlipEstimatorAdapter
from slip_estimator.ros.topics import (
    OUTPUT_TYPES,
    TOPIC_DIAGNOSTICS,
    TOPIC_IMU,
    TOPIC_SLIP,
    TOPIC_SLIP_RATIO,
    Output,
)

NODE_NAME = 'slip_estimator'
INPUT_BATCH = 'input_batch_period_s'
MAX_INPUT_BATCH_PERIOD_S = 0.1
STALE_AFTER_S = 1.0
"""The watchdog reports STALE 'no IMU data' when no IMU message arrived for this long (wall)."""
CALLBACK_WINDOW = 15000
"""IMU callback durations kept for the ``callback_*_ms`` diagnostics (60 s at 250 Hz)."""
ALL_CALLBACKS_WINDOW = 18000
"""Durations of every callback kept for the ``all_callbacks_*_ms`` diagnostics (about 60 s at
250 Hz IMU, 10 Hz wheels and their output steps)."""


_DEFAULTS = Params()
ALLOW_UNKNOWN = 'allow_unknown_parameters'


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
        self._check_parameter_sources(param_files or [])
        defaults = self._defaults_with_old_names()
        for name in PARAMETER_NAMES:
            self.declare_parameter(
                name, defaults[name],
                ParameterDescriptor(description=describe(name), dynamic_typing=True))
        params = Params.from_dict({name: coerce_param_value(
            name, self.get_parameter(name).value) for name in PARAMETER_NAMES})
        self.adapter = SlipEstimatorAdapter(params)
        self.get_logger().info('effective parameters: ' + ', '.join(
            f'{k}={v!r}' for k, v in params.to_dict().items()))

        self._imu_durations = CallbackDurations(CALLBACK_WINDOW)
        self._all_durations = CallbackDurations(ALL_CALLBACKS_WINDOW)
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
            entity.callback = timed(entity.callback, self._all_durations)

    def _check_parameter_sources(self, param_files: list[str]) -> None:
        """Log an ERROR for a params file with no section for this node (a misspelled node name
        would run on every default); raise :class:`ParameterError` for a parameter that is not
        one of the node's (misspelled) unless ``allow_unknown_parameters`` is true."""
        fqn = self.get_fully_qualified_name()
        for path in param_files:
            doc = read_yaml(path)
            if not node_sections(doc, fqn):
                sections = ', '.join(map(str, doc)) if isinstance(doc, dict) else 'none'
                self.get_logger().error(
                    f'parameter file {path} has NO section for this node ({fqn}); sections in '
                    f'the file: {sections or "none"}. None of its values apply: expected '
                    f'"{self.get_name()}:" or "/**:" at the top level.')
        allow = self.declare_parameter(
            ALLOW_UNKNOWN, NODE_ONLY_PARAMETERS[ALLOW_UNKNOWN], ParameterDescriptor(
                description='start even when a parameter file or -p sets a name that is not '
                            'a parameter of this node (otherwise the node refuses to start)',
                read_only=True)).value
        unknown = unknown_parameters(self._parameter_overrides)
        if unknown and not allow:
            raise ParameterError(
                f'unknown parameter(s) {", ".join(unknown)} (misspelled? every parameter: '
                f'slip-estimator default-config); set {ALLOW_UNKNOWN}:=true to start anyway')
        if unknown:
            self.get_logger().error(f'ignoring unknown parameter(s) {", ".join(unknown)} '
                                    f'({ALLOW_UNKNOWN} is true)')
        period = self.declare_parameter(
            INPUT_BATCH, NODE_ONLY_PARAMETERS[INPUT_BATCH], ParameterDescriptor(
                description='s, 0 to 0.1: the node sleeps this long after handling what was '
                            'ready, then handles what arrived meanwhile in one go (less CPU, '
                            'up to this much more output latency; 0: wake for every message)',
                read_only=True, dynamic_typing=True)).value
        if (isinstance(period, bool) or not isinstance(period, (int, float))
                or not 0.0 <= period <= MAX_INPUT_BATCH_PERIOD_S):
            raise ParameterError(f'{INPUT_BATCH} = {period!r}: must be a number of seconds '
                                 f'from 0 to {MAX_INPUT_BATCH_PERIOD_S:g}')
        self.input_batch_period_s = float(period)

    def _defaults_with_old_names(self) -> dict[str, Any]:
        """The schema's defaults, a value set under a parameter's old name
        (:data:`RENAMED_PARAMETERS`) in place of its new name's default (the new name, when set
        too, overrides it as any default); a one-line warning per old name."""
        overrides = self._parameter_overrides
        for warning in renamed_in(overrides):
            self.get_logger().warning(warning)
        defaults = _DEFAULTS.to_dict()
        for old, new in RENAMED_PARAMETERS.items():
            if old in overrides:
                defaults[new] = overrides[old].value
        return defaults

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        """``~/reset`` (std_srvs/Trigger): restart the estimator now, applying any accepted
        parameter change; the reset is named in the next ``/diagnostics`` report."""
        pending = self.adapter.pending_params
        changed = ({k: v for k, v in pending.to_dict().items()
                    if getattr(self.adapter.params, k) != v} if pending is not None else {})
        self.adapter.reset('reset requested on ~/reset')
        response.success = True
        response.message = ('estimator reset' + (f'; parameter change applied: {changed}'
                                                 if changed else ''))
        self.get_logger().warning(response.message)
        return response

    def _callback(self, topic: str):  # noqa: ANN202 -- rclpy callback
        handle = self.adapter.on_raw
        is_imu = topic == TOPIC_IMU
        durations = self._all_durations

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
                self._imu_durations.add(seconds)
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
        self._all_durations.add(time.perf_counter() - t0)

    def _publish(self, outputs: list[Output]) -> None:
        if not self.context.ok():  # stopping (a signal shut the context down): nowhere to send
            return
        for topic, msg in outputs:
            if topic == TOPIC_DIAGNOSTICS:
                self._add_callback_stats(msg)
            self._pubs[topic].publish(serialize(msg))  # bytes: rclpy's publish_raw

    def _add_callback_stats(self, msg: Any) -> None:
        """Append the callback duration percentiles to every status of a DiagnosticArray."""
        keys = ('p50_ms', 'p99_ms', 'max_ms', 'window')
        values = [KeyValue(key=f'callback_{k}', value=v)
                  for k, v in zip(keys, self._imu_durations.summary_ms())]
        values += [KeyValue(key=f'all_callbacks_{k}', value=v)
                   for k, v in zip(keys, self._all_durations.summary_ms())]
        for status in msg.status:
            status.values = list(status.values) + values

    def _check_imu_stale(self) -> None:
        if time.monotonic() - self._last_imu_wall > STALE_AFTER_S:
            stamp_ns = self.get_clock().now().nanoseconds
            self._emit(self.adapter.stale_diagnostics(stamp_ns, 'no IMU data'))

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        ours = {p.name: coerce_param_value(p.name, p.value) for p in parameters
                if p.name in PARAMETER_NAMES}
        if not ours:
            return SetParametersResult(successful=True)
        current = self.adapter.pending_params or self.adapter.params
        if 'wheel_input' in ours and ours['wheel_input'] != current.wheel_input:
            return SetParametersResult(
                successful=False, reason='wheel_input cannot change at runtime; restart the node')
        try:
            new = current.replace(**ours)
        except ParameterError as exc:
            self.get_logger().error(f'rejected parameter change: {exc}')
            return SetParametersResult(successful=False, reason=str(exc))
        self.adapter.request_params(new)
        self.get_logger().info(
            f'accepted parameter change {ours}; effective at the next estimator reset (call '
            f'the {self.get_fully_qualified_name()}/reset service, std_srvs/srv/Trigger, to '
            'apply it now)')
        return SetParametersResult(successful=True)


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
