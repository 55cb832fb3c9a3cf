"""A dependency-free progress bar on stderr for the long accuracy methods."""

from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


class Progress:
    """``Progress(total, label)``; ``update(done)`` redraws at most 10 times a second.

    Args:
        total: the budget (evaluations).
        label: text before the bar.
        enabled: draw at all (None: only when stderr is a terminal).
        width: bar width, characters.
    """

    def __init__(self, total: int, label: str, enabled: bool | None = None, width: int = 30):
        self.total = max(int(total), 1)
        self.label = label
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)
        self.width = width
        self._last = 0.0

    def update(self, done: int, note: str = "", force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        fraction = min(max(done / self.total, 0.0), 1.0)
        filled = int(round(fraction * self.width))
        bar = "#" * filled + "-" * (self.width - filled)
        sys.stderr.write(f"\r{self.label} [{bar}] {done}/{self.total} evaluations {note}")
        sys.stderr.flush()

    def close(self, done: int, note: str = "") -> None:
        if not self.enabled:
            return
        self.update(done, note, force=True)
        sys.stderr.write("\n")
        sys.stderr.flush()
