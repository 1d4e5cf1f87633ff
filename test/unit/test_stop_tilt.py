"""The tilt closure at stops (``validation.stop_tilt``) on closed-form synthetic series."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from slip_estimator.core.frames import rpy_to_dcm
from slip_estimator.validation.stop_tilt import (LEVEL_S, StopTiltRecorder, stop_closures,
                                                 summarize)

DT_S = 0.01


def _series(segments: list[tuple[float, bool]]) -> tuple[np.ndarray, np.ndarray]:
    """Stamps and stationarity from (duration s, stationary) rows at 100 Hz."""
    still = np.concatenate([np.full(round(d / DT_S), s) for d, s in segments])
    return np.arange(len(still)) * DT_S, still


def test_a_tilt_step_at_the_first_zupt_is_the_stops_closure() -> None:
    """2 s of rest, 20 s driving (the tilt wanders), a 3-s stop whose first ZUPT moves roll
    by +0.2 deg and pitch by -0.3 deg and whose next 0.5 s level pitch by another -0.1 deg:
    first = (+0.2, -0.3), level (1 s after) = (+0.2, -0.4), drive 20 s."""
    t, still = _series([(2.0, True), (20.0, False), (3.0, True)])
    i = int(np.flatnonzero(t >= 22.0 - 1e-9)[0])
    roll = np.full(len(t), 0.05)
    pitch = 0.01 * np.clip(t - 2.0, 0.0, 19.0)          # 0.19 deg of wander while driving
    roll[i:] += 0.2
    pitch[i:] -= 0.3
    pitch[i + 1:] -= 0.1 * np.clip((t[i + 1:] - t[i]) / 0.5, 0.0, 1.0)
    v_fwd = np.where(t < 22.0, 0.03, 0.0)                # 0.03 m/s left at the stop
    stops = stop_closures(t, np.radians(roll), np.radians(pitch), still, v_fwd)
    assert len(stops) == 1
    s = stops[0]
    assert s['t_s'] == pytest.approx(22.0)
    assert s['drive_s'] == pytest.approx(20.0)
    assert (s['first_roll_deg'], s['first_pitch_deg']) == pytest.approx((0.2, -0.3))
    assert (s['level_roll_deg'], s['level_pitch_deg']) == pytest.approx((0.2, -0.4))
    assert s['stop_s'] == pytest.approx(3.0 - DT_S)
    assert s['v_stop_mps'] == pytest.approx(0.03)


def test_flicker_is_not_a_stop_and_a_short_stop_has_no_level_figure() -> None:
    """A 0.3-s motion inside a stop is the detector flickering (no second stop); a stop
    shorter than LEVEL_S + margin keeps its first-ZUPT figure and no levelled one; the drive
    after a stop is counted from the stop's end."""
    t, still = _series([(1.0, True), (10.0, False), (2.0, True), (0.3, False), (2.0, True),
                        (8.0, False), (LEVEL_S, True), (6.0, False), (2.0, True)])
    pitch = np.zeros(len(t))
    stops = stop_closures(t, pitch, pitch, still)
    assert [round(s['t_s'], 2) for s in stops] == [11.0, 23.3, 30.3]
    assert [round(s['drive_s'], 2) for s in stops] == [10.0, 8.0, 6.0]
    assert math.isnan(stops[1]['level_pitch_deg']) and stops[1]['first_pitch_deg'] == 0.0
    assert stops[0]['level_pitch_deg'] == 0.0


def test_summary_medians_and_the_rate_per_root_second() -> None:
    """Tilts of 5, 10 and 15 deg (3-4-5 triangles) after 25-s drives: median 10, 90th
    percentile 14, rate median 10 / 5 = 2 deg/sqrt(s); no levelled figure -> NaN."""
    stops = [{'drive_s': 25.0, 'first_roll_deg': 3.0 * k, 'first_pitch_deg': -4.0 * k,
              'level_roll_deg': math.nan, 'level_pitch_deg': math.nan,
              'v_stop_mps': -0.02 * k} for k in (1, 2, 3)]
    s = summarize(stops)
    assert s['n'] == 3 and s['drive_s'] == 25.0
    assert s['first_tilt_median_deg'] == pytest.approx(10.0)
    assert s['first_tilt_p90_deg'] == pytest.approx(14.0)
    assert s['first_pitch_median_deg'] == pytest.approx(8.0)
    assert s['first_tilt_rate_deg_rts'] == pytest.approx(2.0)
    assert math.isnan(s['level_tilt_median_deg']) and s['level_n'] == 0
    assert s['v_stop_median_mps'] == pytest.approx(0.04)
    assert s['gain_median_deg_per_mps'] == pytest.approx(200.0)  # 4 deg per 0.02 m/s


def test_the_recorder_reads_roll_and_pitch_of_the_filter_attitude() -> None:
    """C_b_n built from roll 3 deg, pitch -7 deg, heading north, moving 0.5 m/s north: the
    recorder returns the roll and pitch (rad) and the forward speed 0.5 cos(pitch); nothing
    is recorded before alignment."""
    est = SimpleNamespace(aligned=False, updater=SimpleNamespace(is_stationary=True),
                          filter=SimpleNamespace(state=SimpleNamespace(
                              C_b_n=rpy_to_dcm(math.radians(3.0), math.radians(-7.0), 0.0),
                              v_eb_n=np.array([0.5, 0.0, 0.0]))))
    rec = StopTiltRecorder(est)
    rec(SimpleNamespace(stamp_ns=1_000_000_000))
    est.aligned = True
    rec(SimpleNamespace(stamp_ns=2_000_000_000))
    assert len(rec.rows) == 1
    t, roll, pitch, still, v_fwd = rec.rows[0]
    assert (t, math.degrees(roll), math.degrees(pitch), still) == pytest.approx(
        (2.0, 3.0, -7.0, True))
    assert v_fwd == pytest.approx(0.5 * math.cos(math.radians(-7.0)))  # 0.5 m/s north


def test_the_stop_and_go_drive_has_s5t1s_shape() -> None:
    """Nine legs of 10-16 s at 0.4-0.7 m/s, each followed by a 2-3.5 s stop, between rests."""
    from slip_estimator.sim.drives import stop_and_go_scenario

    segs = stop_and_go_scenario(3).segments
    legs, stops = segs[1:-1:2], segs[2:-1:2]
    assert len(legs) == len(stops) == 9
    assert segs[0].speed_mps == segs[-1].speed_mps == 0.0
    assert all(10.0 <= s.duration_s <= 16.0 and 0.4 <= s.speed_mps <= 0.7 for s in legs)
    assert all(2.0 <= s.duration_s <= 3.5 and s.speed_mps == 0.0 for s in stops)


def test_the_section_judges_each_reading_error_against_its_real_log() -> None:
    """Mean reading errors 0.09 (real), 0.08 (x0.89: reproduced) and 0.02 (x0.22: smaller)."""
    from slip_estimator.validation.sections_evidence import stop_tilt_section

    stop = {'drive_s': 50.0, 'first_roll_deg': 0.03, 'first_pitch_deg': 0.04,
            'level_roll_deg': 0.03, 'level_pitch_deg': 0.04, 'v_stop_mps': 0.02}
    closures = {'real test17run': [stop], 'sim Pathfinder IMU, test17run shape': [stop]}
    readings = {'real test17run': [0.09],
                'sim Pathfinder IMU, test17run shape': [0.07, 0.09],
                'sim Pathfinder IMU motion-bound, test17run shape': [0.01, 0.03]}
    table = {line.split(' | ')[0][2:]: line.split(' | ')
             for line in stop_tilt_section(closures, readings)
             if line.startswith('| sim') and len(line.split(' | ')) == 5}
    bound = table['sim Pathfinder IMU motion-bound, test17run shape']
    assert bound[2] == '0.020' and bound[3] == '0.22' and 'smaller' in bound[4]
    plain = table['sim Pathfinder IMU, test17run shape']
    assert plain[2] == '0.080' and plain[3] == '0.89' and 'reproduced' in plain[4]
