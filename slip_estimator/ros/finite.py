"""The last line of defence before publishing: no NaN or Inf leaves the node.

:func:`message_is_finite` checks every float field of a ROS message (recursively, arrays and
sequences included) and every string that spells a number. It runs on every output, so the
fields of each message class are collected once into dotted ``attrgetter`` paths.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter
from typing import Any

import numpy as np

from slip_estimator.ros.msgbuild import slot_of

_INT_TYPES = frozenset({'boolean', 'octet', 'char', 'byte', 'int8', 'uint8', 'int16', 'uint16',
                        'int32', 'uint32', 'int64', 'uint64', 'builtin_interfaces/Time',
                        'builtin_interfaces/Duration'})


@dataclass(frozen=True, slots=True)
class _GuardPlan:
    """Where a message class can hold a float or a string (integers, stamps and durations
    cannot be NaN). Fields of nested messages are flattened into dotted paths, so that one
    ``attrgetter`` call fetches all scalar floats (or all strings) of the message."""

    floats: Callable[[Any], tuple] | None
    texts: Callable[[Any], tuple] | None
    arrays: tuple[Callable[[Any], Any], ...]
    sequences: tuple[Callable[[Any], Any], ...]

    @property
    def texts_only(self) -> bool:
        """Only strings to check (e.g. ``KeyValue``)."""
        return self.floats is None and not self.arrays and not self.sequences


_GUARD_PLANS: dict[type, _GuardPlan] = {}


def _getter(paths: list[str]) -> Callable[[Any], tuple] | None:
    """``attrgetter`` of the dotted paths that always returns a tuple (None for no path)."""
    if not paths:
        return None
    if len(paths) == 1:
        get = attrgetter(paths[0])
        return lambda msg: (get(msg),)
    return attrgetter(*paths)


def _collect_fields(cls: type, prefix: str, kinds: dict[str, list[str]]) -> None:
    sample = cls()  # field kinds are static per class: read them off a default instance
    for name, kind in cls.get_fields_and_field_types().items():
        if kind.split('[')[0].removeprefix('sequence<').rstrip('>') in _INT_TYPES:
            continue
        slot = slot_of(cls, name)
        value, path = getattr(sample, slot), prefix + slot
        if isinstance(value, float):
            kinds['floats'].append(path)
        elif isinstance(value, str):
            kinds['texts'].append(path)
        elif isinstance(value, np.ndarray):
            kinds['arrays'].append(path)
        elif isinstance(value, (list, tuple)) or type(value).__name__ == 'array':
            kinds['sequences'].append(path)
        elif hasattr(value, 'get_fields_and_field_types'):
            _collect_fields(type(value), path + '.', kinds)


def _guard_plan(cls: type) -> _GuardPlan:
    """The :class:`_GuardPlan` of ``cls``, made once per message class: the guard runs on
    every output."""
    plan = _GUARD_PLANS.get(cls)
    if plan is None:
        kinds: dict[str, list[str]] = {'floats': [], 'texts': [], 'arrays': [], 'sequences': []}
        _collect_fields(cls, '', kinds)
        plan = _GuardPlan(_getter(kinds['floats']), _getter(kinds['texts']),
                          tuple(attrgetter(p) for p in kinds['arrays']),
                          tuple(attrgetter(p) for p in kinds['sequences']))
        _GUARD_PLANS[cls] = plan
    return plan


def message_is_finite(msg: Any) -> bool:
    """True when no float field of a ROS message (recursively, arrays included) is NaN/Inf and
    no string field spells a non-finite number ('nan', 'inf', ...).

    The last line of defence before publishing: whatever the core returns, no NaN goes out.
    """
    plan = _GUARD_PLANS.get(type(msg)) or _guard_plan(type(msg))
    if plan.floats is not None:
        values = plan.floats(msg)
        # A finite sum means every term is finite (inf and NaN propagate); a non-finite sum
        # may also be an overflow of finite terms, so then each term is checked.
        if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
            return False
    if plan.texts is not None:
        for text in plan.texts(msg):
            if not text_is_finite(text):
                return False
    for get in plan.arrays:
        value = get(msg)
        if isinstance(value, np.ndarray) and value.dtype.kind == 'f':
            # As above: a finite sum (of Python floats, which overflow without a warning)
            # means finite elements; otherwise each element is checked.
            flat = value.reshape(-1)
            if not math.isfinite(sum(flat.tolist())) and not np.isfinite(flat).all():
                return False
        elif not _items_are_finite(value):
            return False
    for get in plan.sequences:
        if not _items_are_finite(get(msg)):
            return False
    return True


def _items_are_finite(items: Any) -> bool:
    for item in items:
        if isinstance(item, float):
            if not math.isfinite(item):
                return False
        elif isinstance(item, str):
            if not text_is_finite(item):
                return False
        else:
            plan = _GUARD_PLANS.get(type(item))
            if plan is None:
                if not hasattr(item, 'get_fields_and_field_types'):
                    continue
                plan = _guard_plan(type(item))
            if plan.texts_only:  # diagnostic KeyValues: check the strings here
                for text in plan.texts(item):
                    if not text_is_finite(text):
                        return False
            elif not message_is_finite(item):
                return False
    return True


def text_is_finite(text: str) -> bool:
    """False when ``text`` parses as a non-finite number ('nan', '-inf', '1e999', ...)."""
    if len(text) > 12 or not text:
        return True
    # float() parses only what starts (after blanks) with a sign, a point, a digit or the
    # n/i of nan/inf: skip the parse (and its exception) for names like 'odom'.
    first = text.lstrip()[:1]
    if not first or (first not in '+-.nNiI' and not first.isdecimal()):
        return True
    try:
        return math.isfinite(float(text))
    except ValueError:
        return True
