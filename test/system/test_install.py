"""A non-editable install (``pip install .``) runs the offline tools from the installed copy.

The package is built and installed with ``pip install --no-deps --target`` into a throwaway
folder (its dependencies are this environment's, as after ``pip install .`` with them present);
the console script then runs from a folder outside the checkout with only that folder on
PYTHONPATH, so nothing can come from the source tree.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def installed(tmp_path_factory) -> tuple[Path, Path, dict[str, str]]:
    target = tmp_path_factory.mktemp('site')
    proc = subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '--no-deps',
                           '--target', str(target), str(REPO)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    work = tmp_path_factory.mktemp('work')
    env = dict(os.environ, PYTHONPATH=str(target), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    return target, work, env


def _run(installed, *args: str) -> subprocess.CompletedProcess:
    target, work, env = installed
    return subprocess.run([str(target / 'bin' / 'slip-estimator'), *args], cwd=work, env=env,
                          capture_output=True, text=True, timeout=600)


def test_installed_copy_and_its_files(installed):
    target, work, env = installed
    where = subprocess.run([sys.executable, '-c', 'import slip_estimator.replay as m; '
                            'print(m.__file__)'], cwd=work, env=env, capture_output=True,
                           text=True, check=True).stdout.strip()
    assert Path(where).is_relative_to(target), where
    assert not list((target / 'slip_estimator').rglob('test_*.py'))
    share = target / 'share' / 'slip_estimator'
    assert (share / 'config' / 'slip_estimator.yaml').is_file()
    assert (share / 'launch' / 'slip_estimator.launch.py').is_file()
    assert (share / 'package.xml').is_file()
    for script in ('slip-estimator', 'slip-estimator-node', 'slip_estimator_node'):
        assert (target / 'bin' / script).is_file()


def test_installed_console_script_runs_simulate_replay_evaluate(installed):
    help_ = _run(installed, 'replay', '--help')
    assert help_.returncode == 0 and '--remap' in help_.stdout, help_.stderr
    sim = _run(installed, 'simulate', '--scenario', 'short', '--duration-s', '30', '--output',
               'sim', '--params-out', 'sim.yaml')
    assert sim.returncode == 0, sim.stderr
    rep = _run(installed, 'replay', 'sim', '--params-file', 'sim.yaml', '--output', 'est')
    assert rep.returncode == 0 and 'replay:' in rep.stdout, rep.stderr
    ev = _run(installed, 'evaluate', '--input', 'sim', '--estimate', 'est', '--params',
              'sim.yaml', '--report-dir', 'report', '--no-plots')
    assert ev.returncode == 0 and 'balanced accuracy' in ev.stdout, ev.stderr
    assert '\r' not in ev.stderr + rep.stderr  # not a terminal: plain progress lines


def test_installed_validate_data_folder_is_relative_to_cwd(installed):
    target = installed[0]
    proc = _run(installed, 'validate', '--out', 'v.md')
    assert proc.returncode == 2
    assert 'data folder ../shared/data/pathfinder not found' in proc.stderr, proc.stderr
    assert str(target) not in proc.stderr


DISTRIBUTION = {'numpy': 'numpy', 'yaml': 'pyyaml', 'rosbags': 'rosbags', 'h5py': 'h5py',
                'matplotlib': 'matplotlib', 'rclpy': 'ros-jazzy-rclpy',
                'rcl_interfaces': 'ros-jazzy-rclpy', 'builtin_interfaces': 'ros-jazzy-rclpy',
                'std_msgs': 'ros-jazzy-std-msgs', 'std_srvs': 'ros-jazzy-std-srvs',
                'sensor_msgs': 'ros-jazzy-sensor-msgs', 'nav_msgs': 'ros-jazzy-nav-msgs',
                'geometry_msgs': 'ros-jazzy-geometry-msgs',
                'diagnostic_msgs': 'ros-jazzy-diagnostic-msgs'}


def test_every_third_party_import_is_declared(installed):
    """Each module the package imports outside the standard library comes from a distribution
    the installed metadata requires (directly or through an extra)."""
    import ast

    target = installed[0]
    meta = next(target.glob('slip_estimator-*.dist-info')) / 'METADATA'
    required = {line.split(':', 1)[1].strip().split(';')[0].split('[')[0].split('>')[0]
                .strip().lower() for line in meta.read_text().splitlines()
                if line.startswith('Requires-Dist:')}
    imported = set()
    for path in (target / 'slip_estimator').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported |= {a.name.split('.')[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                imported.add(node.module.split('.')[0])
    third_party = {m for m in imported - {'slip_estimator', '__future__'}
                   if m not in sys.stdlib_module_names}
    undeclared = {m for m in third_party if DISTRIBUTION.get(m, m) not in required}
    assert not undeclared, f'imported but not in setup.py: {sorted(undeclared)}'
