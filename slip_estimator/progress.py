"""Progress lines on stderr: one line rewritten with ``\\r`` on a terminal, plain lines (at most
every ``LOG_EVERY_S``) when stderr is a file or a pipe, so that logs stay readable."""
from __future__ import annotations

import sys
import time

TTY_EVERY_S = 0.5
"""Interval of the updates on a terminal, s."""
LOG_EVERY_S = 5.0
"""Interval of the plain lines when stderr is not a terminal, s."""


class Progress:
    """Throttled progress on stderr (``enabled=False``: silent; ``every_s``: the interval, by
    default ``TTY_EVERY_S`` on a terminal and ``LOG_EVERY_S`` otherwise)."""

    def __init__(self, enabled: bool = True, every_s: float | None = None) -> None:
        self.enabled = enabled
        self.tty = enabled and sys.stderr.isatty()
        self._every_s = every_s if every_s is not None else (
            TTY_EVERY_S if self.tty else LOG_EVERY_S)
        self._last = time.monotonic() if not self.tty else 0.0
        self._pending = False

    def due(self) -> bool:
        """True when an update would be shown now (callers may skip formatting otherwise)."""
        return self.enabled and time.monotonic() - self._last >= self._every_s

    def show(self, text: str) -> None:
        """An intermediate line, if due."""
        if not self.due():
            return
        self._last = time.monotonic()
        if self.tty:
            print(f'\r{text}', end='', file=sys.stderr, flush=True)
            self._pending = True
        else:
            print(text, file=sys.stderr, flush=True)

    def done(self, text: str) -> None:
        """The final line (always shown when enabled)."""
        if not self.enabled:
            return
        if self._pending:
            print(f'\r{text}\033[K', file=sys.stderr, flush=True)
        else:
            print(text, file=sys.stderr, flush=True)
        self._pending = False
