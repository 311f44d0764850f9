"""Process-wide settings of inertia_ros's programs (the CLI, the nodes, the fleet workers).

The estimators work on arrays of a few MiB that each call allocates and frees.  glibc's
allocator gives freed memory at the top of its heap back to the kernel once more than its
trim threshold (about twice the largest block freed so far) is free, so the next call of the
same size page-faults all of it in again: on a 60 s record (200 Hz gyro, 50 Hz torque) the
default ``ml`` method spends about a fifth of its time in those faults.  Keeping a pad of
freed heap removes them; the programs of this package ask for it at start-up, and a Python
program that calls :func:`inertia_ros.core.estimation.estimate` many times can do the same.

This is a property of the process, not of the numerics: estimates are bit-identical with or
without it.  Elsewhere than glibc (macOS, musl) it does nothing.
"""
from __future__ import annotations

import ctypes
import os

__all__ = ['HEAP_PAD_BYTES', 'keep_freed_memory']

#: Freed heap kept for reuse [bytes]: above the largest array of a 60 s record's ``ml``
#: refinement (about 6 MiB), well below a one-hour record's working set.
HEAP_PAD_BYTES = 64 << 20
_M_TOP_PAD = -2            # glibc's mallopt parameter number (malloc.h)
_done: dict[str, bool] = {}


def keep_freed_memory(pad_bytes: int = HEAP_PAD_BYTES) -> bool:
    """Keep up to ``pad_bytes`` of freed heap in this process instead of returning it.

    Calls glibc's ``mallopt(M_TOP_PAD, pad_bytes)`` once per process.  A
    ``MALLOC_TOP_PAD_`` set in the environment wins (the user's choice stands).

    Parameters
    ----------
    pad_bytes : int
        Heap kept beyond what is in use [bytes], >= 0.

    Returns
    -------
    bool
        True when the allocator took the setting (now or at an earlier call).
    """
    if 'pad' in _done:
        return _done['pad']
    ok = False
    if 'MALLOC_TOP_PAD_' not in os.environ and pad_bytes >= 0:
        try:
            libc = ctypes.CDLL(None)        # the process's own symbols: libc's on Linux
            mallopt = libc.mallopt
        except (OSError, AttributeError):     # not glibc: nothing to set
            mallopt = None
        if mallopt is not None:
            mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
            mallopt.restype = ctypes.c_int
            ok = mallopt(_M_TOP_PAD, int(min(pad_bytes, 2 ** 31 - 1))) == 1
    _done['pad'] = ok
    return ok
