"""Wheels and flywheels in a scene: the ``wheels`` section and the body dynamics with them.

Scene YAML (see ``docs/SCENES.md``)::

    wheels:
      rate: 100.0                 # JointState rate [Hz]
      speed_noise_std: 0.05       # wheel-speed white noise [rad/s]
      list:
        - joint: rw1
          axis: [1, 0, 0]         # unit spin axis, body frame
          inertia: 1.2e-3         # kg m^2 about the axis (true value)
          speed: {offset: 100, amplitude: 300, frequency: 0.13, phase: 0.0}   # rad/s, Hz, rad

Each wheel spins relative to the body at ``w_k(t) = offset + amplitude sin(2 pi f t + phase)``
(a speed-controlled wheel); its momentum ``h = sum_k J_k w_k a_k`` acts on the body through
``I w' = tau - h' - w x (I w + h)`` with ``I`` the whole body's tensor (wheels included).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ['WheelScene', 'WheelSpec', 'integrate_with_wheels', 'parse_wheels', 'wheel_streams']


@dataclass(frozen=True, eq=False)
class WheelSpec:
    """One simulated wheel: joint name, unit axis (3,), inertia [kg m^2] and speed profile
    ``offset + amplitude sin(2 pi frequency t + phase)`` [rad/s]."""

    joint: str
    axis: np.ndarray
    inertia: float
    offset: float
    amplitude: float
    frequency: float
    phase: float

    def speed(self, t: np.ndarray) -> np.ndarray:
        """Speed [rad/s] at times ``t`` [s]."""
        return self.offset + self.amplitude * np.sin(2 * np.pi * self.frequency * t + self.phase)

    def accel(self, t: np.ndarray) -> np.ndarray:
        """Speed derivative [rad/s^2] at times ``t`` [s]."""
        om = 2 * np.pi * self.frequency
        return self.amplitude * om * np.cos(om * t + self.phase)


@dataclass(frozen=True, eq=False)
class WheelScene:
    """The ``wheels`` section: the wheels, the JointState rate [Hz] and speed noise [rad/s]."""

    wheels: tuple[WheelSpec, ...]
    rate: float
    speed_noise_std: float

    def momentum(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True ``h`` (n, 3) [N m s] and ``h'`` (n, 3) [N m] at times ``t`` (n,) [s]."""
        t = np.asarray(t, dtype=float)
        h = np.zeros((len(t), 3))
        hd = np.zeros((len(t), 3))
        for wh in self.wheels:
            h += np.outer(wh.speed(t), wh.inertia * wh.axis)
            hd += np.outer(wh.accel(t), wh.inertia * wh.axis)
        return h, hd

    def max_hdot(self) -> float:
        """Largest ``|h'|`` [N m] over the run (bounds the integrator's substeps)."""
        return sum(abs(w.amplitude) * 2 * np.pi * w.frequency * w.inertia for w in self.wheels)


def parse_wheels(value: Any, key: str = 'wheels') -> WheelScene:
    """Validate the ``wheels`` section of a scene.

    Raises
    ------
    ValueError
        (a :class:`~inertia_ros.core.scene.SceneError`) naming the dotted key.
    """
    from .scene import SceneError, _mapping, _number, _string, _vector

    d = _mapping(value, key, ('rate', 'speed_noise_std', 'list'))
    rate = _number(d.get('rate', 100.0), f'{key}.rate', positive=True)
    noise = _number(d.get('speed_noise_std', 0.0), f'{key}.speed_noise_std', nonneg=True)
    items = d.get('list')
    if not isinstance(items, list) or not items:
        raise SceneError(f'{key}.list: must be a non-empty list of wheels')
    out = []
    for i, it in enumerate(items):
        k = f'{key}.list[{i}]'
        m = _mapping(it, k, ('joint', 'axis', 'inertia', 'speed'))
        for req in ('joint', 'axis', 'inertia'):
            if req not in m:
                raise SceneError(f'{k}.{req}: missing')
        joint = _string(m['joint'], f'{k}.joint')
        axis = _vector(m['axis'], f'{k}.axis')
        if not np.linalg.norm(axis) > 0:
            raise SceneError(f'{k}.axis: must not be zero')
        sp = _mapping(m.get('speed'), f'{k}.speed', ('offset', 'amplitude', 'frequency', 'phase'))
        out.append(WheelSpec(
            joint, axis / np.linalg.norm(axis),
            _number(m['inertia'], f'{k}.inertia', positive=True),
            _number(sp.get('offset', 0.0), f'{k}.speed.offset'),
            _number(sp.get('amplitude', 0.0), f'{k}.speed.amplitude'),
            _number(sp.get('frequency', 0.0), f'{k}.speed.frequency', nonneg=True),
            _number(sp.get('phase', 0.0), f'{k}.speed.phase')))
    names = [w.joint for w in out]
    if len(set(names)) != len(names):
        raise SceneError(f'{key}.list: joint names must be unique, got {names}')
    return WheelScene(tuple(out), rate, noise)


def integrate_with_wheels(t_events: np.ndarray, torque: np.ndarray, inertia: np.ndarray,
                          omega0: np.ndarray, wheels: WheelScene,
                          max_step_angle: float = 1.0e-2) -> tuple[np.ndarray, np.ndarray]:
    """RK4 of ``I w' = tau - h'(t) - w x (I w + h(t))`` and the attitude.

    Parameters
    ----------
    t_events : ndarray, shape (K,)
        Strictly increasing report times [s].
    torque : ndarray, shape (K - 1, 3)
        External torque [N m], constant on each ``[t_k, t_{k+1})``.
    inertia : ndarray, shape (3, 3) or (K - 1, 3, 3)
        Whole-body tensor [kg m^2].
    omega0 : ndarray, shape (3,)
        Angular velocity at ``t_events[0]`` [rad/s].
    wheels : WheelScene or RotorScene
        Wheel (rotor) speeds are prescribed functions of time (``h`` smooth: RK4 stays 4th
        order); a rotor scene's ``torque(t)`` is added to ``torque``.
    max_step_angle : float
        Largest body rotation per substep [rad].

    Returns
    -------
    omega : ndarray, shape (K, 3)
        [rad/s] at each event time.
    quat : ndarray, shape (K, 4)
        Attitude ``[w, x, y, z]`` (body -> inertial) at each event time.
    """
    t_events = np.asarray(t_events, dtype=float)
    k = len(t_events)
    inertia = np.broadcast_to(np.asarray(inertia, dtype=float), (max(k - 1, 1), 3, 3))
    # largest |h'| (and actuator torque) [N m]: the rate change it can cause bounds the substep
    hdmax = wheels.max_hdot()
    extra = getattr(wheels, 'torque', None)      # rotors: their thrust and drag torques

    def f(t: float, y: np.ndarray, I: np.ndarray, Ii: np.ndarray, tq: np.ndarray
          ) -> np.ndarray:
        w, q = y[:3], y[3:]
        h, hd = wheels.momentum(np.array([t]))
        r = tq - hd[0] - np.cross(w, I @ w + h[0])
        if extra is not None:
            r = r + extra(np.array([t]))[0]
        qw, qx, qy, qz = q
        wx, wy, wz = w
        dq = 0.5 * np.array([-(qx * wx + qy * wy + qz * wz), qw * wx + qy * wz - qz * wy,
                             qw * wy + qz * wx - qx * wz, qw * wz + qx * wy - qy * wx])
        return np.concatenate([Ii @ r, dq])

    from .scene import MAX_ACTUATOR_WORK, too_many_substeps

    n_joints = max(1, len(wheels.wheels))
    # substeps x joints (the cost of the right-hand side): one substep per segment (their
    # number is the scene's sample budget), plus what the rotation needs
    budget = MAX_ACTUATOR_WORK + k * n_joints
    y = np.concatenate([np.asarray(omega0, dtype=float).reshape(3), [1.0, 0.0, 0.0, 0.0]])
    rows = [y.copy()]
    for j in range(k - 1):
        I = inertia[j]
        Ii = np.linalg.inv(I)
        tq = np.asarray(torque[j], dtype=float)
        t0, dt = t_events[j], t_events[j + 1] - t_events[j]
        wmax = float(np.linalg.norm(y[:3])) + float(np.linalg.norm(Ii, 2)) * (
            float(np.linalg.norm(tq)) + hdmax) * dt
        steps = wmax * dt / max_step_angle
        if not steps * n_joints < budget:    # also inf / nan: refused before the work
            raise too_many_substeps(t0, wmax, MAX_ACTUATOR_WORK / n_joints)
        n = max(1, math.ceil(steps))
        budget -= n * n_joints
        hs = dt / n
        for i in range(n):
            t = t0 + i * hs
            k1 = f(t, y, I, Ii, tq)
            k2 = f(t + hs / 2, y + hs / 2 * k1, I, Ii, tq)
            k3 = f(t + hs / 2, y + hs / 2 * k2, I, Ii, tq)
            k4 = f(t + hs, y + hs * k3, I, Ii, tq)
            y = y + hs / 6 * (k1 + 2 * (k2 + k3) + k4)
        y[3:] /= np.linalg.norm(y[3:])
        rows.append(y.copy())
    out = np.array(rows)
    return out[:, :3].copy(), out[:, 3:].copy()


def wheel_streams(wheels: WheelScene, duration: float, rng: np.random.Generator,
                  stamp_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured JointState stream: times (K,) [s], speeds (K, n) [rad/s] with noise, and the
    true speeds (K, n)."""
    n = int(math.floor(duration * wheels.rate + 1e-9)) + 1
    t = np.arange(n) / wheels.rate
    true = np.column_stack([w.speed(t) for w in wheels.wheels])
    meas = true + (rng.normal(0.0, wheels.speed_noise_std, true.shape)
                   if wheels.speed_noise_std > 0 else 0.0)
    return t + stamp_offset, meas, true

