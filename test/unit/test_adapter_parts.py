"""The node adapter's parts (slip_estimator/ros/): the IMU stamp judge, the output schedule on
data time, the counters' NaN guard and the /diagnostics report, each on hand-made cases."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped

from slip_estimator.core.params import Params
from slip_estimator.core.types import Health
from slip_estimator.ros.counters import NodeCounters
from slip_estimator.ros.data_time import ImuStamps, OutputSchedule, StampStep
from slip_estimator.ros.health_report import HealthReport

MS = 1_000_000


def test_imu_stamps_judge_steps_gaps_and_jumps():
    stamps = ImuStamps()
    steps = [stamps.step(t * MS) for t in (1000, 1004, 1008, 1014)]
    # 4 ms nominal; a 6 ms step is 1.5 periods: not yet a gap (longer than 1.5 is)
    assert steps == [StampStep.NEXT] * 4
    assert stamps.step(1030 * MS) is StampStep.GAP
    assert stamps.step(1030 * MS) is StampStep.BEHIND  # equal: not later
    assert stamps.step(30 * MS) is StampStep.BEHIND  # exactly 1 s back: not more than 1 s
    assert stamps.step(29 * MS) is StampStep.JUMPED_BACK
    assert stamps.last_ns == 1030 * MS  # a stamp behind changes nothing


def test_output_schedule_keeps_a_grid_and_reanchors_after_a_gap():
    schedule = OutputSchedule(Params(odometry_rate_hz=10.0, diagnostics_period_s=1.0))
    sent = []
    for t_ms in (0, 50, 100, 130, 199, 200, 750, 800, 850):
        if schedule.odometry_due(t_ms * MS):
            schedule.odometry_sent(t_ms * MS)
            sent.append(t_ms)
    assert sent == [0, 100, 200, 750, 850]  # 100 ms grid; after the gap from 750 on
    assert [schedule.diagnostics_due(t * MS) for t in (0, 999, 1000, 3500, 4000, 4500)] == [
        True, False, True, True, False, True]


def test_counters_drop_and_count_a_non_finite_message():
    counters = NodeCounters()
    good, bad = Vector3Stamped(), Vector3Stamped()
    bad.vector.x = float('nan')
    assert counters.pass_finite([('/a', good), ('/a', bad)]) == [('/a', good)]
    assert counters.published == {'/a': 1} and counters.dropped_non_finite == {'/a': 1}


def test_health_report_says_what_changed_since_the_last_report():
    report, counters = HealthReport(), NodeCounters()
    ok = Health(level=0, message='ok', values={})

    def status(stamp_s: float):
        msg = report.message(round(stamp_s * 1e9), ok, counters, ['/imu/data'], 'base_link',
                             False)
        assert isinstance(msg, DiagnosticArray)
        return msg.status[0], {kv.key: kv.value for kv in msg.status[0].values}

    counters.received['/imu/data'] = 100
    first, values = status(1.0)
    assert first.level == DiagnosticStatus.OK and first.message == 'ok'
    assert '/imu/data rate_hz' not in values
    counters.received['/imu/data'] = 350
    counters.rejected['/imu/data', 'non_finite'] = 2
    second, values = status(2.0)
    assert float(values['/imu/data rate_hz']) == 250.0
    assert second.level == DiagnosticStatus.WARN
    assert '2 input message(s) rejected, 0 non-finite' in second.message
    assert status(3.0)[0].level == DiagnosticStatus.OK  # nothing new since
    report.restart('IMU clock jumped back: estimator reset')
    after, values = status(4.0)
    assert after.level == DiagnosticStatus.WARN
    assert after.message.endswith('IMU clock jumped back: estimator reset')
    assert '/imu/data rate_hz' not in values  # the rates start again after a reset
