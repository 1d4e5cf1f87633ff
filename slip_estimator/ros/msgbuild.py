"""Fast building and reading of generated ROS message classes (through their slots).

The generated constructor builds (and then discards) a default of every nested message and
checks each keyword, which costs more than the whole odometry computation; :func:`build`
writes the slots directly, through a small function made once per class (as dataclasses make
their ``__init__``, with ``exec`` of source generated from the class's slot names).
:func:`enable_fast_build` turns it on only after checking that both ways give equal messages;
until then (and if the check fails) the constructors are used.
"""
from __future__ import annotations

from collections.abc import Callable
from operator import attrgetter
from typing import Any

from builtin_interfaces.msg import Time

FAST_BUILD = False
"""Whether :func:`build` writes slots (True after a successful :func:`enable_fast_build`)."""
_CHECK_FIELDS = getattr(Time(), '_check_fields', False)
_BUILDERS: dict[type, Callable[..., Any]] = {}


def slot_of(cls: type, name: str) -> str:
    """The attribute that stores field ``name`` of a generated message class: the slot
    ``'_' + name`` behind the Python property where there is one (reading it skips the
    property call), else ``name``."""
    return '_' + name if '_' + name in getattr(cls, '__slots__', ()) else name


def _slot_path(cls: type, path: str) -> str:
    """:func:`slot_of` along a dotted field path (``'header.stamp.sec'``)."""
    out, obj = [], cls()
    for name in path.split('.'):
        slot = slot_of(type(obj), name)
        out.append(slot)
        obj = getattr(obj, slot)
    return '.'.join(out)


def fields_getter(cls: type, *paths: str) -> Callable[[Any], tuple]:
    """One ``attrgetter`` for several dotted field paths of message class ``cls`` (reading
    the slots directly): returns a tuple of the values."""
    return attrgetter(*(_slot_path(cls, p) for p in paths))


def build(cls: type, *values: Any) -> Any:
    """A message of ``cls`` with its fields, in declaration order, set to ``values``."""
    if not FAST_BUILD:
        return cls(**dict(zip(cls.get_fields_and_field_types(), values)))
    make = _BUILDERS.get(cls)
    if make is None:
        make = _BUILDERS[cls] = _slot_builder(cls)
    return make(*values)


def _slot_builder(cls: type) -> Callable[..., Any]:
    """``make(field_1, ..., field_n)`` storing each field in its slot; Jazzy's classes also
    get the constructor's ROS_PYTHON_CHECK_FIELDS flag."""
    slots = [slot_of(cls, name) for name in cls.get_fields_and_field_types()]
    if any(not slot.startswith('_') or not slot[1:].isidentifier() for slot in slots):
        raise TypeError(f'{cls.__name__}: fields not stored in slots')
    args = [f'v{i}' for i in range(len(slots))]
    lines = [f'def make({", ".join(args)}):', '    m = new(cls)']
    lines += [f'    m.{slot} = {arg}' for slot, arg in zip(slots, args)]
    if '_check_fields' in cls.__slots__:
        lines.append('    m._check_fields = check')
    lines.append('    return m')
    scope = {'new': cls.__new__, 'cls': cls, 'check': _CHECK_FIELDS}
    exec('\n'.join(lines), scope)  # noqa: S102 -- source made above from the class's slots
    return scope['make']


def enable_fast_build(sample_outputs: Callable[[], list[Any]]) -> bool:
    """Use the slot builders if ``sample_outputs()`` (messages made with :func:`build`) gives
    the same messages (==, repr) through the slots as through the constructors."""
    global FAST_BUILD
    try:
        FAST_BUILD = False
        reference = sample_outputs()
        FAST_BUILD = True
        FAST_BUILD = all(a == b and repr(a) == repr(b)
                         for a, b in zip(sample_outputs(), reference))
    except Exception:  # noqa: BLE001 -- any surprise: use the constructors
        FAST_BUILD = False
    return FAST_BUILD
