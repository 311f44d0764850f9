"""A dependency-free progress bar on stderr, drawn only when stderr is a terminal."""
from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ['Progress']


class Progress:
    """Counts steps and redraws one status line (``\\r``) on a TTY; silent otherwise.

    Parameters
    ----------
    total : int
        Expected number of steps (>= 1).
    stream : file, optional
        Where to draw (default ``sys.stderr``).
    enabled : bool, optional
        Force drawing on or off (default: ``stream.isatty()``).
    """

    def __init__(self, total: int, stream: TextIO | None = None,
                 enabled: bool | None = None) -> None:
        if total < 1:
            raise ValueError(f'total: must be >= 1, got {total!r}')
        self.total = int(total)
        self.stream = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, 'isatty', lambda: False)
        self.enabled = bool(isatty()) if enabled is None else bool(enabled)
        self.done = 0
        self.t0 = time.monotonic()
        self._last = 0.0

    def __call__(self, label: str = '') -> None:
        """Advance by one step and redraw (at most 10 times a second)."""
        self.done += 1
        if not self.enabled:
            return
        now = time.monotonic()
        if now - self._last < 0.1 and self.done < self.total:
            return
        self._last = now
        frac = min(self.done / self.total, 1.0)
        width = 30
        bar = '#' * int(round(frac * width))
        el = now - self.t0
        eta = el / frac - el if frac > 0 else 0.0
        self.stream.write(f'\r[{bar:<{width}}] {self.done}/{self.total} {el:5.0f}s '
                          f'eta {eta:4.0f}s {label[:40]:<40}')
        self.stream.flush()

    def close(self) -> None:
        """End the status line."""
        if self.enabled:
            self.stream.write('\n')
            self.stream.flush()
