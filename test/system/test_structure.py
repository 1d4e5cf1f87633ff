"""Architecture rules that must hold: a pure core and a config that mirrors the schema."""
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from slip_estimator.core.params import Params, ParameterError
from slip_estimator.paramfile import load_params, render_default_config

REPO = Path(__file__).resolve().parents[2]


def test_core_imports_numpy_and_stdlib_only():
    code = ('import sys, slip_estimator.core.estimator, slip_estimator.core.error_model;'
            'print("\\n".join(sorted(m.split(".")[0] for m in sys.modules)))')
    mods = set(subprocess.run([sys.executable, '-c', code], check=True, capture_output=True,
                              text=True).stdout.split())
    forbidden = {'rclpy', 'rosbags', 'yaml', 'matplotlib', 'h5py', 'scipy', 'sensor_msgs',
                 'nav_msgs', 'geometry_msgs', 'diagnostic_msgs', 'std_msgs'}
    assert not mods & forbidden, mods & forbidden


def test_config_yaml_mirrors_the_schema_key_for_key():
    text = (REPO / 'config' / 'slip_estimator.yaml').read_text()
    assert text == render_default_config(), 'regenerate with `slip-estimator default-config`'
    values = yaml.safe_load(text)['slip_estimator']['ros__parameters']
    assert list(values) == [f.name for f in dataclasses.fields(Params)]
    assert load_params(REPO / 'config' / 'slip_estimator.yaml') == Params()


@pytest.mark.parametrize('name, value', [
    ('wheel_radius', -0.1), ('wheel_radius', float('nan')), ('planet', 'venus'),
    ('imu_to_base_rpy', [0.0, 0.0]), ('wheel_input', 'encoders'), ('track_width', 'wide'),
])
def test_invalid_parameters_are_refused_with_their_name_and_range(name, value):
    with pytest.raises(ParameterError, match=name):
        Params(**{name: value})
