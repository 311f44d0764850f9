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
from .actuator_yaml import check_entry, check_top, joint_name, number, std_of, vector3
from .yaml_input import read_yaml

__all__ = ['load_wheels', 'wheels_from_dict']

_KEYS = ('joint', 'axis', 'inertia', 'inertia_std')


def wheels_from_dict(d: Any, where: str = 'wheels') -> list[Wheel]:
    """Wheels from the parsed YAML (``{'wheels': [...]}``).

    Raises
    ------
    ValueError
        Missing or unknown keys (top level too), values that are not numbers (``true``, a
        string) or out of range, duplicate joints; one line naming the file and the entry.
    """
    items = check_top(d, where, 'wheels', ('wheels',))
    out: list[Wheel] = []
    for i, it in enumerate(items):
        key = f'{where}: wheels[{i}]'
        check_entry(it, key, _KEYS, ('joint', 'axis', 'inertia'))
        inertia = number(it['inertia'], f'{key}.inertia', positive=True)
        std = std_of(it.get('inertia_std', 0.0), f'{key}.inertia_std', inertia)
        joint = joint_name(it['joint'], f'{key}.joint')
        axis = vector3(it['axis'], f'{key}.axis', nonzero=True)
        try:
            out.append(Wheel(joint, axis, inertia, std))
        except (TypeError, ValueError) as exc:
            raise ValueError(f'{key}: {exc}') from None
    names = [w.joint for w in out]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f'{where}: joint names must be unique, {dup[0]!r} is given twice')
    return out


def load_wheels(path: str | Path) -> list[Wheel]:
    """Read and validate a wheels YAML file (bounded, strict: :mod:`.yaml_input`).

    Raises
    ------
    ValueError
        Unreadable file, bad YAML or an invalid entry (one line naming the file).
    """
    return wheels_from_dict(read_yaml(path, 'wheels'), str(path))
