"""One BLAS thread while an estimate runs (every BLAS numpy and scipy loaded, via threadpoolctl).

The estimators' products are many and of medium size (``(60 000, 13)`` Grams, ``(15 000, 9)``
maps on a 300 s record).  Above about 1e6 multiply-adds OpenBLAS hands a product to a second
thread, which then busy-waits for the next one; on this project's 2-core machine that
spinning cost more CPU than the products themselves (a 300 s record's default estimate 273
against 169 ms of CPU, the hour-long log's 1.03 against 0.85 s, also less wall time under
load).  :func:`one_blas_thread` sets every loaded BLAS to one thread for the duration of a
call and restores it after the last concurrent call leaves.  A thread count the user set in
the environment (``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``) stands.  Results do not
depend on it.
"""
from __future__ import annotations

import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from threadpoolctl import ThreadpoolController

__all__ = ['one_blas_thread', 'blas_libraries']

_lock = threading.Lock()
_state: dict = {'libs': [], 'modules': -1, 'depth': 0, 'saved': []}


def blas_libraries() -> list:
    """threadpoolctl's controllers of every BLAS mapped into the process (looked up again
    when modules were imported since: scipy loads its own OpenBLAS lazily)."""
    if len(sys.modules) != _state['modules']:
        _state['modules'] = len(sys.modules)
        _state['libs'] = ThreadpoolController().select(user_api='blas').lib_controllers
    return _state['libs']


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Every loaded BLAS on one thread inside the block (re-entrant, thread-safe)."""
    if 'OPENBLAS_NUM_THREADS' in os.environ or 'OMP_NUM_THREADS' in os.environ:
        yield
        return
    with _lock:
        if _state['depth'] == 0:
            _state['saved'] = [(lib, lib.num_threads) for lib in blas_libraries()]
            for lib, _ in _state['saved']:
                lib.set_num_threads(1)
        _state['depth'] += 1
    try:
        yield
    finally:
        with _lock:
            _state['depth'] -= 1
            if _state['depth'] == 0:
                for lib, n in _state['saved']:
                    lib.set_num_threads(n)
