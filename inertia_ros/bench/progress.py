"""The bench's step counter over the package's one progress bar (:mod:`inertia_ros.progress`)."""
from __future__ import annotations

import sys
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
        from inertia_ros.progress import progress_bar

        self.total = int(total)
        self.stream = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, 'isatty', lambda: False)
        self.enabled = bool(isatty()) if enabled is None else bool(enabled)
        self.done = 0
        self._bar = progress_bar(self.total, '', enabled=self.enabled, stream=self.stream)

    def __call__(self, label: str = '') -> None:
        """Advance by one step and redraw (at most 10 times a second)."""
        self.done += 1
        self._bar.set_postfix_str(label[:40], refresh=False)
        self._bar.update(1)
        if self.done >= self.total:
            self._bar.refresh()

    def close(self) -> None:
        """End the status line."""
        self._bar.close()
