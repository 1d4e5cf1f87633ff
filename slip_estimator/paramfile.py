"""Read and write ROS 2 parameter YAML files (``node: ros__parameters: {...}``) as Params."""
from __future__ import annotations

import dataclasses
import fnmatch
import sys
from pathlib import Path
from typing import Any

import yaml

from slip_estimator.core.params import (
    REMOVED_PARAMETERS,
    RENAMED_PARAMETERS,
    ParameterError,
    Params,
    renamed_in,
)

NODE_NAME = 'slip_estimator'


NODE_ONLY_PARAMETERS = {'allow_unknown_parameters': False, 'use_sim_time': False,
                        'input_batch_period_s': 0.01}
"""Parameters of the node itself (not of the estimator): read by the node, ignored by replay."""


def read_yaml(path: str | Path) -> Any:
    """The YAML document of a parameter file; :class:`ParameterError` (one line naming the file
    and what is wrong) when it cannot be read or parsed."""
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ParameterError(f'{path}: cannot read the parameter file '
                             f'({exc.strerror or exc})') from None
    try:
        return yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or type(exc).__name__
        raise ParameterError(f'{path}: YAML syntax error{where}: {problem}') from None


def node_sections(doc: Any, node_name: str = NODE_NAME) -> list[str]:
    """The sections of a parameter document that apply to the node ``node_name`` (a name or a
    fully qualified name): ``/**``, the name with or without its leading slash, or a wildcard
    pattern matching it, in file order (rcl merges them in that order)."""
    fqn = '/' + node_name.lstrip('/')
    keys = [k for k in doc if isinstance(k, str)] if isinstance(doc, dict) else []
    return [k for k in keys if fnmatch.fnmatchcase(fqn, '/' + k.lstrip('/'))]


def read_param_values(path: str | Path, node_name: str = NODE_NAME) -> dict[str, Any]:
    """Flat parameter mapping for ``node_name`` from a ROS 2 params file.

    The sections that apply to the node (:func:`node_sections`) are merged like rcl does. A file
    with no section for the node is refused, naming the sections it has: a misspelled node name
    would otherwise run silently on every default.
    """
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise ParameterError(f'{path}: not a ROS 2 parameter file (expected '
                             f'"{node_name}: ros__parameters: ...")')
    sections = node_sections(doc, node_name)
    if not sections:
        raise ParameterError(
            f'{path}: no section for node {node_name!r} (sections in the file: '
            f'{", ".join(map(str, doc)) or "none"}); expected "{node_name}:" or "/**:"')
    values: dict[str, Any] = {}
    for key in sections:
        section = doc[key]
        if isinstance(section, dict):
            values.update(section.get('ros__parameters') or {})
    return values


def load_params(path: str | Path, node_name: str = NODE_NAME) -> Params:
    """Params from a ROS 2 params file; unknown keys are an error (a typo must not pass)
    unless the file sets ``allow_unknown_parameters: true`` (they are then ignored). A
    parameter set under its old name (:data:`~slip_estimator.core.params.RENAMED_PARAMETERS`)
    loads, with a one-line warning on stderr naming the new name."""
    values = read_param_values(path, node_name)
    for warning in renamed_in(values):
        print(f'{path}: warning: {warning}', file=sys.stderr)
    allow_unknown = bool(values.get('allow_unknown_parameters', False))
    for key in NODE_ONLY_PARAMETERS:
        values.pop(key, None)
    try:
        return Params.from_dict(values, ignore_unknown=allow_unknown)
    except (ParameterError, TypeError) as exc:
        raise ParameterError(f'{path}: {exc}') from None


def save_params(params: Params, path: str | Path, node_name: str = NODE_NAME, *,
                comments: list[str] | tuple[str, ...] = ()) -> None:
    """Write params as a ROS 2 params file loadable with ``--ros-args --params-file``;
    ``comments`` (one paragraph each) go at the top as ``#`` lines."""
    import textwrap

    head = ''.join(''.join(f'# {line}\n' for line in textwrap.wrap(c, 96)) for c in comments)
    Path(path).write_text(head + yaml.safe_dump(
        {node_name: {'ros__parameters': params.to_dict()}}, sort_keys=False))


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
    """The text of ``config/slip_estimator.yaml``: every parameter, its default and a comment,
    under a heading per group (flat keys: the groups are a comment, the names stay the node's)."""
    from slip_estimator.core.params import describe

    defaults = Params()
    lines = ['# slip_estimator parameters: mirrors slip_estimator/core/params.py key for key',
             '# (regenerate with `slip-estimator default-config > config/slip_estimator.yaml`).',
             f'{NODE_NAME}:', '  ros__parameters:']
    group = None
    for f in dataclasses.fields(Params):
        if f.metadata['group'] != group:
            group = f.metadata['group']
            lines.append(f'    # === {group} (Params.{group}) ===')
        lines.append(f'    # {describe(f.name)}')
        lines.append(f'    {f.name}: {_yaml_value(getattr(defaults, f.name))}')
    return '\n'.join(lines) + '\n'


_DEFAULTS = Params()


def coerce_param_value(name: str, value: Any) -> Any:
    """Give a ROS parameter value the Python type of the Params field (ints to floats where
    the default is a float, arrays to lists); anything else is left for Params to reject."""
    default = getattr(_DEFAULTS, name)
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, list) and not isinstance(value, str):
        try:
            items = list(value)
        except TypeError:
            return value
        if default and isinstance(default[0], float):
            return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                    for v in items]
        return items
    return value


PARAMETER_NAMES = tuple(f.name for f in dataclasses.fields(Params))
"""Every estimator parameter's name (the node declares each one)."""
_ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')
"""Parameters rclpy declares itself (plus ``qos_overrides.*``)."""


def params_files(argv: list[str]) -> list[str]:
    """The ``--params-file`` paths among the ROS arguments of ``argv``."""
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == '--params-file']


def unknown_parameters(names: Any) -> list[str]:
    """Names set for the node (params files, ``-p``) that are not parameters of it (removed
    and renamed ones, :data:`REMOVED_PARAMETERS`, :data:`RENAMED_PARAMETERS`, are not unknown:
    files that still set them load)."""
    return sorted(n for n in names if n not in PARAMETER_NAMES and n not in NODE_ONLY_PARAMETERS
                  and n not in REMOVED_PARAMETERS and n not in RENAMED_PARAMETERS
                  and n not in _ROS_OWN_PARAMETERS
                  and not n.startswith('qos_overrides.'))
