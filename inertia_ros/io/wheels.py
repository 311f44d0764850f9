"""The wheels description file (YAML): per wheel the joint name, spin axis and inertia.

::

    wheels:
      - joint: rw1            # name in JointState.name
        axis: [1.0, 0.0, 0.0] # spin axis, unit vector in the gyro frame
        inertia: 1.2e-3       # kg m^2 about the spin axis
        inertia_std: 1.2e-5   # optional, one sigma
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.estimation.momentum import Wheel

__all__ = ['load_wheels', 'wheels_from_dict']

_KEYS = ('joint', 'axis', 'inertia', 'inertia_std')


def wheels_from_dict(d: Any, where: str = 'wheels') -> list[Wheel]:
    """Wheels from the parsed YAML (``{'wheels': [...]}``).

    Raises
    ------
    ValueError
        Missing or unknown keys, bad values, duplicate joints; the message names the entry.
    """
    if not isinstance(d, dict) or not isinstance(d.get('wheels'), list) or not d['wheels']:
        raise ValueError(f'{where}: expected a mapping with a non-empty list "wheels:"')
    out: list[Wheel] = []
    for i, it in enumerate(d['wheels']):
        key = f'{where}: wheels[{i}]'
        if not isinstance(it, dict):
            raise ValueError(f'{key}: must be a mapping with joint, axis, inertia')
        unknown = sorted(set(it) - set(_KEYS))
        if unknown:
            raise ValueError(f'{key}: unknown key(s) {unknown}; allowed: {list(_KEYS)}')
        for req in ('joint', 'axis', 'inertia'):
            if req not in it:
                raise ValueError(f'{key}.{req}: missing')
        try:
            out.append(Wheel(str(it['joint']), it['axis'], float(it['inertia']),
                             float(it.get('inertia_std', 0.0))))
        except (TypeError, ValueError) as exc:
            raise ValueError(f'{key}: {exc}') from None
    names = [w.joint for w in out]
    if len(set(names)) != len(names):
        raise ValueError(f'{where}: joint names must be unique, got {names}')
    return out


def load_wheels(path: str | Path) -> list[Wheel]:
    """Read and validate a wheels YAML file.

    Raises
    ------
    ValueError
        Unreadable file, bad YAML or an invalid entry (the message names the file).
    """
    import yaml

    p = Path(path)
    try:
        d = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ValueError(f'{p}: cannot read the wheels file ({exc.strerror})') from None
    except yaml.YAMLError as exc:
        raise ValueError(f'{p}: not valid YAML ({exc})') from None
    return wheels_from_dict(d, str(p))
