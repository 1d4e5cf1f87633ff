"""The node's logic without rclpy: messages in, (topic, message) pairs out.

:class:`SlipEstimatorAdapter` is shared by the live node (:mod:`slip_estimator.ros.node`, which
feeds messages in arrival order) and the bag replay (:mod:`slip_estimator.replay`, which feeds
them in header-stamp order). Everything time-driven here runs on DATA time (message stamps),
never on a wall clock, so a replay is deterministic and equals what the node would have done:

* odometry is published at ``odometry_rate_hz`` of IMU stamps (0 = every IMU sample), once the
  core has a solution;
* ``/diagnostics`` is published on the first IMU sample and then every ``diagnostics_period_s``
  of IMU stamps. The live node adds a wall-clock STALE report of its own
  (:meth:`SlipEstimatorAdapter.stale_diagnostics`).

The adapter owns its parts and calls them: :class:`~slip_estimator.ros.inputs.InputDecoder`
(messages or bytes to records with the parameters in force),
:class:`~slip_estimator.ros.data_time.ImuStamps` and
:class:`~slip_estimator.ros.data_time.OutputSchedule` (the IMU stamps' order, jumps and gaps;
when odometry and diagnostics are due), :class:`~slip_estimator.ros.counters.NodeCounters` (the
counts and the NaN guard) and :class:`~slip_estimator.ros.health_report.HealthReport` (the
``/diagnostics`` message). Topic names and message classes: :mod:`slip_estimator.ros.topics`.

Bad input is counted, never raised: each input topic has a ``received`` counter and
``rejected`` counters per reason (see :mod:`slip_estimator.ros.convert` for the reasons, plus
``non_monotonic`` for IMU stamps that do not increase and ``core_error`` for samples the core
raised on). No outgoing message carries NaN/Inf: odometry and ``/diagnostics`` are checked and
dropped (and counted) if they have any; the slip messages cannot have any by construction
(:func:`~slip_estimator.ros.publish.slip_to_diagnostic_array` formats non-finite values as
'unknown', :func:`~slip_estimator.ros.publish.slip_to_vector3` is built only from a known,
finite slip), so they skip the check unless the frame name itself reads as a number.

Parameter changes (:meth:`SlipEstimatorAdapter.request_params`) are validated by the caller and
take effect at the next reset: an IMU stamp jumping back by more than
:data:`~slip_estimator.ros.data_time.RESET_JUMP_BACK_S`
(bag loop, simulator restart, a sensor clock reset) or an explicit
:meth:`SlipEstimatorAdapter.reset` (the node's ``~/reset`` service). The reason of every reset
(the jump with both stamps, or the request) is named in the message of the next
``/diagnostics`` report, at least WARN, and ``clock_jumps_back`` counts the jumps. Resetting a
running INS mid-drive would lose its state, so a change never triggers a reset by itself.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core.estimator import SlipEstimator
from slip_estimator.core.params import Params
from slip_estimator.core.types import Health, ImuSample, SlipEstimate, WheelSample
from slip_estimator.ros import finite, publish, topics
from slip_estimator.ros.counters import NodeCounters
from slip_estimator.ros.data_time import ImuStamps, OutputSchedule, StampStep
from slip_estimator.ros.health_report import HealthReport
from slip_estimator.ros.inputs import InputDecoder
from slip_estimator.ros.topics import (
    TOPIC_DIAGNOSTICS,
    TOPIC_IMU,
    TOPIC_JOINT_STATES,
    TOPIC_ODOMETRY,
    TOPIC_SLIP,
    TOPIC_SLIP_RATIO,
    TOPIC_WHEEL_ODOMETRY,
    Output,
)

REASON_NON_MONOTONIC = 'non_monotonic'
REASON_CORE_ERROR = 'core_error'

EstimatorFactory = Callable[[Params], SlipEstimator]


class SlipEstimatorAdapter:
    """Converts messages, runs the core :class:`SlipEstimator`, returns messages to publish.

    Parameters
    ----------
    params : validated parameters.
    estimator_factory : builds the core from Params (the real :class:`SlipEstimator` unless a
        test substitutes one).
    """

    def __init__(self, params: Params,
                 estimator_factory: EstimatorFactory = SlipEstimator) -> None:
        self._factory = estimator_factory
        self._pending: Params | None = None
        self.counters = NodeCounters()
        """Kept across resets."""
        self._report = HealthReport()
        self._configure(params)

    # --- configuration ------------------------------------------------------------------------
    def _configure(self, params: Params) -> None:
        self.params = params
        self._core = self._factory(params)
        self._decode = InputDecoder(params)
        self._stamps = ImuStamps()
        self._schedule = OutputSchedule(params)
        self._frame_is_finite_text = finite.text_is_finite(params.base_frame)

    @property
    def wheel_topic(self) -> str:
        """The wheel input topic selected by ``wheel_input``."""
        return topics.wheel_topic(self.params)

    @property
    def input_types(self) -> dict[str, type]:
        """Input topics to subscribe to (IMU first) and their message classes."""
        return topics.input_types(self.params)

    @property
    def input_sources(self) -> dict[str, str]:
        """The topic each input is read from, by the input topic name the adapter takes it
        under (:func:`slip_estimator.ros.topics.input_sources`)."""
        return topics.input_sources(self.params)

    @property
    def pending_params(self) -> Params | None:
        """Accepted parameters waiting for the next reset, if any."""
        return self._pending

    def request_params(self, params: Params) -> None:
        """Store validated parameters; they take effect at the next :meth:`reset`."""
        self._pending = None if params == self.params else params

    def reset(self, reason: str = 'reset requested') -> None:
        """Restart the estimator (with pending parameters, if any); counters are kept. The
        reason is named in the next ``/diagnostics`` report."""
        params = self._pending or self.params
        applied = ' (pending parameter change applied)' if self._pending is not None else ''
        self._pending = None
        self.counters.resets += 1
        self._configure(params)
        self._report.restart(f'{reason}: estimator reset{applied}')

    # --- inputs ---------------------------------------------------------------------------------
    def on_message(self, topic: str, msg: Any) -> list[Output]:
        """Dispatch an input message by topic (replay); unknown topics give nothing."""
        if topic == TOPIC_IMU:
            return self.on_imu(msg)
        if topic == TOPIC_JOINT_STATES:
            return self.on_joint_states(msg)
        if topic == TOPIC_WHEEL_ODOMETRY:
            return self.on_wheel_odometry(msg)
        return []

    def on_raw(self, topic: str, raw: bytes | memoryview) -> list[Output]:
        """Dispatch a serialized input message (CDR) by topic: the live node's raw
        subscriptions and the replay's wheel topics; unknown topics give nothing."""
        if topic == TOPIC_IMU:
            return self.on_imu_sample(self._decode.imu_raw(raw))
        if topic == TOPIC_JOINT_STATES:
            return self._on_wheel(topic, self._decode.joint_states_raw(raw))
        if topic == TOPIC_WHEEL_ODOMETRY:
            return self._on_wheel(topic, self._decode.wheel_odometry_raw(raw))
        return []

    def imu_samples(self, raws: list[bytes]) -> list[tuple[int, ImuSample | str]]:
        """(stamp ns, sample or rejection reason) of serialized IMU messages, decoded in one
        batch with the mounting in force now (the replay's IMU path; a later parameter change
        does not reach samples decoded before it)."""
        return self._decode.imu_batch(raws)

    def on_imu(self, msg: Imu) -> list[Output]:
        """Process one ``sensor_msgs/Imu`` message object (:meth:`on_imu_sample`)."""
        return self.on_imu_sample(self._decode.imu(msg))

    def on_imu_sample(self, sample: ImuSample | str) -> list[Output]:
        """Process one IMU sample (or the reason its message was rejected): INS step, due
        slip, odometry and diagnostics."""
        counters = self.counters
        counters.received[TOPIC_IMU] += 1
        if isinstance(sample, str):
            counters.rejected[TOPIC_IMU, sample] += 1
            return []
        stamp_ns = sample.stamp_ns
        step = self._stamps.step(stamp_ns)
        if step is StampStep.BEHIND:
            counters.rejected[TOPIC_IMU, REASON_NON_MONOTONIC] += 1
            return []
        if step is StampStep.JUMPED_BACK:
            last_ns = self._stamps.last_ns or 0
            counters.clock_jumps_back += 1
            self.reset(f'IMU clock jumped back by {(last_ns - stamp_ns) * 1e-9:.1f}'
                       f' s (stamp {last_ns * 1e-9:.3f} -> {stamp_ns * 1e-9:.3f})')
            self._stamps.step(stamp_ns)  # the new run's first stamp: NEXT
        elif step is StampStep.GAP:
            counters.imu_stamp_gaps += 1

        # Most IMU samples produce nothing: the output steps run only when due.
        out: list[Output] = []
        try:
            estimates = self._core.add_imu(sample)
            if estimates:
                out = self._slip_outputs(estimates)
        except Exception:  # noqa: BLE001 -- a core failure must not take the node down
            counters.rejected[TOPIC_IMU, REASON_CORE_ERROR] += 1
        checked: list[Output] = []
        if self._schedule.odometry_due(stamp_ns):
            checked += self._odometry_output(stamp_ns)
        if self._schedule.diagnostics_due(stamp_ns):
            checked.append((TOPIC_DIAGNOSTICS, self._health_message(stamp_ns)))
        if out:  # counted after the diagnostics are built, like the checked outputs
            out = self._pass_slip(out)
        return out + counters.pass_finite(checked) if checked else out

    def on_joint_states(self, msg: JointState) -> list[Output]:
        """Process one ``sensor_msgs/JointState`` (wheel angular velocities)."""
        return self._on_wheel(TOPIC_JOINT_STATES, self._decode.joint_states(msg))

    def on_wheel_odometry(self, msg: Odometry) -> list[Output]:
        """Process one wheel-odometry ``nav_msgs/Odometry``."""
        return self._on_wheel(TOPIC_WHEEL_ODOMETRY, self._decode.wheel_odometry(msg))

    def _on_wheel(self, topic: str, sample: WheelSample | str) -> list[Output]:
        self.counters.received[topic] += 1
        if isinstance(sample, str):
            self.counters.rejected[topic, sample] += 1
            return []
        try:
            estimates = self._core.add_wheel(sample)
        except Exception:  # noqa: BLE001
            self.counters.rejected[topic, REASON_CORE_ERROR] += 1
            return []
        return self.slip_messages(estimates)

    def slip_messages(self, estimates: list[SlipEstimate]) -> list[Output]:
        """The slip messages of ``estimates``, counted as published (checked first only where
        the frame name could read as a non-finite number)."""
        return self._pass_slip(self._slip_outputs(estimates))

    def count_exception(self, topic: str) -> None:
        """Count an exception the caller caught while handling a message of ``topic``."""
        self.counters.callback_exceptions[topic] += 1

    # --- outputs --------------------------------------------------------------------------------
    def _slip_outputs(self, estimates: list[SlipEstimate]) -> list[Output]:
        out: list[Output] = []
        frame = self.params.base_frame
        for est in estimates:
            out.append((TOPIC_SLIP, publish.slip_to_diagnostic_array(est, frame)))
            vec = publish.slip_to_vector3(est, frame)
            if vec is not None:
                out.append((TOPIC_SLIP_RATIO, vec))
        return out

    def _pass_slip(self, out: list[Output]) -> list[Output]:
        """Slip messages are finite by construction (see the module docstring): counted as
        published without the check, unless the frame name parses as a non-finite number."""
        if not self._frame_is_finite_text:
            return self.counters.pass_finite(out)
        return self.counters.count_published(out)

    def _odometry_output(self, stamp_ns: int) -> list[Output]:
        try:
            odo = self._core.odometry()
        except Exception:  # noqa: BLE001
            self.counters.rejected[TOPIC_IMU, REASON_CORE_ERROR] += 1
            return []
        if odo is None:
            return []
        self._schedule.odometry_sent(stamp_ns)
        p = self.params
        return [(TOPIC_ODOMETRY, publish.odometry_to_msg(odo, p.odom_frame, p.base_frame))]

    def _health_message(self, stamp_ns: int) -> DiagnosticArray:
        try:
            health = self._core.health()
        except Exception as exc:  # noqa: BLE001
            health = Health(level=2, message=f'estimator health unavailable: {exc!r}',
                            values={})
        return self._report.message(stamp_ns, health, self.counters, self.input_types,
                                    self.params.base_frame, self._pending is not None)

    def stale_diagnostics(self, stamp_ns: int, message: str = 'no IMU data') -> list[Output]:
        """A STALE ``/diagnostics`` report (the live node's wall-clock watchdog)."""
        msg = publish.stale_diagnostic_array(message, stamp_ns, self.params.base_frame,
                                             self.counter_values())
        return self.counters.pass_finite([(TOPIC_DIAGNOSTICS, msg)])

    def counter_values(self) -> dict[str, Any]:
        """The node's own counters as flat diagnostic values."""
        return self.counters.values(self.input_types, self._pending is not None)
