"""What a new user hits outside replay: evaluate validity following the data, one-line errors
of evaluate and import-pathfinder, progress lines in logs, the import's params-file notes."""
from __future__ import annotations

import io
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import one_line_exit_2, synthetic_messages, write_synthetic_bag

from slip_estimator.evaluation import RunData, evaluate_run
from slip_estimator.progress import Progress
from slip_estimator.pathfinder.cli import import_main
from slip_estimator.report import evaluate_main, summary_text


S_NS = 1_000_000_000


def _run(est_t_s, truth_t_s, truth_class) -> RunData:
    est_t = (np.asarray(est_t_s) * S_NS).astype(np.int64)
    truth_t = (np.asarray(truth_t_s) * S_NS).astype(np.int64)
    n = len(est_t)
    cls = np.asarray(truth_class)
    return RunData(est_t, np.full(n, 0.1), np.full(n, 0.01), np.ones(n, int), np.ones(n),
                   np.ones(n), truth_slip_stamp_ns=truth_t,
                   truth_slip=np.where(cls >= 2, 0.3, 0.1), truth_slip_class=cls)


def test_zero_matched_samples_is_not_valid():
    run = _run(np.arange(10) * 0.1, 100.0 + np.arange(10) * 0.1, np.ones(10, int))
    ev = evaluate_run(run)
    assert ev.valid['slip'] is False
    text = summary_text(ev)
    assert 'slip=NO' in text and 'slip figures are NOT valid' in text


def test_small_classes_named():
    t = np.arange(200) * 0.1
    cls = np.ones(200, int)
    cls[:3] = 3  # three samples of 'high'
    ev = evaluate_run(_run(t, t, cls))
    assert ev.valid['slip'] is True
    assert any('rests on few samples' in n and 'high 3' in n for n in ev.notes), ev.notes
    assert not any('low' in n for n in ev.notes if 'rests on' in n)


def test_evaluate_bad_inputs_one_line(tmp_path, capsys):
    bag = str(write_synthetic_bag(tmp_path / 'in', synthetic_messages(1.0, 1.0)))
    tail = ['--report-dir', str(tmp_path / 'rep'), '--quiet']
    (tmp_path / 'empty').mkdir()
    bad = tmp_path / 'p.yaml'
    bad.write_text('slip_estimator: [\n')
    for argv, words in (
            (['--input', str(tmp_path / 'x'), '--estimate', bag], ('no such file',)),
            (['--input', bag, '--estimate', str(tmp_path / 'empty')], ('empty folder',)),
            (['--input', bag, '--estimate', bag], ('no slip estimates',)),
            (['--input', bag, '--estimate', bag, '--params', str(bad)],
             ('p.yaml', 'YAML syntax error'))):
        one_line_exit_2(evaluate_main, capsys, argv + tail, *words)


def test_import_pathfinder_bad_inputs_one_line(tmp_path, capsys):
    out = str(tmp_path / 'out')
    one_line_exit_2(import_main, capsys, [str(tmp_path / 'none.mat'), '--output', out],
                    'none.mat', 'no such file')
    txt = tmp_path / 'log.txt'
    txt.write_text('not a mat file\n')
    one_line_exit_2(import_main, capsys, [str(txt), '--output', out], 'log.txt',
                    'not a Pathfinder .mat log')


def test_progress_plain_lines_when_not_a_tty(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, 'stderr', err)
    line = Progress(every_s=0.0)  # due at once
    assert not line.tty
    line.show('reading: 10 messages')
    line.done('reading: 20 messages read')
    assert '\r' not in err.getvalue()
    assert err.getvalue().splitlines() == ['reading: 10 messages', 'reading: 20 messages read']


MAT = Path(__file__).resolve().parents[2] / '..' / 'shared' / 'data' / 'pathfinder' / \
    'test17run.mat'


@pytest.mark.skipif(not MAT.exists(), reason='real Pathfinder log not found at ../shared')
def test_import_params_file_says_what_it_took_and_why(tmp_path, capsys):
    params = tmp_path / 't17.yaml'
    assert import_main([str(MAT), '--output', str(tmp_path / 'bag'), '--params-out',
                        str(params)]) == 0
    text = params.read_text()
    head = [line for line in text.splitlines() if line.startswith('#')]
    joined = ' '.join(h[2:] for h in head)
    assert 'Wheel stamps lag the IMU by 0.1' in joined
    assert 'wheel_latency_s stays 0' in joined and '--measured-lag' in joined
    assert 'datasheet, not the values measured at rest' in joined
    from slip_estimator.paramfile import load_params
    assert load_params(params).wheel_latency_s == 0.0
    params2 = tmp_path / 't17b.yaml'
    assert import_main([str(MAT), '--output', str(tmp_path / 'bag2'), '--params-out',
                        str(params2), '--measured-lag', '--measured-noise']) == 0
    p2 = load_params(params2)
    assert 0.1 < p2.wheel_latency_s < 0.25
    assert 'wheel_latency_s = 0.1' in params2.read_text()
