"""Reaction-wheel limits of the planner and the exciter: wheel torque and wheel speed.

A wheel ``k`` (unit spin axis ``a_k`` in the body frame, spin inertia ``J_k``) driven by its
motor torque ``m_k`` pushes the body with ``-m_k a_k``, so the body torque is
``tau = -A m`` with ``A = [a_1 ... a_n]`` (3, n).  The body torques the wheels can produce
are the image of the box ``|m_k| <= max_torque_k`` (a zonotope).  The planner allocates a
body torque to the wheels by the minimum-norm allocation ``m = -pinv(A) tau`` (what a wheel
controller commonly does): for three independent wheels it is the only allocation, so the
check is the exact polytope constraint; for a redundant set it is conservative.

The wheel's speed relative to the body moves by ``m_k / J_k`` (the body's angular
acceleration, ``J_k / I`` smaller, is neglected), so over a profile it is
``w_k(t) = w_k(0) + (1 / J_k) int_0^t m_k dt``: a multisine's integral is bounded, and the
design must keep ``|w_k(t)| <= max_speed_k`` from the initial wheel speed on.

Rotors of a hovering multirotor (:class:`RotorLimits`): the squared speeds ``u`` give the
thrust ``k_f . u`` and the body torque ``R^T u`` (``R`` the torque rows), so the speeds that
hold ``hover_thrust`` and make ``tau`` are ``u = pinv(M) [hover_thrust, tau]`` (the scenes'
allocation, ``docs/SCENES.md``; the only one for four rotors); the design keeps every rotor's
speed within ``[min_speed, max_speed]``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validate import unit_axis

__all__ = ['RotorLimits', 'WheelLimit', 'allocation', 'axis_peaks', 'box_scale',
           'wheel_speed_scale', 'wheel_speeds', 'wheel_torque_scale', 'wheel_torques']


@dataclass(frozen=True, eq=False)
class WheelLimit:
    """One reaction wheel's limits.

    Attributes
    ----------
    joint : str
        Joint name (JointState.name).
    axis : numpy.ndarray, shape (3,)
        Unit spin axis in the body (gyro) frame (normalised here).
    inertia : float
        Spin inertia [kg m^2], > 0.
    max_torque : float
        Largest motor torque [N m], > 0 (``inf``: not limited).
    max_speed : float
        Largest wheel speed magnitude [rad/s], > 0 (``inf``: not limited).
    initial_speed : float
        Wheel speed at the start [rad/s], ``|initial_speed| < max_speed``.
    """

    joint: str
    axis: np.ndarray
    inertia: float
    max_torque: float = math.inf
    max_speed: float = math.inf
    initial_speed: float = 0.0

    def __post_init__(self) -> None:
        """Refuse a zero axis, non-positive inertia or limits, a start at the speed limit."""
        object.__setattr__(self, 'axis', unit_axis(self.axis, f'wheel {self.joint}'))
        for name in ('inertia', 'max_torque', 'max_speed'):
            v = float(getattr(self, name))
            if math.isnan(v) or not v > 0 or (name == 'inertia' and math.isinf(v)):
                raise ValueError(f'wheel {self.joint}: {name} must be > 0, got {v:g}')
            object.__setattr__(self, name, v)
        w0 = float(self.initial_speed)
        if not math.isfinite(w0) or abs(w0) >= self.max_speed:
            raise ValueError(f'wheel {self.joint}: initial speed {w0:g} rad/s must be finite '
                             f'and below max_speed {self.max_speed:g} rad/s')
        object.__setattr__(self, 'initial_speed', w0)


def allocation(wheels: Sequence[WheelLimit]) -> np.ndarray:
    """The minimum-norm allocation ``P`` (n, 3): motor torques ``m = P tau`` [N m] that
    produce the body torque ``tau`` (``P = -pinv(A)``).

    Raises
    ------
    ValueError
        The wheel axes do not span the three body axes (the body torque about some axis
        cannot be produced).
    """
    A = np.stack([w.axis for w in wheels], axis=1)
    if np.linalg.matrix_rank(A, tol=1e-6) < 3:
        raise ValueError(f'the {len(wheels)} wheel axes span only '
                         f'{np.linalg.matrix_rank(A, tol=1e-6)} body axes: the plan needs '
                         'torque about every axis (give wheels whose axes span 3-D)')
    return -np.linalg.pinv(A)


def axis_peaks(wheels: Sequence[WheelLimit]) -> np.ndarray:
    """Largest body torque [N m] about each body axis alone within the wheel torques, (3,):
    ``min_k max_torque_k / |P_ki|`` (the box a per-axis peak may use when one axis at a
    time is driven; several at once are checked by :func:`wheel_torque_scale`)."""
    P = np.abs(allocation(wheels))
    mt = np.array([w.max_torque for w in wheels])[:, None]
    with np.errstate(divide='ignore'):
        ratio = np.where(P > 1e-12, mt / np.where(P > 1e-12, P, 1.0), np.inf)
    return np.min(ratio, axis=0)


def wheel_torques(wheels: Sequence[WheelLimit], tau: np.ndarray) -> np.ndarray:
    """Motor torques [N m], shape (M, n), producing body torques ``tau`` (M, 3)."""
    return np.asarray(tau, dtype=float) @ allocation(wheels).T


def wheel_speeds(wheels: Sequence[WheelLimit], t: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Wheel speeds [rad/s], shape (M, n), under the body torque ``tau`` (M, 3) held from
    ``t[j]`` to ``t[j + 1]`` (zero-order hold), from each wheel's initial speed."""
    m = wheel_torques(wheels, tau)
    dt = np.diff(np.asarray(t, dtype=float))
    j = np.array([w.inertia for w in wheels])
    w0 = np.array([w.initial_speed for w in wheels])
    dh = np.vstack([np.zeros((1, len(wheels))), np.cumsum(m[:-1] * dt[:, None], axis=0)])
    return w0 + dh / j


def wheel_torque_scale(wheels: Sequence[WheelLimit], tau: np.ndarray) -> np.ndarray:
    """Largest factor ``<= 1`` per wheel, (n,), by which ``tau`` (M, 3) may be scaled and
    keep that wheel's motor torque within its ``max_torque``."""
    peak = np.max(np.abs(wheel_torques(wheels, tau)), axis=0)
    mt = np.array([w.max_torque for w in wheels])
    return np.minimum(1.0, np.where(peak > 0, mt / np.where(peak > 0, peak, 1.0), 1.0))


def wheel_speed_scale(wheels: Sequence[WheelLimit], t: np.ndarray, tau: np.ndarray
                      ) -> np.ndarray:
    """Largest factor ``<= 1`` per wheel, (n,), by which ``tau`` may be scaled and keep that
    wheel's speed ``w0 + s dw(t)`` within ``+- max_speed`` at every ``t``."""
    w0 = np.array([w.initial_speed for w in wheels])
    dw = wheel_speeds(wheels, t, tau) - w0                     # (M, n), linear in the scale
    cap = np.array([w.max_speed for w in wheels])
    return box_scale(w0, dw, -cap, cap)


def box_scale(x0: np.ndarray, dx: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Largest factor ``s <= 1`` per column, (n,), with ``lo <= x0 + s dx <= hi`` for every
    row of ``dx`` (M, n); ``x0``, ``lo``, ``hi`` (n,) with ``lo < x0 < hi``."""
    up = np.where(dx > 0, (hi - x0) / np.where(dx > 0, dx, 1.0), np.inf)
    down = np.where(dx < 0, (x0 - lo) / np.where(dx < 0, -dx, 1.0), np.inf)
    return np.minimum(1.0, np.min(np.minimum(up, down), axis=0))


@dataclass(frozen=True, eq=False)
class RotorLimits:
    """A hovering multirotor's rotors and their speed ranges.

    Attributes
    ----------
    joints : tuple of str
        Rotor joint names (n).
    k_f : numpy.ndarray, shape (n,)
        Thrust coefficients [N/(rad/s)^2].
    torque_rows : numpy.ndarray, shape (n, 3)
        Body torque per unit squared speed [N m/(rad/s)^2].
    min_speed, max_speed : numpy.ndarray, shape (n,)
        Speed range of each rotor [rad/s], ``0 <= min < max``.
    hover_thrust : float
        Total thrust held while exciting [N], > 0.
    """

    joints: tuple[str, ...]
    k_f: np.ndarray
    torque_rows: np.ndarray
    min_speed: np.ndarray
    max_speed: np.ndarray
    hover_thrust: float

    def __post_init__(self) -> None:
        """Refuse rotors that cannot make every torque axis or cannot hover in range."""
        n = len(self.joints)
        M = np.vstack([np.asarray(self.k_f, float).reshape(1, n),
                       np.asarray(self.torque_rows, float).reshape(n, 3).T])
        if np.linalg.matrix_rank(M, tol=1e-12 * np.max(np.abs(M))) < 4:
            raise ValueError(f'the {n} rotors cannot set the thrust and every torque axis '
                             'independently (give a rotor set that can)')
        if not (math.isfinite(self.hover_thrust) and self.hover_thrust > 0):
            raise ValueError(f'hover thrust must be > 0 N, got {self.hover_thrust:g}')
        alloc = np.linalg.pinv(M)
        object.__setattr__(self, 'alloc', alloc)
        u0 = alloc[:, 0] * self.hover_thrust
        for k, j in enumerate(self.joints):
            lo, hi = float(self.min_speed[k]), float(self.max_speed[k])
            w = math.sqrt(max(u0[k], 0.0))
            if not lo ** 2 < u0[k] < hi ** 2:
                raise ValueError(f'rotor {j}: hovering at {self.hover_thrust:g} N needs '
                                 f'{w:.4g} rad/s, outside its speed range [{lo:g}, {hi:g}] '
                                 'rad/s (change the hover thrust or the range)')

    def squared_speeds(self, tau: np.ndarray) -> np.ndarray:
        """Squared rotor speeds [(rad/s)^2], (M, n), hovering and making ``tau`` (M, 3)."""
        return self.alloc[:, 0] * self.hover_thrust + np.asarray(tau, float) @ \
            self.alloc[:, 1:].T

    def speed_scale(self, tau: np.ndarray) -> np.ndarray:
        """Largest factor ``<= 1`` per rotor, (n,), keeping its speed in range under
        ``s tau`` (the squared speed is linear in ``s``)."""
        u0 = self.alloc[:, 0] * self.hover_thrust
        return box_scale(u0, self.squared_speeds(tau) - u0, self.min_speed ** 2,
                         self.max_speed ** 2)

    def speed_share(self, tau: np.ndarray) -> np.ndarray:
        """Largest share of each rotor's room from hover to its speed limits used, (n,)."""
        u0 = self.alloc[:, 0] * self.hover_thrust
        du = self.squared_speeds(tau) - u0
        up = np.max(du, axis=0) / (self.max_speed ** 2 - u0)
        down = np.max(-du, axis=0) / (u0 - self.min_speed ** 2)
        return np.maximum(up, down)

    def axis_peaks(self) -> np.ndarray:
        """Largest body torque [N m] about each axis alone within the speed ranges, (3,)."""
        u0 = self.alloc[:, 0] * self.hover_thrust
        room = np.minimum(self.max_speed ** 2 - u0, u0 - self.min_speed ** 2)[:, None]
        a = np.abs(self.alloc[:, 1:])
        with np.errstate(divide='ignore'):
            return np.min(np.where(a > 0, room / np.where(a > 0, a, 1.0), np.inf), axis=0)
