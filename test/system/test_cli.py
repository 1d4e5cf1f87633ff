"""The command-line shells: help, unknown commands, the node's --help (no ROS started)."""
from __future__ import annotations

from helpers import one_line_exit_2

from slip_estimator import cli
from slip_estimator.ros import node


def test_help_lists_every_command(capsys):
    assert cli.main(['--help']) == 0
    out = capsys.readouterr().out
    assert out.startswith('usage: slip-estimator COMMAND')
    for name in cli.COMMANDS:
        assert f'  {name} ' in out


def test_unknown_command_is_one_line_and_exit_2(capsys):
    assert cli.main(['replai']) == 2
    captured = capsys.readouterr()
    assert captured.out == ''
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "unknown command 'replai'" in lines[0]


def test_no_command_prints_usage_and_fails(capsys):
    assert cli.main([]) == 2
    assert 'usage:' in capsys.readouterr().out


def test_node_help_does_not_start_the_node(capsys):
    assert node.main(['--help']) == 0
    assert capsys.readouterr().out.startswith('usage: slip-estimator-node')


def test_accuracy_scores_a_drive_and_says_what_it_skipped(tmp_path, capsys):
    """One drive of the matrix through the core: the fixed short drive keeps its level (the
    test fails when the slip model loses it) and its slip alarms at rest stay few (7 samples
    before the hold's speed variance was carried into the stops, 2 now: the ratio's last
    samples before the wheels stop), and a missing real log is one line, not a traceback.
    With ``--bound`` the drive's reading bound is printed and written."""
    import json

    out_json = tmp_path / 'acc.json'
    assert cli.main(['accuracy', '--families', 'short', '--seeds', '1', '--jobs', '1',
                     '--data-dir', str(tmp_path), '--json', str(out_json), '--bound']) == 0
    out = capsys.readouterr().out
    assert 'real-log cases skipped' in out and out.count('short ') == 1
    m = json.loads(out_json.read_text())
    assert [r['seed'] for r in m['sim']] == [0] and not m['real']
    assert m['sim'][0]['balanced_accuracy'] >= 0.9
    assert m['sim'][0]['alarms_at_rest'] <= 3 and 'at-rest alarms' in out
    # Beside the detection figures: the false alarms (truth low read medium or worse: 0.20
    # before the slip resolution rule, 0.16 now)
    # and the published sigma's and P(medium+)'s calibration (measured 1.00 and 0.97).
    assert 'false alarms' in out and 'calibration: truth within 2 sigma' in out
    assert m['sim'][0]['false_alarm'] <= 0.18 and m['sim'][0]['slip_within_2sigma'] >= 0.9
    assert m['sim'][0]['p_medium_precision'] >= 0.9
    bound = m['sim'][0]['bound_recall']
    assert len(bound) == 4 and all(0.0 <= b <= 1.0 for b in bound if b is not None)
    assert 'reading bound (1.5 s)' in out


def test_accuracy_bad_inputs_one_line(capsys):
    for argv in (['--families', 'sand'], ['--set', 'slip_change_sigmaa=3'],
                 ['--set', 'slip_change_sigma=-1'], ['--set', 'slip_change_sigma']):
        one_line_exit_2(cli.main, capsys, ['accuracy', '--seeds', '0', *argv],
                        'slip-estimator accuracy: ')


def test_every_command_help_has_a_one_line_example(capsys):
    """``slip-estimator COMMAND --help`` ends with ``example: slip-estimator COMMAND ...`` for
    every command (the example's options are the command's own)."""
    import pytest

    for name in cli.COMMANDS:
        with pytest.raises(SystemExit) as exit_:
            cli.main([name, '--help'])
        assert exit_.value.code == 0
        out = capsys.readouterr().out
        examples = [ln.strip() for ln in out.splitlines() if ln.strip().startswith('example:')]
        assert len(examples) == 1, (name, out)
        example = examples[0].removeprefix('example: ').split()
        assert example[:2] == ['slip-estimator', name]
        options = {a for a in example if a.startswith('--')}
        assert all(o in out.split('example:')[0] for o in options), (name, options)


def test_evaluate_without_report_dir_writes_next_to_the_estimate(tmp_path, capsys):
    from slip_estimator.replay import replay_main
    from slip_estimator.report import evaluate_main
    from slip_estimator.sim.bag import simulate_main

    bag, params, est = tmp_path / 'drive', tmp_path / 'drive.yaml', tmp_path / 'estimate'
    assert simulate_main(['--scenario', 'short', '--duration-s', '30', '-o', str(bag),
                          '--params-out', str(params)]) == 0
    assert replay_main([str(bag), '--params-file', str(params), '-o', str(est)]) == 0
    capsys.readouterr()
    assert evaluate_main(['--input', str(bag), '--estimate', str(est), '--params', str(params),
                          '--no-plots', '--quiet']) == 0
    out = capsys.readouterr().out
    report = tmp_path / 'estimate_report'
    assert (report / 'metrics.json').is_file() and (report / 'summary.txt').is_file()
    assert f'report: {report}' in out
