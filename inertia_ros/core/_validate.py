"""Argument validators shared by the core: arrays, times, noise levels, masses, rotations.

Every validator converts its argument and raises one ``ValueError`` whose message starts with
the argument's name (``'omega: expected shape (N, 3), got (5, 2)'``), so user-facing code can
show it without a traceback.  Used by :mod:`.tensor`, :mod:`.dynamics`, :mod:`.inertia`,
:mod:`.bodies`, :mod:`.crlb` and the estimators.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ._numeric import median

__all__ = ['MAX_SAMPLE_INTERVAL_S', 'MAX_TIME_S', 'require_after', 'as_float_array', 'as_mass',
           'as_matrix33',
           'as_noise_std', 'as_rotation',
           'as_sample_block', 'as_samples', 'as_times', 'as_unit_axis', 'as_vector3',
           'as_vectors', 'check_symmetric', 'max_asymmetry', 'refuse_nanoseconds',
           'require_finite', 'require_plausible', 'show']


def as_float_array(x: Any, name: str) -> np.ndarray:
    """Convert ``x`` to a float64 array, raising ValueError naming ``name`` on failure.

    Integer arrays are converted; complex ones are refused (their imaginary part would be
    dropped silently).
    """
    _refuse_complex(x, name)
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name}: expected an array of real numbers, got {type(x).__name__} '
                         f'({exc})') from None
    return arr


def _refuse_complex(x: Any, name: str) -> None:
    """Raise ValueError naming ``name`` when ``x`` holds complex numbers."""
    if np.iscomplexobj(x):
        raise ValueError(f'{name}: complex values are not supported; give real numbers')


def _to_float(x: Any, name: str) -> np.ndarray:
    """``np.asarray(x, dtype=float)`` with a one-line ValueError naming ``name`` on failure."""
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name}: expected real numbers, got {type(x).__name__} '
                         f'({str(exc).splitlines()[0] if str(exc) else "not convertible"})'
                         ) from None


#: Largest plausible time stamp [s] (30 000 years): beyond it a stamp is nanoseconds.
MAX_TIME_S = 1e12
#: Largest plausible median sample interval [s]: beyond it the stamps are nanoseconds.
MAX_SAMPLE_INTERVAL_S = 3600.0


def refuse_nanoseconds(t: np.ndarray, name: str) -> None:
    """Raise ValueError when the times ``t`` [s] look like nanoseconds.

    A median sample interval over an hour (or stamps beyond 1e12 s, 30 000 years) is a
    stamp in nanoseconds given as seconds; estimating would allocate for 1e9 times as long.
    """
    if not len(t):
        return
    d = np.diff(t)
    # the median interval can be over the limit only if the largest is (a max, not a median)
    long_steps = len(d) > 0 and float(np.max(d)) > MAX_SAMPLE_INTERVAL_S
    if (long_steps and median(d) > MAX_SAMPLE_INTERVAL_S) \
            or float(np.max(np.abs(t))) > MAX_TIME_S:
        dt = median(d) if len(d) else 0.0
        raise ValueError(f'{name}: times look like nanoseconds (first {float(t[0]):.6g}, median '
                         f'interval {dt:.3g} s); give seconds, e.g. t_ns * 1e-9')


def require_finite(arr: np.ndarray, name: str) -> None:
    """Raise ValueError naming ``name`` if ``arr`` holds NaN or infinity."""
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f'{name}: must be finite, found {bad} NaN/inf value(s)')


def as_vectors(x: Any, name: str, *, check_finite: bool = True) -> np.ndarray:
    """A float array of shape (..., 3), validated; ValueError names ``name``."""
    arr = as_float_array(x, name)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f'{name}: expected shape (..., 3), got {arr.shape}')
    if check_finite:
        require_finite(arr, name)
    return arr


def as_vector3(x: Any, name: str) -> np.ndarray:
    """A finite float array of shape exactly (3,); ValueError names ``name``."""
    arr = as_float_array(x, name)
    if arr.shape != (3,):
        raise ValueError(f'{name}: expected shape (3,), got {arr.shape}')
    require_finite(arr, name)
    return arr


def max_asymmetry(m: np.ndarray) -> float:
    """Largest |M_ij - M_ji| of a (..., 3, 3) array (0 for an empty stack)."""
    if m.size == 0:
        return 0.0
    return float(np.max(np.abs(m - np.swapaxes(m, -1, -2))))


def check_symmetric(m: np.ndarray, name: str, rtol: float) -> None:
    """Raise ValueError if a (..., 3, 3) array is not symmetric within ``rtol`` of max |M_ij|."""
    if m.size == 0:
        return
    asym = max_asymmetry(m)
    scale = float(np.max(np.abs(m)))
    if asym > rtol * scale:
        raise ValueError(f'{name}: not symmetric: max |I_ij - I_ji| = {asym:.3g} exceeds '
                         f'rtol * max|I_ij| = {rtol:.1g} * {scale:.3g}')


def as_matrix33(I: Any, name: str) -> np.ndarray:
    """``I`` (array-like or anything with ``.matrix``) as a finite float (3, 3) array."""
    if hasattr(I, 'matrix') and not isinstance(I, np.ndarray):
        I = I.matrix
    arr = as_float_array(I, name)
    if arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    require_finite(arr, name)
    return arr


def as_mass(m: Any, name: str = 'mass', *, positive: bool = False) -> float:
    """A finite mass >= 0 (> 0 when ``positive``) as float; ValueError names ``name``."""
    try:
        val = float(m)
    except (TypeError, ValueError):
        raise ValueError(f'{name}: expected a number [kg], got {m!r}') from None
    if not np.isfinite(val):
        raise ValueError(f'{name}: must be finite, got {val!r}')
    if val < 0.0 or (positive and val == 0.0):
        raise ValueError(f'{name}: must be {"> 0" if positive else ">= 0"} kg, got {val!r}')
    return val


def as_unit_axis(n: Any, name: str = 'axis') -> np.ndarray:
    """Normalise a non-zero finite (..., 3) direction; ValueError names ``name``."""
    v = as_vectors(n, name)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm == 0.0):
        raise ValueError(f'{name}: zero vector has no direction; pass a non-zero axis')
    return v / norm


def as_rotation(R: Any, name: str = 'rotation', atol: float = 1e-9) -> np.ndarray:
    """A (3, 3) proper rotation matrix (orthonormal within ``atol``, det +1)."""
    arr = as_float_array(R, name)
    if arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    require_finite(arr, name)
    err = float(np.max(np.abs(arr @ arr.T - np.eye(3))))
    if err > atol:
        raise ValueError(f'{name}: not orthonormal: max |R R^T - 1| = {err:.3g} '
                         f'exceeds {atol:.1g}')
    if np.linalg.det(arr) < 0.0:
        raise ValueError(f'{name}: det = -1 is a reflection, not a proper rotation')
    return arr

def as_times(t: Any, name: str, *, min_samples: int = 0, detail: bool = True) -> np.ndarray:
    """Validated 1-D, finite, strictly increasing sample times.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times [s].
    name : str
        Argument name for the messages.
    min_samples : int
        Fewer samples raise ``ValueError`` (``expected shape (N,) with N >= min_samples``).
    detail : bool
        Name the first non-increasing pair in the message.

    Returns
    -------
    ndarray, shape (N,)
    """
    _refuse_complex(t, name)
    arr = _to_float(t, name)
    if arr.ndim != 1 or arr.size < min_samples:
        more = f' with N >= {min_samples}' if min_samples else ''
        raise ValueError(f'{name}: expected shape (N,){more}, got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name}: contains NaN or inf')
    if len(arr) > 1 and np.any(np.diff(arr) <= 0):
        if not detail:
            raise ValueError(f'{name}: times must be strictly increasing')
        k = int(np.argmax(np.diff(arr) <= 0))
        raise ValueError(f'{name}: times must be strictly increasing (t[{k + 1}] = '
                         f'{arr[k + 1]!r} <= t[{k}] = {arr[k]!r})')
    return arr


def as_samples(x: Any, n: int, name: str, tname: str) -> np.ndarray:
    """Validated (n, 3) finite float samples matching ``n`` times named ``tname``.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    _refuse_complex(x, name)
    arr = _to_float(x, name)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f'{name}: expected shape (N, 3), got {arr.shape}')
    if arr.shape[0] != n:
        raise ValueError(f'{name}: has {arr.shape[0]} rows but {tname} has {n} samples')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name}: contains NaN or inf')
    require_plausible(arr, name)
    return arr


#: Largest magnitude accepted in a sample (rad/s, N m): beyond it the squares and Gram sums of
#: the estimators overflow, and no sensor reads that.
MAX_SAMPLE_MAGNITUDE = 1e12


def require_plausible(arr: np.ndarray, name: str) -> None:
    """Raise ValueError (one line, naming the first offending sample) for values beyond
    :data:`MAX_SAMPLE_MAGNITUDE` in magnitude, or so small that squaring them underflows."""
    a = np.abs(arr)
    bad = (a > MAX_SAMPLE_MAGNITUDE) | ((a > 0) & (a < 1e-150))
    if np.any(bad):
        k = int(np.argmax(np.any(bad, axis=-1))) if arr.ndim > 1 else int(np.argmax(bad))
        raise ValueError(f'{name}: sample {k} holds {np.atleast_1d(arr[k]).tolist()}, outside '
                         f'the plausible range (1e-150 to {MAX_SAMPLE_MAGNITUDE:g} in magnitude, '
                         'or exactly 0); remove such samples or fix their units')


def as_sample_block(t: Any, x: Any, name: str) -> tuple[np.ndarray, np.ndarray]:
    """One sample (``t`` scalar, ``x`` (3,)) or a block (``t`` (n,), ``x`` (n, 3)), validated.

    Returns
    -------
    t : ndarray, shape (n,)
        Strictly increasing finite times [s].
    x : ndarray, shape (n, 3)
        Finite values.
    """
    _refuse_complex(t, f'{name} times')
    _refuse_complex(x, name)
    ta = np.atleast_1d(_to_float(t, f'{name} times'))
    xa = _to_float(x, name)
    if xa.ndim == 1:
        xa = xa[None, :]
    if ta.ndim != 1 or xa.ndim != 2 or xa.shape[1] != 3 or len(ta) != len(xa):
        raise ValueError(f'{name}: expected t (n,) and values (n, 3) or (3,), got '
                         f'{ta.shape} and {np.shape(x)}')
    if not (np.isfinite(ta).all() and np.isfinite(xa).all()):
        raise ValueError(f'{name}: contains NaN or inf')
    require_plausible(xa, name)
    refuse_nanoseconds(ta, name)
    if len(ta) > 1 and (ta[1:] <= ta[:-1]).any():
        raise ValueError(f'{name}: times must be strictly increasing')
    return ta, xa


def require_after(first: float, last: float | None, name: str) -> None:
    """Refuse a stream block whose first time [s] is not after the stream's ``last`` one.

    ``name`` is ``'omega'`` (the gyro stream) or ``'torque'``; ``last`` None = no sample yet.
    """
    if last is not None and first <= last:
        what = 'gyro' if name == 'omega' else name
        raise ValueError(f'{name}: time {first!r} is not after the previous {what} sample '
                         f'{last!r} (call reset() after a clock jump)')


def as_noise_std(x: Any, name: str, *, what: str = '') -> np.ndarray:
    """Validated per-axis noise standard deviation: a scalar or 3 values, finite, >= 0.

    Parameters
    ----------
    x : float or array_like, shape (3,)
        Standard deviation per axis (units of the stream).
    name : str
        Argument name for the message.
    what : str
        Extra words after ``>= 0`` in the message (e.g. ``' (scalar or 3 values)'``).

    Returns
    -------
    ndarray, shape (3,)
    """
    try:
        arr = np.broadcast_to(_to_float(x, name), (3,)).copy()
    except ValueError:
        raise ValueError(f'{name}: must be a number or 3 numbers{what}, got {x!r}') from None
    if not np.all(np.isfinite(arr)) or np.any(arr < 0) or np.any(arr > MAX_SAMPLE_MAGNITUDE):
        raise ValueError(f'{name}: must be finite and >= 0{what} (at most '
                         f'{MAX_SAMPLE_MAGNITUDE:g}), got {x!r}')
    return arr


def show(value: Any, limit: int = 60) -> str:
    """``repr(value)`` cut to ``limit`` characters (for one-line messages about user values).

    Containers are summarised by type and length before ``repr`` is tried, so a value holding
    an alias bomb is never expanded into text.
    """
    if isinstance(value, (list, tuple, dict)) and len(value) > 8:
        return f'a {type(value).__name__} of {len(value)} items'
    text = repr(value) if not isinstance(value, (list, tuple, dict)) else _short(value, limit)
    return text if len(text) <= limit else text[:limit - 3] + '...'


def _short(value: Any, limit: int) -> str:
    """A repr of a small container whose items are themselves shown shortly."""
    if isinstance(value, dict):
        items = ', '.join(f'{show(k, 20)}: {show(v, 20)}' for k, v in value.items())
        text = '{' + items + '}'
    else:
        text = '[' + ', '.join(show(v, 20) for v in value) + ']'
    return text if len(text) <= limit else text[:limit - 3] + '...'


def unit_axis(axis: Any, owner: str) -> np.ndarray:
    """``axis`` as a read-only unit vector (3,); ``owner`` names it in the one-line error.

    Raises
    ------
    ValueError
        Not 3 finite numbers, or all zero.
    """
    try:
        a = np.asarray(axis, dtype=float)
    except (TypeError, ValueError):
        a = np.full(1, np.nan)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 0:
        raise ValueError(f'{owner}: axis must be 3 finite numbers, not all zero, got {axis!r}')
    a = a / np.linalg.norm(a)
    a.setflags(write=False)
    return a
