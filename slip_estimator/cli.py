"""``slip-estimator``: a thin command-line shell; every subcommand imports its module lazily.

Subcommands
-----------
demo               simulate the embedded default drive, replay it through the node, evaluate
simulate           write a simulated rover drive (MCAP bag + params file)
setup              measure a robot on its bag, write its params file (topics, mounting, noise)
replay             play a bag through the node code, write its outputs to an MCAP bag
evaluate           compare a replay output with truth (simulator truth or GNSS)
import-pathfinder  convert a Pathfinder .mat log to an MCAP bag + params file
bench              measure core, replay, live-node and memory performance on this machine
validate           regenerate docs/validation.md: the model study on the real Pathfinder logs
accuracy           score the slip model over seeded simulated drives and injected real logs
default-config     print config/slip_estimator.yaml as generated from the parameter schema
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _demo(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog='slip-estimator demo', description=(
        'Simulate the embedded default rover drive, replay it through the node and print the '
        'slip confusion matrix and the drift.'),
        epilog='example: slip-estimator demo --scenario short --out demo_output')
    parser.add_argument('--out', default='demo_output', help='output folder (default: %(default)s)')
    parser.add_argument('--seed', type=int, default=0, help='trajectory seed')
    parser.add_argument('--scenario', choices=('default', 'short', 'mixed', 'patches', 'rough'),
                        default='default', help='simulated drive (wheel-rate control; mixed '
                        'adds wheels spinning up at an unchanged body speed)')
    args = parser.parse_args(argv)
    from slip_estimator.replay import replay_main
    from slip_estimator.report import evaluate_main
    from slip_estimator.sim.bag import simulate_main

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sim_bag, params, est_bag = out / 'sim_drive', out / 'sim_drive.params.yaml', out / 'estimate'
    for bag in (sim_bag, est_bag):
        if bag.exists():
            import shutil
            shutil.rmtree(bag)
    print(f'[1/3] simulating the {args.scenario} drive (seed {args.seed}) -> {sim_bag}')
    rc = simulate_main(['--seed', str(args.seed), '--scenario', args.scenario,
                        '--output', str(sim_bag), '--params-out', str(params)])
    if rc:
        return rc
    print(f'[2/3] replaying through the node -> {est_bag}')
    rc = replay_main([str(sim_bag), '--params-file', str(params), '--output', str(est_bag)])
    if rc:
        return rc
    print(f'[3/3] evaluating -> {out / "report"}')
    return evaluate_main(['--input', str(sim_bag), '--estimate', str(est_bag),
                          '--params', str(params), '--report-dir', str(out / 'report'),
                          '--json', str(out / 'metrics.json')])


def _default_config(argv: list[str]) -> int:
    argparse.ArgumentParser(
        prog='slip-estimator default-config',
        description='Print the default parameter file, generated from the parameter schema.',
        epilog='example: slip-estimator default-config > my_robot.yaml').parse_args(argv)
    from slip_estimator.paramfile import render_default_config
    sys.stdout.write(render_default_config())
    return 0


def _lazy(module: str, func: str, defaults: tuple[tuple[str, str], ...] = ()):
    """A subcommand run by ``module.func(argv)``, imported on first use; ``defaults`` are
    (option, path under ``SHARED_DATA``) appended when the user did not give the option."""
    def run(argv: list[str]) -> int:
        import importlib
        if not {'-h', '--help'} & set(argv):
            for option, name in defaults:
                if not any(a == option or a.startswith(option + '=') for a in argv):
                    argv = [*argv, option, str(SHARED_DATA / name)]
        return getattr(importlib.import_module(module), func)(argv)
    return run


SHARED_DATA = Path('..') / 'shared' / 'data' / 'pathfinder'
"""The real logs, relative to the current folder (a checkout's root): never inside an
installed package."""


COMMANDS = {
    'demo': _demo,
    'simulate': _lazy('slip_estimator.sim.bag', 'simulate_main'),
    'setup': _lazy('slip_estimator.robot_setup.cli', 'setup_main'),
    'replay': _lazy('slip_estimator.replay', 'replay_main'),
    'evaluate': _lazy('slip_estimator.report', 'evaluate_main'),
    'import-pathfinder': _lazy('slip_estimator.pathfinder.cli', 'import_main'),
    'bench': _lazy('slip_estimator.bench.cli', 'bench_main', (('--pathfinder', 's5t1.mat'),)),
    'validate': _lazy('slip_estimator.validation.cli', 'validate_main', (('--data-dir', ''),)),
    'accuracy': _lazy('slip_estimator.accuracy', 'accuracy_main', (('--data-dir', ''),)),
    'default-config': _default_config,
}


def usage() -> str:
    """The command list, from the module docstring's table."""
    table = __doc__.split('-----------\n', 1)[1].strip()
    return ('usage: slip-estimator COMMAND [ARGS...]   (slip-estimator COMMAND --help for its '
            'options)\n\ncommands:\n' + '\n'.join('  ' + line for line in table.splitlines()))


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``slip-estimator`` console script."""
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ('-h', '--help'):
        print(usage())
        return 0 if argv else 2
    if argv[0] not in COMMANDS:
        print(f"slip-estimator: unknown command '{argv[0]}' (one of: {', '.join(COMMANDS)}; "
              'see slip-estimator --help)', file=sys.stderr)
        return 2
    try:
        return int(COMMANDS[argv[0]](argv[1:]) or 0)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split('.')[0] in ROS_MODULES:
            print(f'slip-estimator: ROS 2 Jazzy Python package {exc.name!r} not found: source '
                  '/opt/ros/jazzy/setup.bash, or pip install "slip_estimator[ros]" (the '
                  'ros-jazzy-* wheels)', file=sys.stderr)
            return 2
        if exc.name in OPTIONAL_MODULES:
            print(f'slip-estimator {argv[0]}: needs {exc.name}: pip install '
                  f'"slip_estimator[{OPTIONAL_MODULES[exc.name]}]"', file=sys.stderr)
            return 2
        raise


ROS_MODULES = ('rclpy', 'rcl_interfaces', 'builtin_interfaces', 'std_msgs', 'std_srvs',
               'sensor_msgs', 'nav_msgs', 'geometry_msgs', 'diagnostic_msgs')
OPTIONAL_MODULES = {'h5py': 'pathfinder', 'matplotlib': 'plots'}
"""Modules of the setup.py extras, by extra."""


if __name__ == '__main__':
    sys.exit(main())
