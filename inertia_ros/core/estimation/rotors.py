"""Multirotor input: rotor speeds and a rotor description give the body torque and momentum.

Rotor ``i`` sits at ``p_i`` (body frame, relative to the centre of mass [m]) and spins about
the common thrust axis ``a`` (unit, body frame; default ``+z``) in the direction ``s_i``
(+1: counter-clockwise about ``+a`` by the right-hand rule, -1: clockwise) at the speed
``w_i`` [rad/s] (its magnitude: the sign of a JointState velocity is not used, the file's
spin is).  With the thrust coefficient ``k_f`` [N/(rad/s)^2] and the drag-torque coefficient
``k_m`` [N m/(rad/s)^2] the torque on the body about the centre of mass is

``tau = sum_i w_i^2 (k_f,i p_i x a - s_i k_m,i a)``

(thrust at the arm; the propeller's drag reacts on the body against its spin), and a rotor of
spin inertia ``J_i`` [kg m^2] carries the internal momentum ``h = sum_i J_i s_i w_i a``, which
enters the momentum form like a wheel's (:mod:`.momentum`: nothing is differentiated).

Motor lag: a rotor with ``time_constant`` ``T > 0`` has its JointState speeds read as
*commands*; the rotor follows them through a first-order lag ``T w' = c - w`` with each
command held until the next (exact discretisation, :func:`motor_lag`; the first command is
taken as steady state).  Give no ``time_constant`` when the JointState carries measured
speeds (ESC telemetry, encoders): those already include the lag.

Uncertainty: the torque is linear in every ``k_f,i`` and ``k_m,i`` and the momentum in every
``J_i``, so a one-sigma change of each coefficient is a known change of the input
(:attr:`.momentum.Momentum.torque_std`, :attr:`~.momentum.Momentum.h_std`), propagated into
the estimate's covariance by its sensitivity as the wheel inertias are.  The coefficients'
errors are taken as independent from rotor to rotor.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._validate import unit_axis
from .momentum import Momentum, as_momentum, nonneg, speeds, spin_inputs

__all__ = ['Rotor', 'RotorSet', 'motor_lag', 'rotors_momentum']


@dataclass(frozen=True)
class Rotor:
    """One rotor (see the module docstring for the model).

    Attributes
    ----------
    joint : str
        Joint name (``sensor_msgs/JointState.name``).
    position : ndarray, shape (3,)
        Rotor hub relative to the centre of mass, body frame [m].
    spin : int
        +1 counter-clockwise about the thrust axis, -1 clockwise.
    k_f : float
        Thrust coefficient [N/(rad/s)^2], > 0.
    k_m : float
        Drag-torque coefficient [N m/(rad/s)^2], >= 0.
    time_constant : float
        First-order motor lag [s] applied to the JointState speeds (commands); 0: measured.
    inertia : float
        Spin inertia of the rotor about its axis [kg m^2] (0: its momentum is neglected).
    k_f_std, k_m_std, inertia_std : float
        One-sigma uncertainties in the units of each coefficient.
    """

    joint: str
    position: np.ndarray
    spin: int
    k_f: float
    k_m: float
    time_constant: float = 0.0
    inertia: float = 0.0
    k_f_std: float = 0.0
    k_m_std: float = 0.0
    inertia_std: float = 0.0

    def __post_init__(self) -> None:
        """Validate every field (one-line ValueError naming the rotor and the field)."""
        if not isinstance(self.joint, str) or not self.joint:
            raise ValueError(f'joint: must be a non-empty name, got {self.joint!r}')
        p = np.asarray(self.position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f'rotor {self.joint}: position must be 3 finite numbers [m], got '
                             f'{self.position!r}')
        p = p.copy()
        p.setflags(write=False)
        object.__setattr__(self, 'position', p)
        if self.spin not in (1, -1) or isinstance(self.spin, bool):
            raise ValueError(f'rotor {self.joint}: spin must be +1 or -1, got {self.spin!r}')
        object.__setattr__(self, 'spin', int(self.spin))
        object.__setattr__(self, 'k_f', nonneg(f'rotor {self.joint}', 'k_f', self.k_f, True))
        for name in ('k_m', 'time_constant', 'inertia', 'k_f_std', 'k_m_std', 'inertia_std'):
            object.__setattr__(self, name, nonneg(f'rotor {self.joint}', name,
                                                  getattr(self, name)))


@dataclass(frozen=True)
class RotorSet:
    """The rotors of a multirotor and their common thrust axis (unit, body frame).

    Attributes
    ----------
    rotors : tuple of Rotor
    axis : ndarray, shape (3,)
        Thrust axis (normalised), default ``[0, 0, 1]``.
    """

    rotors: tuple[Rotor, ...]
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))

    def __post_init__(self) -> None:
        """Validate: at least one rotor, unique joints, a non-zero axis (normalised)."""
        if not self.rotors:
            raise ValueError('rotors: at least one rotor is needed')
        names = [r.joint for r in self.rotors]
        if len(set(names)) != len(names):
            raise ValueError(f'rotors: joint names must be unique, got {names}')
        object.__setattr__(self, 'rotors', tuple(self.rotors))
        object.__setattr__(self, 'axis', unit_axis(self.axis, 'rotors'))

    @property
    def joints(self) -> list[str]:
        """Joint names in column order."""
        return [r.joint for r in self.rotors]

    @property
    def time_constants(self) -> np.ndarray:
        """Motor lags (n,) [s] (0: none)."""
        return np.array([r.time_constant for r in self.rotors])

    def torque_rows(self) -> np.ndarray:
        """Body torque per unit squared speed of each rotor, shape (n, 3) [N m/(rad/s)^2]."""
        a = self.axis
        return np.array([r.k_f * np.cross(r.position, a) - r.spin * r.k_m * a
                         for r in self.rotors]).reshape(len(self.rotors), 3)

    def momentum_rows(self) -> np.ndarray:
        """Momentum per unit speed of each rotor ``J_i s_i a``, shape (n, 3) [N m s/(rad/s)]."""
        return np.array([r.inertia * r.spin * self.axis for r in self.rotors]).reshape(-1, 3)

    def torque(self, speed: Any) -> np.ndarray:
        """Body torque (K, 3) [N m] of the speeds (K, n) [rad/s] (no lag applied)."""
        s = np.abs(speeds(speed, len(self.rotors)))
        return (s * s) @ self.torque_rows()

    def momentum(self, speed: Any) -> np.ndarray:
        """Rotor momentum ``sum J_i s_i |w_i| a`` (K, 3) [N m s]."""
        return np.abs(speeds(speed, len(self.rotors))) @ self.momentum_rows()

    def stated(self) -> list[tuple[str, int, np.ndarray | None, np.ndarray | None]]:
        """The stated inputs for :func:`.momentum.spin_inputs`: one per positive ``k_f_std``,
        ``k_m_std`` and ``inertia_std`` (named ``k_f:<joint>``, ``k_m:<joint>``,
        ``inertia:<joint>``) with its one-sigma change of the torque or of ``h`` per unit
        (squared) speed."""
        a, out = self.axis, []
        for i, r in enumerate(self.rotors):
            for name, std, dh, dtq in (('k_f', r.k_f_std, None, np.cross(r.position, a)),
                                       ('k_m', r.k_m_std, None, -r.spin * a),
                                       ('inertia', r.inertia_std, r.spin * a, None)):
                if std > 0:
                    out.append((f'{name}:{r.joint}', i, None if dh is None else std * dh,
                                None if dtq is None else std * dtq))
        return out

    def inputs(self, t: Any, speed: Any, state: dict[str, Any] | None = None) -> Momentum:
        """The momentum input of a block of JointState speeds (unvalidated, any K >= 1).

        Parameters
        ----------
        t : array_like, shape (K,)
            Stamps [s], increasing.
        speed : array_like, shape (K, n)
            JointState speeds (commands for rotors with a time constant) [rad/s].
        state : dict, optional
            Motor-lag state carried from the previous block (updated in place); None starts
            at steady state.

        Returns
        -------
        Momentum
            ``h``, ``torque`` and their one-sigma changes (:func:`.momentum.spin_inputs`);
            ``noise_cov`` None.
        """
        t = np.asarray(t, dtype=float).reshape(-1)
        s = np.abs(speeds(speed, len(self.rotors)))
        if np.any(self.time_constants > 0):
            s = motor_lag(t, s, self.time_constants, state)
        return spin_inputs(t, s, self.momentum_rows(), self.torque_rows(), self.stated())


def motor_lag(t: np.ndarray, command: np.ndarray, time_constant: np.ndarray,
              state: dict[str, Any] | None = None) -> np.ndarray:
    """First-order lag ``T w' = c - w`` of held commands, sampled at the command stamps.

    Exact for commands held between their stamps: ``w_k = c_{k-1} + (w_{k-1} - c_{k-1})
    exp(-(t_k - t_{k-1}) / T)``.  Columns with ``T = 0`` pass through.

    Parameters
    ----------
    t : ndarray, shape (K,)
        Command stamps [s], increasing.
    command : ndarray, shape (K, n)
        Commanded speeds [rad/s].
    time_constant : ndarray, shape (n,)
        Lags [s] (>= 0).
    state : dict, optional
        ``{'t': last stamp, 'c': last command (n,), 'w': last speed (n,)}`` of the previous
        block, updated in place; None (or empty): the first command is a steady state.

    Returns
    -------
    ndarray, shape (K, n)
        Rotor speeds [rad/s].
    """
    c = np.asarray(command, dtype=float)
    T = np.asarray(time_constant, dtype=float)
    out = c.copy()
    if len(t) == 0:
        return out
    st = state if state is not None else {}
    lag = T > 0
    if st:
        tt = np.concatenate([[st['t']], t])
        cc = np.vstack([st['c'], c])
        w = np.asarray(st['w'], dtype=float).copy()
        start = 0
    else:
        tt, cc = t, c
        w = c[0].copy()
        start = 1
    dt = np.diff(tt)
    for k in range(len(dt)):
        decay = np.exp(-dt[k] / np.where(lag, T, 1.0))
        w = np.where(lag, cc[k] + (w - cc[k]) * decay, cc[k + 1])
        out[start + k] = w
    if state is not None:
        state.update(t=float(t[-1]), c=c[-1].copy(), w=out[-1].copy())
    return out


def rotors_momentum(t: Any, speed: Any, rotors: RotorSet) -> Momentum:
    """:class:`~.momentum.Momentum` of a whole record of rotor speeds (the batch input).

    The momentum's noise covariance comes from the white noise of its component along the
    thrust axis (high-order differences, after any motor lag); the torque's noise is
    estimated from the torque itself by :func:`.momentum.estimate_with_momentum`.
    """
    from .noise import noise_std_from_differences

    m = rotors.inputs(t, speed)
    a = rotors.axis
    # h lies along the thrust axis: the white noise of its component (after any motor lag)
    sd = float(noise_std_from_differences((m.h @ a)[:, None])[0])
    cov = sd ** 2 * np.outer(a, a)
    return as_momentum(Momentum(m.t, m.h, m.h_std, m.names, cov, m.torque, m.torque_std))
