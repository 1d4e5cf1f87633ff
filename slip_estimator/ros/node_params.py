"""The node's parameters: declared at start, changed at runtime, applied at a reset.

Declared from :class:`slip_estimator.core.params.Params` (names, defaults, descriptions with
unit and range) with dynamic typing, so that ``wheel_radius:=1`` (an integer) is accepted and
every value is validated once, by Params. An invalid start-up value logs the parameter, value
and allowed range and ``main`` returns 2. Runtime changes are validated the same way (invalid
ones are rejected with that message); valid ones take effect at the next estimator reset: a
sensor clock jump back, or a call of the ``~/reset`` service (``std_srvs/srv/Trigger``, e.g.
``ros2 service call /slip_estimator/reset std_srvs/srv/Trigger``), which restarts the estimator
at once. ``wheel_input`` cannot change at runtime: it decides the subscriptions.

Parameter files: a file with no section for the node's name is reported at ERROR level with
the sections it has (its values do not apply); a name that is not a parameter of the node
(misspelled) makes the node refuse to start (exit 2) unless ``allow_unknown_parameters`` is
true. Two node-only parameters are read-only: ``allow_unknown_parameters`` and
``input_batch_period_s`` (:mod:`slip_estimator.ros.spin`).
"""
from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter

from slip_estimator.core.params import (
    RENAMED_PARAMETERS,
    ParameterError,
    Params,
    describe,
    renamed_in,
)
from slip_estimator.paramfile import (
    NODE_ONLY_PARAMETERS,
    PARAMETER_NAMES,
    coerce_param_value,
    node_sections,
    read_yaml,
    unknown_parameters,
)
from slip_estimator.ros.adapter import SlipEstimatorAdapter

INPUT_BATCH = 'input_batch_period_s'
MAX_INPUT_BATCH_PERIOD_S = 0.1
ALLOW_UNKNOWN = 'allow_unknown_parameters'

_DEFAULTS = Params()


def declare_params(node: Node, param_files: list[str]) -> tuple[Params, float]:
    """Check the parameter sources, declare every parameter of ``node``; the validated
    parameters and ``input_batch_period_s``. Raises :class:`ParameterError` when a value is
    invalid or a name unknown (see the module docstring)."""
    input_batch_period_s = _check_parameter_sources(node, param_files)
    defaults = _defaults_with_old_names(node)
    for name in PARAMETER_NAMES:
        node.declare_parameter(
            name, defaults[name],
            ParameterDescriptor(description=describe(name), dynamic_typing=True))
    params = Params.from_dict({name: coerce_param_value(
        name, node.get_parameter(name).value) for name in PARAMETER_NAMES})
    return params, input_batch_period_s


def _check_parameter_sources(node: Node, param_files: list[str]) -> float:
    """Log an ERROR for a params file with no section for this node (a misspelled node name
    would run on every default); raise :class:`ParameterError` for a parameter that is not
    one of the node's (misspelled) unless ``allow_unknown_parameters`` is true. Declares the
    node-only parameters; returns ``input_batch_period_s``."""
    fqn = node.get_fully_qualified_name()
    for path in param_files:
        doc = read_yaml(path)
        if not node_sections(doc, fqn):
            sections = ', '.join(map(str, doc)) if isinstance(doc, dict) else 'none'
            node.get_logger().error(
                f'parameter file {path} has NO section for this node ({fqn}); sections in '
                f'the file: {sections or "none"}. None of its values apply: expected '
                f'"{node.get_name()}:" or "/**:" at the top level.')
    allow = node.declare_parameter(
        ALLOW_UNKNOWN, NODE_ONLY_PARAMETERS[ALLOW_UNKNOWN], ParameterDescriptor(
            description='start even when a parameter file or -p sets a name that is not '
                        'a parameter of this node (otherwise the node refuses to start)',
            read_only=True)).value
    unknown = unknown_parameters(node._parameter_overrides)
    if unknown and not allow:
        raise ParameterError(
            f'unknown parameter(s) {", ".join(unknown)} (misspelled? every parameter: '
            f'slip-estimator default-config); set {ALLOW_UNKNOWN}:=true to start anyway')
    if unknown:
        node.get_logger().error(f'ignoring unknown parameter(s) {", ".join(unknown)} '
                                f'({ALLOW_UNKNOWN} is true)')
    period = node.declare_parameter(
        INPUT_BATCH, NODE_ONLY_PARAMETERS[INPUT_BATCH], ParameterDescriptor(
            description='s, 0 to 0.1: the node sleeps this long after handling what was '
                        'ready, then handles what arrived meanwhile in one go (less CPU, '
                        'up to this much more output latency; 0: wake for every message)',
            read_only=True, dynamic_typing=True)).value
    if (isinstance(period, bool) or not isinstance(period, (int, float))
            or not 0.0 <= period <= MAX_INPUT_BATCH_PERIOD_S):
        raise ParameterError(f'{INPUT_BATCH} = {period!r}: must be a number of seconds '
                             f'from 0 to {MAX_INPUT_BATCH_PERIOD_S:g}')
    return float(period)


def _defaults_with_old_names(node: Node) -> dict[str, Any]:
    """The schema's defaults, a value set under a parameter's old name
    (:data:`RENAMED_PARAMETERS`) in place of its new name's default (the new name, when set
    too, overrides it as any default); a one-line warning per old name."""
    overrides = node._parameter_overrides
    for warning in renamed_in(overrides):
        node.get_logger().warning(warning)
    defaults = _DEFAULTS.to_dict()
    for old, new in RENAMED_PARAMETERS.items():
        if old in overrides:
            defaults[new] = overrides[old].value
    return defaults


def change_params(adapter: SlipEstimatorAdapter, parameters: list[Parameter],
                  logger: RcutilsLogger, node_fqn: str) -> SetParametersResult:
    """A runtime parameter change: validated, then handed to the adapter, which applies it at
    the next reset (``wheel_input`` cannot change)."""
    ours = {p.name: coerce_param_value(p.name, p.value) for p in parameters
            if p.name in PARAMETER_NAMES}
    if not ours:
        return SetParametersResult(successful=True)
    current = adapter.pending_params or adapter.params
    if 'wheel_input' in ours and ours['wheel_input'] != current.wheel_input:
        return SetParametersResult(
            successful=False, reason='wheel_input cannot change at runtime; restart the node')
    try:
        new = current.replace(**ours)
    except ParameterError as exc:
        logger.error(f'rejected parameter change: {exc}')
        return SetParametersResult(successful=False, reason=str(exc))
    adapter.request_params(new)
    logger.info(
        f'accepted parameter change {ours}; effective at the next estimator reset (call '
        f'the {node_fqn}/reset service, std_srvs/srv/Trigger, to apply it now)')
    return SetParametersResult(successful=True)


def reset_applying_changes(adapter: SlipEstimatorAdapter) -> str:
    """Restart the estimator now (``~/reset``), applying any accepted parameter change; what
    was done, in one line."""
    pending = adapter.pending_params
    changed = ({k: v for k, v in pending.to_dict().items()
                if getattr(adapter.params, k) != v} if pending is not None else {})
    adapter.reset('reset requested on ~/reset')
    return 'estimator reset' + (f'; parameter change applied: {changed}' if changed else '')
