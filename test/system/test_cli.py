"""The command-line shells: help, unknown commands, the node's --help (no ROS started)."""
from __future__ import annotations

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
