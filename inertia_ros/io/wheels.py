"""The wheels description file (YAML): per wheel the joint name, spin axis and inertia.

::

    wheels:
      - joint: rw1            # name in JointState.name
        axis: [1.0, 0.0, 0.0] # spin axis, unit vector in the gyro frame
        inertia: 1.2e-3       # kg m^2 about the spin axis
        inertia_std: 1.2e-5   # optional, one sigma
        max_torque: 0.01      # optional: largest motor torque [N m] (plan --wheels)
        max_speed: 600.0      # optional: largest wheel speed [rad/s] (plan, exciter)

The estimator reads the first four keys; the planner and the exciter read the limits
(:func:`load_wheel_limits`).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..core.estimation.momentum import Wheel
from .actuator_yaml import check_entry, check_top, joint_name, number, std_of, vector3
from .yaml_input import read_yaml

if TYPE_CHECKING:   # imported where used: core.excitation's package imports the designer and
    # scipy.optimize, ~0.3 s of CPU that every `estimate --wheels/--rotors` paid
    from ..core.excitation.actuators import WheelLimit

__all__ = ['load_wheel_limits', 'load_wheels', 'wheel_limits_from_dict', 'wheels_from_dict']

_KEYS = ('joint', 'axis', 'inertia', 'inertia_std', 'max_torque', 'max_speed')
#: Largest wheel speed limit [rad/s] (as the scenes' wheels).
MAX_WHEEL_SPEED = 1e5


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
        for lim in ('max_torque', 'max_speed'):
            if lim in it:
                number(it[lim], f'{key}.{lim}', positive=True,
                       high=MAX_WHEEL_SPEED if lim == 'max_speed' else 1e6)
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


def wheel_limits_from_dict(d: Any, where: str = 'wheels', *,
                           need: tuple[str, ...] = ('max_speed',),
                           initial_speed: Any = None) -> list[WheelLimit]:
    """The wheels' limits from the parsed YAML (read as :func:`wheels_from_dict`).

    Parameters
    ----------
    need : tuple of str
        Limit keys every wheel must have (``max_torque``, ``max_speed``); a missing one is
        unlimited (``inf``) otherwise.
    initial_speed : sequence of float, optional
        Each wheel's speed at the start [rad/s], in file order (default 0).

    Raises
    ------
    ValueError
        As :func:`wheels_from_dict`; a missing needed limit; a wrong number of initial speeds
        or one at or over its wheel's ``max_speed``: one line naming the file and the entry.
    """
    from ..core.excitation.actuators import WheelLimit

    wheels = wheels_from_dict(d, where)
    items = d['wheels']
    w0 = [0.0] * len(wheels) if initial_speed is None else list(initial_speed)
    if len(w0) != len(wheels):
        raise ValueError(f'{where}: {len(wheels)} wheels but {len(w0)} initial wheel speeds '
                         '(give one per wheel, in file order)')
    out = []
    for i, (w, it) in enumerate(zip(wheels, items, strict=True)):
        key = f'{where}: wheels[{i}]'
        for lim in need:
            if lim not in it:
                raise ValueError(f'{key}.{lim}: missing (needed here: '
                                 f'{" and ".join(need)} per wheel)')
        mt = float(it.get('max_torque', math.inf))
        ms = float(it.get('max_speed', math.inf))
        if not abs(float(w0[i])) < ms:
            raise ValueError(f'{key}.max_speed: {ms:g} rad/s is not above the initial wheel '
                             f'speed {float(w0[i]):g} rad/s (raise it or start slower)')
        out.append(WheelLimit(w.joint, w.axis, w.inertia, mt, ms, float(w0[i])))
    return out


def load_wheel_limits(path: str | Path, *, need: tuple[str, ...] = ('max_speed',),
                      initial_speed: Any = None) -> list[WheelLimit]:
    """Read a wheels YAML file and return its wheels' limits (:func:`wheel_limits_from_dict`).

    Raises
    ------
    ValueError
        Unreadable file, bad YAML, an invalid entry or a missing needed limit (one line
        naming the file).
    """
    return wheel_limits_from_dict(read_yaml(path, 'wheels'), str(path), need=need,
                                  initial_speed=initial_speed)
