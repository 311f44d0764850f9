"""The rotor description file (YAML) and the JointState actuator input of the CLI and node.

::

    thrust_axis: [0.0, 0.0, 1.0]   # optional, unit thrust axis in the gyro frame (default +z)
    rotors:
      - joint: rotor_0             # name in JointState.name (velocity [rad/s], magnitude used)
        position: [0.12, -0.12, 0.0]   # rotor hub from the centre of mass, gyro frame [m]
        spin: 1                    # +1 counter-clockwise about the thrust axis, -1 clockwise
        k_f: 8.5e-6                # thrust coefficient [N/(rad/s)^2]
        k_m: 1.4e-7                # drag-torque coefficient [N m/(rad/s)^2]
        time_constant: 0.02        # optional: JointState speeds are commands, lagged [s]
        inertia: 3.0e-5            # optional: rotor spin inertia [kg m^2] (its momentum)
        k_f_std: 1.7e-7            # optional one-sigma uncertainties, same units
        k_m_std: 2.8e-9
        inertia_std: 1.0e-6
        min_speed: 300.0           # optional: speed range [rad/s] (plan --rotors)
        max_speed: 1200.0

The body torque is ``sum_i w_i^2 (k_f,i p_i x a - s_i k_m,i a)`` (see
:mod:`inertia_ros.core.estimation.rotors`).  :class:`ActuatorInput` turns JointState speeds
of wheels or rotors into the core's momentum input, block by block (the node) or at once
(the CLI).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core._validate import show
from ..core.estimation.momentum import Momentum, Wheel, wheel_inputs, wheels_momentum
from ..core.estimation.rotors import Rotor, RotorSet, rotors_momentum
from .actuator_yaml import check_entry, check_top, joint_name, number, std_of, vector3
from .yaml_input import read_yaml

__all__ = ['ActuatorInput', 'load_actuators', 'load_rotor_limits', 'load_rotors',
           'rotors_from_dict']

_KEYS = ('joint', 'position', 'spin', 'k_f', 'k_m', 'time_constant', 'inertia', 'k_f_std',
         'k_m_std', 'inertia_std', 'min_speed', 'max_speed')
#: Largest rotor speed limit [rad/s].
MAX_ROTOR_SPEED = 1e5
_REQUIRED = ('joint', 'position', 'spin', 'k_f', 'k_m')
#: Longest motor time constant [s].
MAX_TIME_CONSTANT = 10.0


def rotors_from_dict(d: Any, where: str = 'rotors') -> RotorSet:
    """The rotors of the parsed YAML (``{'rotors': [...], 'thrust_axis': [...]}``).

    Raises
    ------
    ValueError
        Missing or unknown keys, wrong shapes, values that are not numbers or out of range,
        duplicate joints: one line naming the file and the entry.
    """
    items = check_top(d, where, 'rotors', ('rotors', 'thrust_axis'))
    axis = vector3(d['thrust_axis'], f'{where}: thrust_axis', nonzero=True) \
        if 'thrust_axis' in d else [0.0, 0.0, 1.0]
    out: list[Rotor] = []
    for i, it in enumerate(items):
        key = f'{where}: rotors[{i}]'
        check_entry(it, key, _KEYS, _REQUIRED)
        spin = it['spin']
        if isinstance(spin, bool) or spin not in (1, -1):
            raise ValueError(f'{key}.spin: must be +1 or -1, got {show(spin)}')
        val = {'k_f': number(it['k_f'], f'{key}.k_f', positive=True),
               'k_m': number(it['k_m'], f'{key}.k_m', nonneg=True)}
        val['time_constant'] = number(it.get('time_constant', 0.0), f'{key}.time_constant',
                                      nonneg=True, high=MAX_TIME_CONSTANT)
        val['inertia'] = number(it.get('inertia', 0.0), f'{key}.inertia', nonneg=True)
        for k in ('k_f', 'k_m', 'inertia'):
            val[f'{k}_std'] = std_of(it.get(f'{k}_std', 0.0), f'{key}.{k}_std', val[k])
        joint = joint_name(it['joint'], f'{key}.joint')
        _speed_range(it, key)
        pos = np.array(vector3(it['position'], f'{key}.position'))
        try:
            out.append(Rotor(joint, pos, int(spin), **val))
        except (TypeError, ValueError) as exc:
            raise ValueError(f'{key}: {exc}') from None
    names = [r.joint for r in out]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f'{where}: joint names must be unique, {dup[0]!r} is given twice')
    try:
        return RotorSet(tuple(out), np.array(axis))
    except ValueError as exc:
        raise ValueError(f'{where}: {exc}') from None


def _speed_range(it: dict, key: str) -> tuple[float, float]:
    """A rotor's optional ``[min_speed, max_speed]`` [rad/s] (default ``[0, inf]``)."""
    lo = number(it.get('min_speed', 0.0), f'{key}.min_speed', nonneg=True,
                high=MAX_ROTOR_SPEED)
    if 'max_speed' not in it:
        return lo, float('inf')
    hi = number(it['max_speed'], f'{key}.max_speed', positive=True, high=MAX_ROTOR_SPEED)
    if not hi > lo:
        raise ValueError(f'{key}.max_speed: must be above min_speed ({lo:g}), got '
                         f'{show(it["max_speed"])}')
    return lo, hi


def load_rotor_limits(path: str | Path, hover_thrust: float) -> Any:
    """The rotors of a rotors file with their speed ranges, hovering at ``hover_thrust``
    [N] (:class:`~inertia_ros.core.excitation.actuators.RotorLimits`; ``max_speed`` needed).

    Raises
    ------
    ValueError
        As :func:`load_rotors`; a rotor without ``max_speed``; rotors that cannot make every
        torque axis or hover within their ranges: one line naming the file.
    """
    from ..core.excitation.actuators import RotorLimits

    d = read_yaml(path, 'rotors')
    rs = rotors_from_dict(d, str(path))
    ranges = []
    for i, it in enumerate(d['rotors']):
        if 'max_speed' not in it:
            raise ValueError(f'{path}: rotors[{i}].max_speed: missing (plan --rotors needs a '
                             'speed range per rotor)')
        ranges.append(_speed_range(it, f'{path}: rotors[{i}]'))
    lo, hi = (np.array(v) for v in zip(*ranges, strict=True))
    try:
        return RotorLimits(tuple(rs.joints), np.array([r.k_f for r in rs.rotors]),
                           rs.torque_rows(), lo, hi, float(hover_thrust))
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from None


def load_rotors(path: str | Path) -> RotorSet:
    """Read and validate a rotors YAML file (bounded, strict: :mod:`.yaml_input`; one-line
    ValueError naming the file)."""
    return rotors_from_dict(read_yaml(path, 'rotors'), str(path))


@dataclass
class ActuatorInput:
    """Wheels or rotors read from JointState: the joints, the uncertain inputs and the
    conversion of speeds to the core's :class:`~inertia_ros.core.estimation.momentum.Momentum`.

    Attributes
    ----------
    kind : {'wheels', 'rotors'}
    file : str
        The description file.
    wheels : list of Wheel, optional
    rotors : RotorSet, optional
    state : dict
        Motor-lag state between blocks (rotors with a time constant).
    """

    kind: str
    file: str
    wheels: list[Wheel] | None = None
    rotors: RotorSet | None = None
    state: dict[str, Any] = field(default_factory=dict)

    @property
    def joints(self) -> list[str]:
        """JointState names, in column order."""
        return self.rotors.joints if self.rotors is not None else \
            [w.joint for w in self.wheels or []]

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the uncertain inputs (as every block lists them)."""
        return self.block(np.zeros(1), np.zeros((1, len(self.joints))), stateless=True).names

    def block(self, t: np.ndarray, speed: np.ndarray, stateless: bool = False) -> Momentum:
        """The momentum input of a block of speeds (K, n) at ``t`` (K,) [s] (online form)."""
        if self.rotors is not None:
            return self.rotors.inputs(t, speed, None if stateless else self.state)
        return wheel_inputs(t, speed, self.wheels or [])

    def record(self, t: np.ndarray, speed: np.ndarray) -> Momentum:
        """The validated momentum input of a whole record (batch form, noise estimated)."""
        if self.rotors is not None:
            return rotors_momentum(t, speed, self.rotors)
        return wheels_momentum(t, speed, self.wheels or [])

    def reset(self) -> None:
        """Forget the motor-lag state (a new run)."""
        self.state.clear()


def load_actuators(wheels_file: str | Path | None, rotors_file: str | Path | None
                   ) -> ActuatorInput | None:
    """The actuator input of a wheels or a rotors file (None when neither is given).

    Raises
    ------
    ValueError
        Both given, or an invalid file (one line naming it).
    """
    from .wheels import load_wheels

    if wheels_file and rotors_file:
        raise ValueError('wheels and rotors files given together; use one of them')
    if wheels_file:
        return ActuatorInput('wheels', str(wheels_file), wheels=load_wheels(wheels_file))
    if rotors_file:
        return ActuatorInput('rotors', str(rotors_file), rotors=load_rotors(rotors_file))
    return None
