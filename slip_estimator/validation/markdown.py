"""The report: ``docs/validation.md`` rendered from a :class:`~.study.Study`.

:data:`TEMPLATE` is the page; each ``{name}`` line is filled by the section function of that
name in :data:`SECTIONS` (:mod:`.sections`, :mod:`.sections_effects`), which reads every number
from the study (none is typed in here). Cells and tables: :mod:`.tables`; judgements whose
wording depends on the numbers: :mod:`.verdicts`; sections from the core-level evidence runs:
:mod:`.sections_evidence`.
"""
from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from slip_estimator.validation.configs import COMMAND
from slip_estimator.validation.sections import (Page, before_after, header, notes,
                                                stop_tilt, trajectories, truth, undeclared,
                                                unexplained, what_was_run)
from slip_estimator.validation.sections_effects import (effect_b, effect_c, effect_d, effect_e,
                                                        effect_f)
from slip_estimator.validation.study import Study


TEMPLATE = """\
{header}
## What was run

{what_was_run}
## Which metric rests on which truth

{truth}
## Before / after

{before_after}
## Evidence per effect

{effect_b}
{effect_c}
{effect_d}
{effect_e}
{effect_f}
### s5t1 trajectories

{trajectories}
{undeclared}
{stop_tilt}
## What remains unexplained

{unexplained}
## Notes from the evaluation

{notes}"""
"""The page: literal lines, and ``{name}`` lines replaced by the lines of section ``name``."""

SECTIONS: dict[str, Callable[[Page], list[str]]] = {
    section.__name__: section for section in (
        header, what_was_run, truth, before_after, effect_b, effect_c, effect_d, effect_e,
        effect_f, trajectories, undeclared, stop_tilt, unexplained, notes)}
"""Section functions by the name of their ``{name}`` line in :data:`TEMPLATE`."""

_SLOT = re.compile(r'^\{(\w+)\}$')


def render_markdown(study: Study, figures: dict[str, Path], md_path: Path,
                    command: str = COMMAND) -> str:
    """The report text (Markdown). Figures are linked relative to ``md_path``."""
    page = Page(study, figures, md_path, command)
    lines: list[str] = []
    for line in TEMPLATE.split('\n'):
        slot = _SLOT.match(line)
        lines += SECTIONS[slot.group(1)](page) if slot else [line]
    return '\n'.join(lines)
