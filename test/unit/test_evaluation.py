"""Closed-form checks of slip_estimator.metrics, .truth and .evaluation (no ROS, no files)."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from slip_estimator.metrics import (
    confusion_matrix,
    evaluate_slip,
    evaluate_speed,
    evaluate_trajectory,
    match_nearest,
    path_length,
    wrap_deg,
)
from slip_estimator.truth import gnss_slip_truth, gnss_velocity_enu, slip_class, slip_ratio

NS = 1_000_000_000


# --- eq. 1 / eq. 30 ------------------------------------------------------------------------
@pytest.mark.parametrize('v, rw, s', [
    (1.0, 1.0, 0.0),       # rolling without slip
    (0.0, 0.0, 0.0),       # both zero
    (0.5, 1.0, 0.5),       # v < r w: s = 1 - v/(r w)
    (0.0, 1.0, 1.0),       # wheels spin, body stands: s = 1
    (1.0, 0.5, -0.5),      # v > r w: s = r w / v - 1 (skid)
    (1.0, 0.0, -1.0),      # locked wheels sliding: s = -1
    (0.8, 1.0, 0.2),       # on the low/medium boundary
    (-0.5, -1.0, 0.5),     # driving backwards mirrors the formula
    (-1.0, 1.0, 1.0),      # body opposite to the wheels: clipped to |s| = 1
])
def test_slip_ratio_eq1_cases(v: float, rw: float, s: float) -> None:
    assert float(slip_ratio(v, rw)) == pytest.approx(s, abs=1e-12)


def test_slip_ratio_nan_and_range() -> None:
    rng = np.random.default_rng(1)
    v, w = rng.uniform(-2, 2, 1000), rng.uniform(-2, 2, 1000)
    s = slip_ratio(v, w)
    assert np.all(np.abs(s) <= 1.0)
    assert np.isnan(slip_ratio(np.nan, 1.0))


def test_slip_class_bounds() -> None:
    s = np.array([0.0, 0.2, 0.2000001, 0.4, 0.41, 0.7, 0.71, -1.0, 0.1, np.nan])
    moving = np.array([True] * 8 + [False, True])
    assert slip_class(s, moving).tolist() == [1, 1, 2, 2, 3, 3, 4, 4, 0, -1]


# --- confusion matrix and slip scores ----------------------------------------------------------
def test_perfect_estimate_scores_100_percent() -> None:
    t = np.arange(50) * NS // 10
    s = np.concatenate([np.zeros(10), np.full(10, 0.1), np.full(10, 0.3), np.full(10, 0.5),
                        np.full(10, -0.9)])
    c = np.repeat(np.arange(5), 10)
    r = evaluate_slip(t, s, c, t, s, c)
    assert np.allclose(np.diag(r.percent), 100.0)
    assert r.balanced_accuracy == 1.0 and r.balanced_accuracy_strict == 1.0
    assert r.coverage == 1.0
    assert r.significant_precision == r.significant_recall == r.significant_f1 == 1.0
    assert r.slip_mae == 0.0 and r.n_matched == 50


def test_constructed_confusion_matrix_is_exact() -> None:
    truth = np.array([0, 0, 0, 1, 1, 1, 1, 2, 2, 4])
    est = np.array([0, 1, 0, 1, 1, 2, 0, 1, 2, 4])
    counts, pct = confusion_matrix(est, truth)
    expected = np.zeros((5, 5), int)
    for e, t in zip(est, truth):
        expected[e, t] += 1
    assert np.array_equal(counts, expected)
    # Column-normalised: rows estimated, columns truth (paper Table 2).
    assert pct[0, 0] == pytest.approx(200 / 3) and pct[1, 0] == pytest.approx(100 / 3)
    assert pct[1, 1] == 50.0 and pct[2, 1] == 25.0 and pct[0, 1] == 25.0
    assert np.all(np.isnan(pct[:, 3]))   # class 3 absent
    t = np.arange(10) * NS
    r = evaluate_slip(t, np.zeros(10), est, t, np.zeros(10), truth)
    # Balanced accuracy over the moving classes present (1, 2, 4): (0.5 + 0.5 + 1) / 3.
    assert r.balanced_accuracy == pytest.approx(2.0 / 3.0)
    # Significant slip (class >= 2) among moving samples: TP 2 (2->2, 4->4), FP 1 (1->2),
    # FN 1 (2->1).
    assert r.significant_precision == pytest.approx(2 / 3)
    assert r.significant_recall == pytest.approx(2 / 3)
    assert r.significant_f1 == pytest.approx(2 / 3)


def test_balanced_accuracy_ignores_absent_classes_and_coverage() -> None:
    truth = np.array([1, 1, 1, 1, 0, 0])
    est = np.array([1, 1, -1, 2, 0, 0])
    t = np.arange(6) * NS
    r = evaluate_slip(t, np.zeros(6), est, t, np.zeros(6), truth)
    assert r.balanced_accuracy == pytest.approx(2 / 3)       # only class 1 present
    assert r.balanced_accuracy_strict == pytest.approx(2 / 4)  # unknown counts as a miss
    assert r.coverage == pytest.approx(3 / 4)
    assert r.n_unknown[1] == 1


def test_missing_estimates_lower_coverage() -> None:
    t = np.arange(10) * NS
    r = evaluate_slip(t[:5], np.zeros(5), np.ones(5, int), t, np.zeros(10), np.ones(10, int))
    assert r.coverage == 0.5 and r.n_matched == 5


@pytest.mark.parametrize('stated_over_true, z2', [(1.0, 1.0), (0.5, 4.0), (2.0, 0.25)])
def test_slip_sigma_honesty_is_the_mean_z2_of_the_published_sigma(stated_over_true, z2) -> None:
    """Errors drawn with sigma 0.05 and published as ``stated_over_true`` times that: the mean
    z^2 is 1 / ratio^2 (the slip's NEES) and the share within 3 sigma that of a Gaussian at
    3 * ratio; samples at rest, with no sigma or sigma 0, are left out; without sigmas NaN."""
    rng = np.random.default_rng(5)
    n = 20000
    t = np.arange(n) * NS // 10
    truth = np.full(n, 0.3)
    est = truth + rng.normal(0.0, 0.05, n)
    cls = np.full(n, 2)
    cls[:100] = 0                                  # at rest: not scored
    std = np.full(n, 0.05 * stated_over_true)
    std[100:110], std[110:120] = np.nan, 0.0       # no sigma published
    r = evaluate_slip(t, est, cls, t, truth, cls, est_slip_std=std)
    assert r.slip_z2_mean == pytest.approx(z2, rel=0.05)
    assert r.slip_within_3sigma == pytest.approx(math.erf(3.0 * stated_over_true / math.sqrt(2.0)),
                                                 abs=0.01)
    assert math.isnan(evaluate_slip(t, est, cls, t, truth, cls).slip_z2_mean)
    assert r.slip_within_2sigma == pytest.approx(math.erf(2.0 * stated_over_true / math.sqrt(2.0)),
                                                 abs=0.01)


def test_the_share_truly_medium_of_confident_medium_probabilities() -> None:
    """Of the moving samples published with P(medium+) >= 0.8 (six: 0.8, 0.9 twice, 1.0 and
    two at rest left out), the share whose truth is medium or worse: 3 of 4; none: NaN."""
    t = np.arange(8) * NS // 10
    truth_cls = np.array([2, 3, 1, 2, 1, 2, 0, 0])
    p = np.array([0.8, 0.9, 0.9, 1.0, 0.79, 0.1, 0.95, 0.99])
    r = evaluate_slip(t, np.zeros(8), truth_cls, t, np.zeros(8), truth_cls, est_p_medium=p)
    assert r.n_p_medium_confident == 4 and r.p_medium_precision == pytest.approx(0.75)
    none = evaluate_slip(t, np.zeros(8), truth_cls, t, np.zeros(8), truth_cls,
                         est_p_medium=np.zeros(8))
    assert none.n_p_medium_confident == 0 and math.isnan(none.p_medium_precision)


def test_match_nearest_tolerance() -> None:
    ref = np.array([0, 100, 200])
    assert match_nearest(np.array([-10, 49, 51, 260, 1000]), ref, 50).tolist() == [0, 0, 1, -1,
                                                                                   -1]


# --- speed and trajectory -------------------------------------------------------------------------
def test_speed_rmse_against_interpolated_truth() -> None:
    tt = np.arange(0, 11) * NS
    vt = np.linspace(0, 1, 11)
    te = np.arange(0, 101) * NS // 10
    r = evaluate_speed(te, np.linspace(0, 1, 101) + 0.1, tt, vt, max_gap_s=1.0)
    assert r.n == 101 and r.rmse == pytest.approx(0.1) and r.mean == pytest.approx(0.1)


def test_drift_on_synthetic_trajectory() -> None:
    # Truth: a 100 m straight line east at 1 m/s; estimate: 2 deg heading error.
    t = np.arange(0, 101) * NS
    truth = np.column_stack([np.arange(101.0), np.zeros(101), np.zeros(101)])
    a = math.radians(2.0)
    est = np.column_stack([np.arange(101.0) * math.cos(a), np.arange(101.0) * math.sin(a),
                           np.zeros(101)])
    r = evaluate_trajectory(t, est, t, truth, np.full(101, a), np.zeros(101), 'odometry')
    final = 2 * 100 * math.sin(a / 2)
    assert r.distance_m == pytest.approx(100.0)
    assert r.final_error_m == pytest.approx(final)
    assert r.drift_percent == pytest.approx(final)   # 100 m travelled
    assert r.heading_rms_deg == pytest.approx(2.0) and r.heading_final_deg == pytest.approx(2.0)
    assert r.rms_error_m == pytest.approx(final * math.sqrt(np.mean((np.arange(101) / 100) ** 2)))


def test_origin_alignment_and_wrap() -> None:
    t = np.arange(0, 11) * NS
    truth = np.column_stack([np.arange(11.0) + 5.0, np.full(11, 3.0), np.zeros(11)])
    est = np.column_stack([np.arange(11.0), np.zeros(11), np.zeros(11)])
    r = evaluate_trajectory(t, est, t, truth)
    assert r.final_error_m == pytest.approx(0.0, abs=1e-12)
    assert wrap_deg(350.0) == pytest.approx(-10.0) and wrap_deg(-190.0) == pytest.approx(170.0)


def test_path_length_smoothing_removes_noise() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(0, 100, 0.1)
    p = np.column_stack([0.5 * t, np.zeros_like(t), np.zeros_like(t)])
    noisy = p + rng.normal(0, 0.02, p.shape)
    assert path_length(p) == pytest.approx(0.5 * t[-1])
    assert path_length(noisy) > 1.1 * path_length(p)
    assert path_length(noisy, t, 1.0) == pytest.approx(path_length(p), rel=0.02)


# --- GNSS truth (eq. 30) -------------------------------------------------------------------
def test_gnss_truth_recovers_known_slip_with_gaps() -> None:
    # 10 Hz GNSS with gaps, rover at 0.6 m/s north-east, wheels at 0.8 m/s: s = 0.25.
    tg = np.arange(0.0, 30.0, 0.1)
    tg = np.delete(tg, [50, 51, 120, 121, 122])
    d = np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0])
    p = 0.6 * tg[:, None] * d
    tw = (np.arange(1.0, 29.0, 0.1) * NS).astype(np.int64)
    g = gnss_slip_truth(tw, np.full(len(tw), 0.8), tg, p)
    ok = np.isfinite(g.s)
    assert ok.mean() > 0.95
    assert np.allclose(g.s[ok], 0.25, atol=1e-9)
    assert np.all(g.slip_class[ok] == 2)
    assert g.projection == 'course'
    # Projection on a body x axis 90 deg off gives zero forward speed -> s = 1.
    x_axis = np.tile([-d[1], d[0], 0.0], (len(tw), 1))
    g2 = gnss_slip_truth(tw, np.full(len(tw), 0.8), tg, p, x_axis_enu=x_axis)
    assert g2.projection == 'estimate'
    assert np.allclose(g2.s[np.isfinite(g2.s)], 1.0)


def test_gnss_velocity_needs_fixes_on_both_sides() -> None:
    tg = np.array([0.0, 0.1, 0.2, 0.3, 2.0, 2.1, 2.2, 2.3])
    p = np.column_stack([tg, np.zeros(8), np.zeros(8)])
    v = gnss_velocity_enu(tg, p, np.array([0.15, 1.0, 2.15]), window_s=0.5)
    assert v[0, 0] == pytest.approx(1.0) and np.isnan(v[1, 0]) and v[2, 0] == pytest.approx(1.0)


def test_gnss_truth_at_rest_is_class_none() -> None:
    tg = np.arange(0.0, 10.0, 0.1)
    rng = np.random.default_rng(3)
    p = rng.normal(0, 0.003, (len(tg), 3))
    tw = (np.arange(1.0, 9.0, 0.1) * NS).astype(np.int64)
    g = gnss_slip_truth(tw, np.zeros(len(tw)), tg, p)
    assert np.all(g.slip_class == 0) and np.all(g.s == 0.0)


def test_evaluation_core_is_ros_free() -> None:
    code = ('import sys, slip_estimator.evaluation; '
            'bad = [m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "rosbags", "matplotlib", "h5py") or m.endswith("_msgs")]; '
            'print(bad); sys.exit(1 if bad else 0)')
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=False)
    assert res.returncode == 0, res.stdout + res.stderr


def test_load_run_and_evaluate_round_trip(tmp_path) -> None:
    """Bags with simulation truth -> load_run -> evaluate_run: a perfect estimate scores 100 %."""
    pytest.importorskip('rclpy')
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry

    from slip_estimator.bagio import BagWriter
    from slip_estimator.evaluation import evaluate_run
    from slip_estimator.report import evaluate_main, load_run

    n = 60
    t_ns = (np.arange(n) * NS // 10 + 1_700_000_000 * NS).astype(np.int64)
    s = np.where(np.arange(n) < 10, 0.0, np.where(np.arange(n) < 40, 0.1, 0.5))
    cls = slip_class(s, np.arange(n) >= 10)
    v = np.where(np.arange(n) < 10, 0.0, 0.5)

    def stamp(msg, ns):
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(ns // NS), int(ns % NS)
        return msg

    def odom(ns, x, vx):
        m = stamp(Odometry(), ns)
        m.header.frame_id, m.child_frame_id = 'odom', 'base_link'
        m.pose.pose.position.x = float(x)
        m.pose.pose.orientation.w = 1.0
        m.twist.twist.linear.x = float(vx)
        return m

    x = np.cumsum(v) * 0.1
    with BagWriter(tmp_path / 'in') as bag_in, BagWriter(tmp_path / 'out') as bag_out:
        for k in range(n):
            tv = stamp(Vector3Stamped(), t_ns[k])
            tv.vector.x, tv.vector.z = float(s[k]), float(cls[k])
            bag_in.write('/truth/slip', tv, t_ns[k])
            bag_in.write('/truth/odometry', odom(t_ns[k], x[k], v[k]), t_ns[k])
            bag_out.write('/slip_estimator/odometry', odom(t_ns[k], x[k], v[k]), t_ns[k])
            vals = {'slip_ratio': f'{s[k]:.6g}', 'slip_class': str(cls[k]),
                    'slip_ratio_std': '0.01', 'body_speed': f'{v[k]:.6g}',
                    'wheel_speed': f'{v[k]:.6g}'}
            st = DiagnosticStatus(name='slip', message='x',
                                  values=[KeyValue(key=a, value=b) for a, b in vals.items()])
            bag_out.write('/slip_estimator/slip', stamp(DiagnosticArray(status=[st]), t_ns[k]),
                          t_ns[k])
    run = load_run(tmp_path / 'in', tmp_path / 'out', progress=False)
    ev = evaluate_run(run)
    assert ev.truth_source == 'simulation'
    assert ev.slip.balanced_accuracy == 1.0 and ev.slip.coverage == 1.0
    assert ev.speed.rmse == pytest.approx(0.0, abs=1e-9)
    assert ev.trajectory.final_error_m == pytest.approx(0.0, abs=1e-9)
    out_json = tmp_path / 'm.json'
    assert evaluate_main(['--input', str(tmp_path / 'in'), '--estimate', str(tmp_path / 'out'),
                          '--report-dir', str(tmp_path / 'rep'), '--json', str(out_json),
                          '--quiet']) == 0
    assert (tmp_path / 'rep' / 'confusion_matrix.png').exists()
    import json
    assert json.loads(out_json.read_text())['slip']['balanced_accuracy'] == 1.0


def test_the_false_alarm_share_is_low_truth_read_medium_or_worse() -> None:
    """``counts[est, truth]``: of 10 truth-low samples, 2 read medium and 1 extreme; at rest
    and truth-medium samples do not count; without truth-low samples NaN."""
    from slip_estimator.accuracy import false_alarm_share

    counts = np.zeros((5, 5), dtype=int)
    counts[1, 1], counts[2, 1], counts[4, 1] = 7, 2, 1
    counts[3, 0], counts[2, 2] = 5, 9
    assert false_alarm_share(counts) == pytest.approx(0.3)
    counts[:, 1] = 0
    assert math.isnan(false_alarm_share(counts))


def test_wheels_gyro_track_integrates_the_rim_speed_along_the_estimated_heading() -> None:
    """A quarter circle at 1 m/s turning pi/20 rad/s (radius 20/pi m) from (1, 2): the
    baseline ends at (1 + R, 2 + R) whatever positions the fused odometry published."""
    from slip_estimator.evaluation import RunData, wheels_gyro_track

    t_s = np.arange(0.0, 10.0 + 1e-9, 0.01)
    t_ns = (t_s * 1e9).astype(np.int64)
    yaw = np.pi / 20.0 * t_s
    q = np.column_stack([np.cos(yaw / 2), 0 * t_s, 0 * t_s, np.sin(yaw / 2)])
    p_odom = np.tile([1.0, 2.0, 0.0], (len(t_s), 1)) + 50.0 * (t_s > 0)[:, None]
    nan = np.full(len(t_s), np.nan)
    run = RunData(t_ns, nan, nan, np.ones(len(t_s), int), nan, np.ones(len(t_s)), t_ns,
                  p_odom, q)
    stamps, p = wheels_gyro_track(run)
    radius = 20.0 / np.pi
    assert stamps[-1] == t_ns[-1]
    assert p[-1] == pytest.approx([1.0 + radius, 2.0 + radius, 0.0], abs=1e-3)
