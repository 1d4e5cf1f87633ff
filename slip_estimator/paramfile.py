"""Read and write ROS 2 parameter YAML files (``node: ros__parameters: {...}``) as Params."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from slip_estimator.core.params import ParameterError, Params

NODE_NAME = 'slip_estimator'


def read_param_values(path: str | Path, node_name: str = NODE_NAME) -> dict[str, Any]:
    """Flat parameter mapping for ``node_name`` from a ROS 2 params file.

    Sections ``/**``, ``node_name`` and ``/node_name`` are merged in that order, like rcl does.
    """
    doc = yaml.safe_load(Path(path).read_text()) or {}
    if not isinstance(doc, dict):
        raise ParameterError(f'{path}: not a ROS 2 parameter file')
    values: dict[str, Any] = {}
    for key in ('/**', node_name, '/' + node_name):
        section = doc.get(key)
        if isinstance(section, dict):
            values.update(section.get('ros__parameters') or {})
    return values


def load_params(path: str | Path, node_name: str = NODE_NAME) -> Params:
    """Params from a ROS 2 params file; unknown keys are an error (a typo must not pass)."""
    return Params.from_dict(read_param_values(path, node_name))


def save_params(params: Params, path: str | Path, node_name: str = NODE_NAME) -> None:
    """Write params as a ROS 2 params file loadable with ``--ros-args --params-file``."""
    Path(path).write_text(yaml.safe_dump({node_name: {'ros__parameters': params.to_dict()}},
                                         sort_keys=False))


def _yaml_value(value: Any) -> str:
    if isinstance(value, list):
        return '[' + ', '.join(_yaml_value(v) for v in value) + ']'
    if isinstance(value, float):
        text = repr(value)
        # YAML 1.1 (PyYAML, rcl) reads "1e-07" as a string: keep a mantissa dot.
        if 'e' in text and '.' not in text.split('e')[0]:
            mantissa, exponent = text.split('e')
            text = f'{mantissa}.0e{exponent}'
        return text
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def render_default_config() -> str:
    """The text of ``config/slip_estimator.yaml``: every parameter, its default and a comment."""
    import dataclasses

    from slip_estimator.core.params import describe

    defaults = Params()
    lines = ['# slip_estimator parameters: mirrors slip_estimator/core/params.py key for key',
             '# (regenerate with `slip-estimator default-config > config/slip_estimator.yaml`).',
             f'{NODE_NAME}:', '  ros__parameters:']
    for f in dataclasses.fields(Params):
        lines.append(f'    # {describe(f.name)}')
        lines.append(f'    {f.name}: {_yaml_value(getattr(defaults, f.name))}')
    return '\n'.join(lines) + '\n'
