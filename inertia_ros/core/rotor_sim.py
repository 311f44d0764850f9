"""Multirotors in a scene: the ``rotors`` section, its rotor speeds, torque and momentum.

Scene YAML (see ``docs/SCENES.md``)::

    rotors:
      rate: 200.0                  # JointState rate [Hz]
      speed_noise_std: 1.0         # rotor-speed white noise [rad/s]
      thrust_axis: [0, 0, 1]       # unit, body frame (default +z)
      hover_thrust: 14.7           # total thrust held while exciting [N]
      excitation:                  # body torque the rotor speeds are allocated to [N m, Hz]
        amplitude: [0.05, 0.05, 0.01]
        frequency: [0.7, 1.1, 0.5]
      list:
        - {joint: rotor_0, position: [0.12, -0.12, 0], spin: 1, k_f: 8.5e-6, k_m: 1.4e-7,
           inertia: 3.0e-5}

The commanded body torque is a multisine per axis ``c``,
``tau_c(t) = A_c (sin(2 pi f_c t + c) + 0.5 sin(2 pi 2.7 f_c t + 2 c))``; the squared speeds
``u = w^2`` are the allocation ``u = pinv(M) [T, tau(t)]`` with ``M`` the rows ``k_f,i`` (thrust)
and ``k_f,i p_i x a - s_i k_m,i a`` (torque, :meth:`.estimation.rotors.RotorSet.torque_rows`),
so the rotors produce exactly ``tau(t)`` about the centre of mass, and their momentum
``h = sum J_i s_i w_i a`` acts as a wheel's (:func:`.wheel_sim.integrate_with_wheels`).  The
true coefficients are the scene's; the estimator reads them from a rotors file.  The rotor
section is held in :attr:`.scene.Scene.wheels` (the scene's JointState actuators), so the
simulation and the log writer treat rotors like wheels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .estimation.rotors import Rotor, RotorSet

__all__ = ['RotorScene', 'RotorSpeed', 'parse_rotors']

_HARMONIC = 2.7                  # frequency ratio of each axis' second sine
_MAX_CHECK_POINTS = 200_001      # rotor speeds checked on at most this grid (else bounded)


@dataclass(frozen=True, eq=False)
class RotorSpeed:
    """One rotor's speed in a :class:`RotorScene` (the interface of a wheel spec)."""

    joint: str
    scene: RotorScene
    index: int

    def speed(self, t: np.ndarray) -> np.ndarray:
        """True rotor speed [rad/s] at times ``t`` [s]."""
        return np.sqrt(self.scene.squared_speeds(np.asarray(t, dtype=float))[0][:, self.index])


@dataclass(frozen=True, eq=False)
class RotorScene:
    """The ``rotors`` section: the rotor set, the allocation and the JointState stream."""

    rotors: RotorSet
    rate: float
    speed_noise_std: float
    hover_thrust: float
    amplitude: np.ndarray
    frequency: np.ndarray

    @property
    def wheels(self) -> tuple[RotorSpeed, ...]:
        """The rotors as JointState joints (the wheel-scene interface)."""
        return tuple(RotorSpeed(r.joint, self, i) for i, r in enumerate(self.rotors.rotors))

    @cached_property
    def _allocation(self) -> np.ndarray:
        """``pinv(M)`` (n, 4): squared speeds per [thrust, tau_x, tau_y, tau_z]."""
        kf = np.array([r.k_f for r in self.rotors.rotors])
        return np.linalg.pinv(np.vstack([kf, self.rotors.torque_rows().T]))

    @cached_property
    def _rows(self) -> np.ndarray:
        return self.rotors.torque_rows()

    @cached_property
    def _js(self) -> np.ndarray:
        return np.array([r.inertia * r.spin for r in self.rotors.rotors])

    def body_torque(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Commanded torque (n, 3) [N m] and its derivative (n, 3) [N m/s] at ``t`` (n,)."""
        t = np.asarray(t, dtype=float)[:, None]
        c = np.arange(3)[None, :]
        om = 2 * np.pi * self.frequency[None, :]
        a = self.amplitude[None, :]
        tau = a * (np.sin(om * t + c) + 0.5 * np.sin(_HARMONIC * om * t + 2 * c))
        dtau = a * om * (np.cos(om * t + c) + 0.5 * _HARMONIC * np.cos(_HARMONIC * om * t + 2 * c))
        return tau, dtau

    def squared_speeds(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``u = w^2`` (n, k) [rad^2/s^2] and ``u'`` (n, k) at ``t`` (n,)."""
        tau, dtau = self.body_torque(t)
        P = self._allocation
        u = self.hover_thrust * P[:, 0][None, :] + tau @ P[:, 1:].T
        return u, dtau @ P[:, 1:].T

    def torque(self, t: np.ndarray) -> np.ndarray:
        """Rotor torque on the body (n, 3) [N m] at ``t`` (n,) (the true coefficients)."""
        return self.squared_speeds(t)[0] @ self._rows

    def momentum(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotor momentum ``h`` (n, 3) [N m s] and ``h'`` (n, 3) [N m] at ``t`` (n,)."""
        u, du = self.squared_speeds(t)
        w = np.sqrt(np.maximum(u, 0.0))
        dw = du / (2.0 * np.maximum(w, 1e-9))
        return np.outer(w @ self._js, self.rotors.axis), np.outer(dw @ self._js, self.rotors.axis)

    def max_hdot(self) -> float:
        """A bound of ``|h'| + |tau|`` [N m] over the run (for the integrator's substeps)."""
        t = np.linspace(0.0, 1.0 / max(float(np.min(self.frequency)), 1e-3), 2000)
        return float(np.max(np.linalg.norm(self.momentum(t)[1], axis=1))
                     + np.max(np.linalg.norm(self.torque(t), axis=1)))


def _rotor(m: Any, k: str) -> Rotor:
    """One rotor entry of the scene (true coefficients)."""
    from .scene import SceneError, _mapping, _number, _string, _vector

    m = _mapping(m, k, ('joint', 'position', 'spin', 'k_f', 'k_m', 'inertia'))
    for req in ('joint', 'position', 'spin', 'k_f', 'k_m'):
        if req not in m:
            raise SceneError(f'{k}.{req}: missing')
    spin = m['spin']
    if spin not in (1, -1) or isinstance(spin, bool):
        raise SceneError(f'{k}.spin: must be +1 or -1, got {spin!r}')
    return Rotor(_string(m['joint'], f'{k}.joint'), _vector(m['position'], f'{k}.position'),
                 int(spin), _number(m['k_f'], f'{k}.k_f', positive=True),
                 _number(m['k_m'], f'{k}.k_m', nonneg=True),
                 inertia=_number(m.get('inertia', 0.0), f'{k}.inertia', nonneg=True))


def parse_rotors(value: Any, duration: float, key: str = 'rotors') -> RotorScene:
    """Validate the ``rotors`` section of a scene (speeds must stay positive over the run).

    Raises
    ------
    ValueError
        (a :class:`~inertia_ros.core.scene.SceneError`) naming the dotted key.
    """
    from .scene import SceneError, _mapping, _number, _vector

    d = _mapping(value, key, ('rate', 'speed_noise_std', 'thrust_axis', 'hover_thrust',
                              'excitation', 'list'))
    items = d.get('list')
    if not isinstance(items, list) or not items:
        raise SceneError(f'{key}.list: must be a non-empty list of rotors')
    rotors = [_rotor(it, f'{key}.list[{i}]') for i, it in enumerate(items)]
    axis = _vector(d.get('thrust_axis', [0.0, 0.0, 1.0]), f'{key}.thrust_axis')
    try:
        rset = RotorSet(tuple(rotors), axis)
    except ValueError as exc:
        raise SceneError(f'{key}: {exc}') from None
    ex = _mapping(d.get('excitation'), f'{key}.excitation', ('amplitude', 'frequency'))
    sc = RotorScene(rset, _number(d.get('rate', 200.0), f'{key}.rate', positive=True),
                    _number(d.get('speed_noise_std', 0.0), f'{key}.speed_noise_std',
                            nonneg=True),
                    _number(d.get('hover_thrust', 10.0), f'{key}.hover_thrust', positive=True),
                    _vector(ex.get('amplitude', [0.0, 0.0, 0.0]), f'{key}.excitation.amplitude',
                            nonneg=True),
                    _vector(ex.get('frequency', [0.5, 0.7, 0.3]), f'{key}.excitation.frequency',
                            nonneg=True))
    if np.linalg.matrix_rank(np.vstack([[r.k_f for r in rotors], rset.torque_rows().T])) < 4:
        raise SceneError(f'{key}.list: the rotors cannot produce every torque axis and the '
                         'thrust (allocation matrix of rank < 4)')
    n = int(math.ceil(duration * 200)) + 1
    if n <= _MAX_CHECK_POINTS:
        u_min = float(np.min(sc.squared_speeds(np.linspace(0.0, duration, max(2, n)))[0]))
    else:        # a long run: the bound of each axis' two sines at their peaks (1.5 A)
        P = sc._allocation
        u_min = float(np.min(sc.hover_thrust * P[:, 0] - np.abs(P[:, 1:]) @ (1.5 * sc.amplitude)))
    if u_min <= 0:
        raise SceneError(f'{key}.excitation.amplitude: too large for hover_thrust (a rotor '
                         'speed would reach zero); lower it or raise hover_thrust')
    return sc
