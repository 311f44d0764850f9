"""The one progress bar of the package (estimate, fleet, bench): tqdm, on stderr, TTY only.

Every long command draws its progress through :func:`progress_bar`, so they look alike and
stay silent when stderr is not a terminal (logs, pipes, CI) unless asked.
"""
from __future__ import annotations

import sys
from typing import Any, TextIO

__all__ = ['progress_bar']


def progress_bar(total: float, desc: str, *, enabled: bool | None = None,
                 stream: TextIO | None = None, unit: str = 'it', scale: float = 1.0,
                 fmt: str | None = None) -> Any:
    """A ``tqdm`` bar with the package's look.

    Parameters
    ----------
    total : float
        Expected total (steps, or bytes with ``scale``).
    desc : str
        Label in front of the bar.
    enabled : bool, optional
        Draw or not; default: only when ``stream`` is a terminal.
    stream : file, optional
        Where to draw (default ``sys.stderr``).
    unit : str
        Unit of the count.
    scale : float
        Multiply counts by this for display (``1e-6`` shows bytes as MB).
    fmt : str, optional
        tqdm ``bar_format``; default ``DESC [####  ] n/total elapsed<eta postfix``.

    Returns
    -------
    tqdm.tqdm
        Call ``update(n)``, ``set_postfix_str(text)``, ``close()``.
    """
    from tqdm import tqdm

    out = stream if stream is not None else sys.stderr
    if enabled is None:
        enabled = bool(getattr(out, 'isatty', lambda: False)())
    return tqdm(total=total, desc=desc, file=out, disable=not enabled, leave=False,
                ascii=' #', ncols=100, mininterval=0.1, unit=unit,
                unit_scale=scale if scale != 1.0 else False,
                bar_format=fmt or '{desc} [{bar:30}] {n_fmt}/{total_fmt} '
                                  '{elapsed}<{remaining} {postfix}')
