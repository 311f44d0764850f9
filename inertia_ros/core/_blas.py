"""One BLAS thread while an estimate runs (OpenBLAS, as loaded by numpy and scipy).

The estimators' products are many and of medium size (``(60 000, 13)`` Grams, ``(15 000, 9)``
maps on a 300 s record).  Above about 1e6 multiply-adds OpenBLAS hands a product to a second
thread, which then busy-waits for the next one; on this project's 2-core machine that
spinning cost more CPU than the products themselves (a 300 s record's default estimate 273
against 169 ms of CPU, the hour-long log's 1.03 against 0.85 s, also less wall time under
load).  :func:`one_blas_thread` sets every loaded OpenBLAS to one thread for the duration of
a call and restores it after the last concurrent call leaves.  A thread count the user set
in the environment (``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``) stands; without OpenBLAS
(another BLAS, another platform) it does nothing.  Results do not depend on it.
"""
from __future__ import annotations

import ctypes
import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ['one_blas_thread']

_SUFFIXES = ('', '64_')                      # numpy's scipy-openblas64 names end in 64_
_PREFIXES = ('scipy_openblas', 'openblas')
_lock = threading.Lock()
_state: dict = {'libs': [], 'modules': -1, 'depth': 0, 'saved': []}


def _openblas() -> list[tuple]:
    """``(get, set)`` thread-count functions of every OpenBLAS mapped into the process
    (looked up again when modules were imported since: scipy loads its own lazily)."""
    if len(sys.modules) == _state['modules']:
        return _state['libs']
    _state['modules'] = len(sys.modules)
    found = []
    try:
        with open('/proc/self/maps') as maps:
            paths = {line.split()[-1] for line in maps if 'openblas' in line.lower()}
    except OSError:                            # not Linux
        paths = set()
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for pre in _PREFIXES:
            for suf in _SUFFIXES:
                get = getattr(lib, f'{pre}_get_num_threads{suf}', None)
                put = getattr(lib, f'{pre}_set_num_threads{suf}', None)
                if get is not None and put is not None:
                    put.argtypes = [ctypes.c_int]
                    found.append((get, put))
    _state['libs'] = found
    return found


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Every loaded OpenBLAS on one thread inside the block (re-entrant, thread-safe)."""
    if 'OPENBLAS_NUM_THREADS' in os.environ or 'OMP_NUM_THREADS' in os.environ:
        yield
        return
    with _lock:
        if _state['depth'] == 0:
            _state['saved'] = [(put, get()) for get, put in _openblas()]
            for put, _ in _state['saved']:
                put(1)
        _state['depth'] += 1
    try:
        yield
    finally:
        with _lock:
            _state['depth'] -= 1
            if _state['depth'] == 0:
                for put, n in _state['saved']:
                    put(n)
