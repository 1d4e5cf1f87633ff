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

Bad input is counted, never raised: each input topic has a ``received`` counter and
``rejected`` counters per reason (see :mod:`slip_estimator.ros.convert` for the reasons, plus
``non_monotonic`` for IMU stamps that do not increase and ``core_error`` for samples the core
raised on). No outgoing message carries NaN/Inf: odometry and ``/diagnostics`` are checked and
dropped (and counted) if they have any; the slip messages cannot have any by construction
(:func:`~slip_estimator.ros.publish.slip_to_diagnostic_array` formats non-finite values as
'unknown', :func:`~slip_estimator.ros.publish.slip_to_vector3` is built only from a known,
finite slip), so they skip the check unless the frame name itself reads as a number.

Parameter changes (:meth:`SlipEstimatorAdapter.request_params`) are validated by the caller and
take effect at the next reset: an IMU stamp jumping back by more than ``RESET_JUMP_BACK_S``
(bag loop, simulator restart, a sensor clock reset) or an explicit
:meth:`SlipEstimatorAdapter.reset` (the node's ``~/reset`` service). The reason of every reset
(the jump with both stamps, or the request) is named in the message of the next
``/diagnostics`` report, at least WARN, and ``clock_jumps_back`` counts the jumps. Resetting a
running INS mid-drive would lose its state, so a change never triggers a reset by itself.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from slip_estimator.core import frames
from slip_estimator.core.estimator import SlipEstimator
from slip_estimator.core.params import Params
from slip_estimator.core.types import Health, ImuSample, SlipEstimate, WheelSample
from slip_estimator.ros import convert, finite, publish

TOPIC_IMU = '/imu/data'
TOPIC_JOINT_STATES = '/joint_states'
TOPIC_WHEEL_ODOMETRY = '/wheel/odometry'
TOPIC_ODOMETRY = '/slip_estimator/odometry'
TOPIC_SLIP = '/slip_estimator/slip'
TOPIC_SLIP_RATIO = '/slip_estimator/slip_ratio'
TOPIC_DIAGNOSTICS = '/diagnostics'

OUTPUT_TYPES: dict[str, type] = {
    TOPIC_ODOMETRY: Odometry,
    TOPIC_SLIP: DiagnosticArray,
    TOPIC_SLIP_RATIO: Vector3Stamped,
    TOPIC_DIAGNOSTICS: DiagnosticArray,
}

REASON_NON_MONOTONIC = 'non_monotonic'
REASON_CORE_ERROR = 'core_error'

RESET_JUMP_BACK_S = 1.0
"""An IMU stamp this far behind the previous one restarts the estimator (bag loop, sim reset);
smaller steps back are rejected as ``non_monotonic``."""

IMU_GAP_FACTOR = 1.5
"""An IMU stamp step longer than this many nominal periods counts as a gap (lost samples)."""

Output = tuple[str, Any]
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
        self.received: Counter[str] = Counter()
        self.rejected: Counter[tuple[str, str]] = Counter()
        self.published: Counter[str] = Counter()
        self.dropped_non_finite: Counter[str] = Counter()
        self.callback_exceptions: Counter[str] = Counter()
        self.resets = 0
        self.clock_jumps_back = 0
        self.imu_stamp_gaps = 0
        self._reset_notes: list[str] = []
        self._configure(params)

    # --- configuration ------------------------------------------------------------------------
    def _configure(self, params: Params) -> None:
        self.params = params
        self._core = self._factory(params)
        self._C_imu_b = frames.imu_to_body_dcm(params.imu_to_base_rpy)
        self._joint_rates = convert.JointRatesFromPositions(
            params.max_wheel_speed_mps / params.wheel_radius)
        self._frame_is_finite_text = finite.text_is_finite(params.base_frame)
        self._odom_period_ns = (0 if params.odometry_rate_hz == 0.0
                                else round(1e9 / params.odometry_rate_hz))
        self._diag_period_ns = round(params.diagnostics_period_s * 1e9)
        self._last_imu_ns: int | None = None
        self._imu_dt_ns: float | None = None
        self._next_odom_ns: int | None = None
        self._next_diag_ns: int | None = None
        self._last_diag_ns: int | None = None
        self._received_at_last_diag: Counter[str] = Counter()
        self._rejected_at_last_diag = 0
        self._dropped_at_last_diag = 0

    @property
    def wheel_topic(self) -> str:
        """The wheel input topic selected by ``wheel_input``."""
        return (TOPIC_JOINT_STATES if self.params.wheel_input == 'joint_states'
                else TOPIC_WHEEL_ODOMETRY)

    @property
    def input_types(self) -> dict[str, type]:
        """Input topics to subscribe to (IMU first) and their message classes."""
        wheel_type = JointState if self.wheel_topic == TOPIC_JOINT_STATES else Odometry
        return {TOPIC_IMU: Imu, self.wheel_topic: wheel_type}

    @property
    def input_sources(self) -> dict[str, str]:
        """The topic each input is read from (``imu_topic`` and the wheel topic parameter),
        by the input topic name the adapter takes it under."""
        p = self.params
        source = {TOPIC_IMU: p.imu_topic, TOPIC_JOINT_STATES: p.joint_states_topic,
                  TOPIC_WHEEL_ODOMETRY: p.wheel_odometry_topic}
        return {topic: source[topic] for topic in self.input_types}

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
        self.resets += 1
        self._configure(params)
        self._reset_notes.append(f'{reason}: estimator reset{applied}')

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
        p = self.params
        if topic == TOPIC_IMU:
            return self.on_imu_sample(convert.imu_from_cdr(raw, self._C_imu_b))
        if topic == TOPIC_JOINT_STATES:
            return self._on_wheel(topic, convert.wheel_from_cdr_joint_state(
                raw, p.wheel_joint_names, p.wheel_radius, max_speed_mps=p.max_wheel_speed_mps,
                from_positions=self._joint_rates))
        if topic == TOPIC_WHEEL_ODOMETRY:
            return self._on_wheel(topic, convert.wheel_from_cdr_odometry(
                raw, p.track_width, max_speed_mps=p.max_wheel_speed_mps))
        return []

    def imu_samples(self, raws: list[bytes]) -> list[tuple[int, ImuSample | str]]:
        """(stamp ns, sample or rejection reason) of serialized IMU messages, decoded in one
        batch with the mounting in force now (the replay's IMU path; a later parameter change
        does not reach samples decoded before it)."""
        return convert.imu_samples_from_cdr(raws, self._C_imu_b)

    def on_imu(self, msg: Imu) -> list[Output]:
        """Process one ``sensor_msgs/Imu`` message object (:meth:`on_imu_sample`)."""
        return self.on_imu_sample(convert.imu_from_msg(msg, self._C_imu_b))

    def on_imu_sample(self, sample: ImuSample | str) -> list[Output]:
        """Process one IMU sample (or the reason its message was rejected): INS step, due
        slip, odometry and diagnostics."""
        self.received[TOPIC_IMU] += 1
        if isinstance(sample, str):
            self.rejected[TOPIC_IMU, sample] += 1
            return []
        stamp_ns = sample.stamp_ns
        if self._last_imu_ns is not None and stamp_ns <= self._last_imu_ns:
            if self._last_imu_ns - stamp_ns > RESET_JUMP_BACK_S * 1e9:
                self.clock_jumps_back += 1
                self.reset(f'IMU clock jumped back by {(self._last_imu_ns - stamp_ns) * 1e-9:.1f}'
                           f' s (stamp {self._last_imu_ns * 1e-9:.3f} -> {stamp_ns * 1e-9:.3f})')
            else:
                self.rejected[TOPIC_IMU, REASON_NON_MONOTONIC] += 1
                return []
        self._track_imu_period(stamp_ns)
        self._last_imu_ns = stamp_ns

        # Most IMU samples produce nothing: the output steps run only when due.
        out: list[Output] = []
        try:
            estimates = self._core.add_imu(sample)
            if estimates:
                out = self._slip_outputs(estimates)
        except Exception:  # noqa: BLE001 -- a core failure must not take the node down
            self.rejected[TOPIC_IMU, REASON_CORE_ERROR] += 1
        checked: list[Output] = []
        if self._next_odom_ns is None or stamp_ns >= self._next_odom_ns:
            checked += self._odometry_output(stamp_ns)
        if self._next_diag_ns is None or stamp_ns >= self._next_diag_ns:
            checked += self._diagnostics_output(stamp_ns)
        if out:  # counted after the diagnostics are built, like the checked outputs
            out = self._pass_slip(out)
        return out + self._guard(checked) if checked else out

    def on_joint_states(self, msg: JointState) -> list[Output]:
        """Process one ``sensor_msgs/JointState`` (wheel angular velocities)."""
        p = self.params
        sample = convert.wheel_from_joint_state(msg, p.wheel_joint_names, p.wheel_radius,
                                                max_speed_mps=p.max_wheel_speed_mps,
                                                from_positions=self._joint_rates)
        return self._on_wheel(TOPIC_JOINT_STATES, sample)

    def on_wheel_odometry(self, msg: Odometry) -> list[Output]:
        """Process one wheel-odometry ``nav_msgs/Odometry``."""
        p = self.params
        sample = convert.wheel_from_odometry(msg, p.track_width,
                                             max_speed_mps=p.max_wheel_speed_mps)
        return self._on_wheel(TOPIC_WHEEL_ODOMETRY, sample)

    def _on_wheel(self, topic: str, sample: WheelSample | str) -> list[Output]:
        self.received[topic] += 1
        if isinstance(sample, str):
            self.rejected[topic, sample] += 1
            return []
        try:
            estimates = self._core.add_wheel(sample)
        except Exception:  # noqa: BLE001
            self.rejected[topic, REASON_CORE_ERROR] += 1
            return []
        return self.slip_messages(estimates)

    def slip_messages(self, estimates: list[SlipEstimate]) -> list[Output]:
        """The slip messages of ``estimates``, counted as published (checked first only where
        the frame name could read as a non-finite number)."""
        return self._pass_slip(self._slip_outputs(estimates))

    def count_exception(self, topic: str) -> None:
        """Count an exception the caller caught while handling a message of ``topic``."""
        self.callback_exceptions[topic] += 1

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
            return self._guard(out)
        for topic, _ in out:
            self.published[topic] += 1
        return out

    def _odometry_output(self, stamp_ns: int) -> list[Output]:
        if self._next_odom_ns is not None and stamp_ns < self._next_odom_ns:
            return []
        try:
            odo = self._core.odometry()
        except Exception:  # noqa: BLE001
            self.rejected[TOPIC_IMU, REASON_CORE_ERROR] += 1
            return []
        if odo is None:
            return []
        # Next due time on a fixed grid (no drift), re-anchored after a gap in the data.
        nxt = (self._next_odom_ns or stamp_ns) + self._odom_period_ns
        self._next_odom_ns = nxt if nxt > stamp_ns else stamp_ns + self._odom_period_ns
        p = self.params
        return [(TOPIC_ODOMETRY, publish.odometry_to_msg(odo, p.odom_frame, p.base_frame))]

    def _diagnostics_output(self, stamp_ns: int) -> list[Output]:
        if self._next_diag_ns is not None and stamp_ns < self._next_diag_ns:
            return []
        nxt = (self._next_diag_ns or stamp_ns) + self._diag_period_ns
        self._next_diag_ns = nxt if nxt > stamp_ns else stamp_ns + self._diag_period_ns
        return [(TOPIC_DIAGNOSTICS, self._health_message(stamp_ns))]

    def _health_message(self, stamp_ns: int) -> DiagnosticArray:
        try:
            health = self._core.health()
        except Exception as exc:  # noqa: BLE001
            health = Health(level=2, message=f'estimator health unavailable: {exc!r}',
                            values={})
        values = self.counter_values()
        # Input rates over the last period of data time.
        if self._last_diag_ns is not None and stamp_ns > self._last_diag_ns:
            window_s = (stamp_ns - self._last_diag_ns) * 1e-9
            for topic in self.input_types:
                n = self.received[topic] - self._received_at_last_diag[topic]
                values[f'{topic} rate_hz'] = n / window_s
        level, message = health.level, health.message
        new_rejects = sum(self.rejected.values()) - self._rejected_at_last_diag
        new_drops = sum(self.dropped_non_finite.values()) - self._dropped_at_last_diag
        if new_rejects or new_drops:
            level = max(level, 1)
            message = (f'{message}; {new_rejects} input message(s) rejected, {new_drops} '
                       f'non-finite output(s) dropped since the last report')
        if self._reset_notes:
            level = max(level, 1)
            message = '; '.join([message, *self._reset_notes])
            self._reset_notes = []
        self._last_diag_ns = stamp_ns
        self._received_at_last_diag = Counter(self.received)
        self._rejected_at_last_diag = sum(self.rejected.values())
        self._dropped_at_last_diag = sum(self.dropped_non_finite.values())
        return publish.health_to_diagnostic_array(
            Health(level=level, message=message, values=health.values), stamp_ns,
            self.params.base_frame, values)

    def stale_diagnostics(self, stamp_ns: int, message: str = 'no IMU data') -> list[Output]:
        """A STALE ``/diagnostics`` report (the live node's wall-clock watchdog)."""
        msg = publish.stale_diagnostic_array(message, stamp_ns, self.params.base_frame,
                                             self.counter_values())
        return self._guard([(TOPIC_DIAGNOSTICS, msg)])

    def counter_values(self) -> dict[str, Any]:
        """The node's own counters as flat diagnostic values."""
        values: dict[str, Any] = {}
        for topic in self.input_types:
            values[f'{topic} received'] = self.received[topic]
        for (topic, reason), n in sorted(self.rejected.items()):
            values[f'{topic} rejected {reason}'] = n
        values['/imu/data stamp_gaps'] = self.imu_stamp_gaps
        for topic in OUTPUT_TYPES:
            values[f'{topic} published'] = self.published[topic]
        for topic, n in sorted(self.dropped_non_finite.items()):
            values[f'{topic} dropped_non_finite'] = n
        for topic, n in sorted(self.callback_exceptions.items()):
            values[f'{topic} callback_exceptions'] = n
        values['node_resets'] = self.resets  # 'resets' is the core's own counter
        values['clock_jumps_back'] = self.clock_jumps_back
        values['parameter_change_pending'] = self._pending is not None
        return values

    def _guard(self, out: list[Output]) -> list[Output]:
        """Drop (and count) messages with NaN/Inf; count the rest as published."""
        kept = []
        for topic, msg in out:
            if finite.message_is_finite(msg):
                self.published[topic] += 1
                kept.append((topic, msg))
            else:
                self.dropped_non_finite[topic] += 1
        return kept

    def _track_imu_period(self, stamp_ns: int) -> None:
        """Count stamp steps much longer than the nominal period (an EMA of the steps)."""
        if self._last_imu_ns is None:
            return
        dt = float(stamp_ns - self._last_imu_ns)
        if self._imu_dt_ns is None:
            self._imu_dt_ns = dt
        elif dt > IMU_GAP_FACTOR * self._imu_dt_ns:
            self.imu_stamp_gaps += 1
        else:
            self._imu_dt_ns += 0.01 * (dt - self._imu_dt_ns)
