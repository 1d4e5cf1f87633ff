"""Smoke test of ``slip-estimator bench``: every section runs with tiny durations and prints its
table; the JSON has the figures. No timing assertions (this machine's speed is not a property
of the code); only structure and sanity (counts, received <= sent, positive rates)."""
from __future__ import annotations

import json

from slip_estimator.bench.cli import SECTIONS, bench_main

TINY = ['--repeats', '1', '--core-duration-s', '12', '--replay-duration-s', '12',
        '--replay-repeats', '1', '--pathfinder', '', '--live-duration-s', '4',
        '--live-imu-rates', '250,1000',
        '--memory-duration-s', '24',
        '--memory-sample-s', '10', '--scaling-rates', '50,250', '--scaling-rate-duration-s',
        '11', '--scaling-lengths', '11,22']


def test_bench_all_sections(tmp_path, capsys):
    out = tmp_path / 'bench.json'
    assert bench_main(TINY + ['--json', str(out)]) == 0
    text = capsys.readouterr().out
    for header in ('== machine', '== core throughput', '== offline replay',
                   '== live node over DDS', '== memory', '== scaling: core cost vs IMU rate',
                   '== scaling: core cost vs log length'):
        assert header in text, header
    assert 'FAILED' not in text
    report = json.loads(out.read_text())
    assert set(SECTIONS) <= set(report)
    assert report['machine']['cores'] >= 1

    core = report['core']['rows']
    assert [r['label'].split()[0] for r in core] == ['default', 'reference']
    assert all(r['imu_steps'] > 2000 and r['steps_per_s'] > 0 and r['aligned']
               and r['cpu_us_per_step'] > 0 for r in core)

    (sim,) = report['replay']['rows']
    assert sim['messages_in'] > 0 and sim['messages_out'] > 0
    assert min(sim['read_s'], sim['estimation_s'], sim['write_s']) > 0
    assert sim['read_s'] + sim['estimation_s'] + sim['write_s'] <= sim['wall_s']
    assert sim['estimation_realtime_ratio'] > sim['realtime_ratio'] > 0
    assert report['replay']['pathfinder_skipped']

    (proc,) = report['replay']['process']  # whole process, no --baseline
    assert proc['label'] == 'this tree' and proc['wall_s'] > 0 and proc['cpu_s'] > 0

    runs = report['live']['runs']
    assert [(r['label'], r['imu_rate_hz']) for r in runs] == [('this tree', 250.0),
                                                                ('this tree', 1000.0)]
    for live, sent in zip(runs, (1000, 4000)):
        assert 0 < live['imu_received'] <= live['imu_sent'] == sent
        assert 0 <= live['wheel_received'] <= live['wheel_sent']
        assert live['callback_p50_ms'] <= live['callback_p99_ms'] <= live['callback_max_ms']
        assert (live['all_callbacks_p50_ms'] <= live['all_callbacks_p99_ms']
                <= live['all_callbacks_max_ms'])
        assert live['all_callbacks_window'] > live['callback_window']
        assert live['end_to_end']['n'] > 0 and live['end_to_end']['p50_ms'] > 0
        assert live['node_cpu_percent_of_one_core'] >= 0

    mem = report['memory']
    assert mem['imu_steps'] > 5000 and len(mem['samples']) >= 3
    assert mem['peak_rss_processing_mb'] >= mem['rss_before_processing_mb'] > 0
    assert mem['verdict']

    scaling = report['scaling']
    assert [r['rate_hz'] for r in scaling['by_rate']] == [50.0, 250.0]
    assert [r['length_s'] for r in scaling['by_length']] == [11.0, 22.0]
    assert all(r['us_per_step'] > 0 for r in scaling['by_rate'] + scaling['by_length'])


def test_bench_only_and_unknown_section(capsys):
    assert bench_main(['--only', 'core', '--repeats', '1', '--core-duration-s', '11']) == 0
    text = capsys.readouterr().out
    assert '== core throughput' in text and '== replay' not in text
    assert bench_main(['--only', 'nope']) == 2
