"""Field checks shared by the wheels and the rotors description files.

Both files are read by :func:`inertia_ros.io.yaml_input.read_yaml` (bounded, strict YAML) and
their entries checked here alike: a number is a YAML number (never ``true`` or a string), in
a stated range; a vector is three such numbers; a joint is a short printable name; the
top-level keys and the entry keys are known ones; the list is not longer than
:data:`MAX_ACTUATORS`.  Every problem is one ``ValueError`` line naming the file and the key.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..core._validate import show

__all__ = ['MAX_ACTUATORS', 'MAX_JOINT_CHARS', 'MAX_MAGNITUDE', 'check_entry', 'check_top',
           'joint_name', 'number', 'std_of', 'vector3']

#: Most wheels or rotors in one file.
MAX_ACTUATORS = 64
#: Longest joint name [characters].
MAX_JOINT_CHARS = 128
#: Largest magnitude of any number in the files (SI units: kg m^2, m, N/(rad/s)^2, s).
MAX_MAGNITUDE = 1e6


def number(value: Any, key: str, *, positive: bool = False, nonneg: bool = False,
           high: float = MAX_MAGNITUDE) -> float:
    """A YAML number (int or float, not a bool or a string), finite, ``|x| <= high``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'{key}: must be a number, got {show(value)}')
    x = float(value)
    if not math.isfinite(x) or abs(x) > high:
        raise ValueError(f'{key}: must be a finite number of magnitude at most {high:g}, '
                         f'got {show(value)}')
    if positive and not x > 0.0:
        raise ValueError(f'{key}: must be > 0, got {show(value)}')
    if nonneg and x < 0.0:
        raise ValueError(f'{key}: must be >= 0, got {show(value)}')
    return x


def std_of(value: Any, key: str, of: float) -> float:
    """A one-sigma uncertainty: a number in ``[0, of]`` (100 % of the value it belongs to;
    beyond it the value is unknown, and the error propagation overflows)."""
    x = number(value, key, nonneg=True)
    if x > of:
        raise ValueError(f'{key}: must be at most the value it belongs to ({of:g}), got '
                         f'{show(value)}')
    return x


def vector3(value: Any, key: str, *, nonzero: bool = False) -> list[float]:
    """Three YAML numbers (each ``|x| <= MAX_MAGNITUDE``); ``nonzero``: not all zero."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 3:
        raise ValueError(f'{key}: must be a list of 3 numbers, got {show(value)}')
    out = [number(v, f'{key}[{i}]') for i, v in enumerate(value)]
    if nonzero and math.hypot(*out) == 0.0:
        raise ValueError(f'{key}: must be 3 numbers, not all zero, got {show(value)}')
    return out


def joint_name(value: Any, key: str) -> str:
    """A JointState name: a non-empty printable string (an integer is read as its digits)."""
    if isinstance(value, int) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f'{key}: must be a joint name (a non-empty string), got {show(value)}')
    if len(value) > MAX_JOINT_CHARS or not value.isprintable():
        raise ValueError(f'{key}: must be a printable name of at most {MAX_JOINT_CHARS} '
                         f'characters, got {show(value)}')
    return value


def check_top(d: Any, where: str, list_key: str, allowed: Sequence[str]) -> list[Any]:
    """The entry list of a file's top-level mapping, after refusing unknown keys."""
    if not isinstance(d, dict) or not isinstance(d.get(list_key), list) or not d[list_key]:
        raise ValueError(f'{where}: expected a mapping with a non-empty list "{list_key}:"')
    unknown = sorted(str(k) for k in set(d) - set(allowed))
    if unknown:
        raise ValueError(f'{where}: unknown top-level key(s) {show(unknown)}; allowed: '
                         f'{", ".join(allowed)}')
    items = d[list_key]
    if len(items) > MAX_ACTUATORS:
        raise ValueError(f'{where}: {len(items)} {list_key}, more than {MAX_ACTUATORS}')
    return items


def check_entry(it: Any, key: str, allowed: Sequence[str], required: Sequence[str]) -> dict:
    """One list entry: a mapping with only ``allowed`` keys and every ``required`` one."""
    if not isinstance(it, dict):
        raise ValueError(f'{key}: must be a mapping with {", ".join(required)}')
    bad = sorted(str(k) for k in set(it) - set(allowed))
    if bad:
        raise ValueError(f'{key}: unknown key(s) {show(bad)}; allowed: {", ".join(allowed)}')
    for req in required:
        if req not in it:
            raise ValueError(f'{key}.{req}: missing')
    return it
