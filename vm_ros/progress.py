"""A small progress line on stderr for long CLI work (no dependency; silent when not a TTY
unless forced)."""

from __future__ import annotations

import sys
import time


class Progress:
    """``with Progress("fit W", total=100) as p: p.update(k)`` prints ``fit W  37% 12.3 s``."""

    def __init__(self, label: str, total: float, stream=None, enabled: bool | None = None):
        self.label, self.total = label, max(float(total), 1e-12)
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.start = time.monotonic()
        self._last = -1.0

    def update(self, done: float, note: str = "") -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < 0.2 and done < self.total:
            return
        self._last = now
        percent = 100.0 * min(done / self.total, 1.0)
        self.stream.write(f"\r{self.label} {percent:5.1f}% {now - self.start:6.1f} s {note}   ")
        self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
