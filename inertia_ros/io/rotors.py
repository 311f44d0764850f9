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

from ..core.estimation.momentum import Momentum, Wheel, wheel_inputs, wheels_momentum
from ..core.estimation.rotors import Rotor, RotorSet, rotors_momentum

__all__ = ['ActuatorInput', 'load_actuators', 'load_rotors', 'rotors_from_dict']

_KEYS = ('joint', 'position', 'spin', 'k_f', 'k_m', 'time_constant', 'inertia', 'k_f_std',
         'k_m_std', 'inertia_std')
_REQUIRED = ('joint', 'position', 'spin', 'k_f', 'k_m')


def _vector3(value: Any, key: str) -> list[float]:
    """Three finite numbers, or a one-line ValueError naming ``key``."""
    ok = isinstance(value, (list, tuple)) and len(value) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
        for v in value)
    if not ok:
        raise ValueError(f'{key}: must be a list of 3 numbers, got {value!r}')
    return [float(v) for v in value]


def rotors_from_dict(d: Any, where: str = 'rotors') -> RotorSet:
    """The rotors of the parsed YAML (``{'rotors': [...], 'thrust_axis': [...]}``).

    Raises
    ------
    ValueError
        Missing or unknown keys, wrong shapes, bad values, duplicate joints: one line naming
        the file and the entry.
    """
    if not isinstance(d, dict) or not isinstance(d.get('rotors'), list) or not d['rotors']:
        raise ValueError(f'{where}: expected a mapping with a non-empty list "rotors:"')
    unknown = sorted(set(d) - {'rotors', 'thrust_axis'})
    if unknown:
        raise ValueError(f'{where}: unknown top-level key(s) {unknown}; allowed: rotors, '
                         'thrust_axis')
    axis = _vector3(d['thrust_axis'], f'{where}: thrust_axis') if 'thrust_axis' in d \
        else [0.0, 0.0, 1.0]
    out: list[Rotor] = []
    for i, it in enumerate(d['rotors']):
        key = f'{where}: rotors[{i}]'
        if not isinstance(it, dict):
            raise ValueError(f'{key}: must be a mapping with {", ".join(_REQUIRED)}')
        bad = sorted(set(it) - set(_KEYS))
        if bad:
            raise ValueError(f'{key}: unknown key(s) {bad}; allowed: {list(_KEYS)}')
        for req in _REQUIRED:
            if req not in it:
                raise ValueError(f'{key}.{req}: missing')
        pos = _vector3(it['position'], f'{key}.position')
        opt = {k: it[k] for k in _KEYS[5:] if k in it}
        try:
            out.append(Rotor(str(it['joint']), np.array(pos), it['spin'], it['k_f'],
                             it['k_m'], **opt))
        except (TypeError, ValueError) as exc:
            raise ValueError(f'{key}: {exc}') from None
    try:
        return RotorSet(tuple(out), np.array(axis))
    except ValueError as exc:
        raise ValueError(f'{where}: {exc}') from None


def _read_yaml(path: str | Path, what: str) -> Any:
    """Parse a YAML file; one-line ValueError naming it when unreadable or invalid."""
    import yaml

    p = Path(path)
    try:
        return yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ValueError(f'{p}: cannot read the {what} file ({exc.strerror})') from None
    except yaml.YAMLError as exc:
        text = ' '.join(str(exc).split())
        raise ValueError(f'{p}: not valid YAML ({text})') from None


def load_rotors(path: str | Path) -> RotorSet:
    """Read and validate a rotors YAML file (one-line ValueError naming the file)."""
    return rotors_from_dict(_read_yaml(path, 'rotors'), str(path))


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
