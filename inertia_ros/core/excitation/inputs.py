"""Inputs of the excitation planner: the prior tensor, the limits, the target, a profile.

All SI; every validation error is one ``ValueError`` line naming the field and the value.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scene import SceneError, TorqueComponent
from ..tensor import MATRIX_INDEX, THETA_NAMES, matrix_to_theta
from .actuators import RotorLimits, WheelLimit, axis_peaks

__all__ = ['NEAR_DIAGONAL', 'Limits', 'Prior', 'Profile', 'Target', 'make_prior']

#: Largest ``|I_ij| / sqrt(I_ii I_jj)`` of a near-diagonal prior (principal-moment targets).
NEAR_DIAGONAL = 0.005


@dataclass(frozen=True, eq=False)
class Prior:
    """Prior knowledge of the tensor.

    Attributes
    ----------
    inertia : numpy.ndarray, shape (3, 3)
        Prior value [kg m^2], symmetric positive definite, triangle inequality satisfied.
    std : numpy.ndarray, shape (6,)
        One-sigma uncertainty of ``theta = [ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2].
    """

    inertia: np.ndarray
    std: np.ndarray

    @property
    def theta(self) -> np.ndarray:
        """Prior ``theta`` [kg m^2], shape (6,)."""
        return _theta(self.inertia)

    def near_diagonal(self) -> bool:
        """Products small against the moments (``<= NEAR_DIAGONAL``, see module docstring)."""
        d = np.diag(self.inertia)
        ratio = np.abs(self.theta[3:]) / np.sqrt(d[[0, 0, 1]] * d[[1, 2, 2]])
        return bool(np.all(ratio <= NEAR_DIAGONAL))

    def bodies(self, n: int, seed: int = 0) -> list[np.ndarray]:
        """The prior value and ``n - 1`` physical tensors drawn from ``N(theta, diag(std^2))``."""
        rng = np.random.default_rng(seed)
        out = [self.inertia]
        for _ in range(200 * n):
            if len(out) >= n:
                break
            m = (self.theta + rng.standard_normal(6) * self.std)[MATRIX_INDEX]
            if _physical_problem(m) is None:
                out.append(m)
        return out


def _theta(m: np.ndarray) -> np.ndarray:
    """``[ixx, iyy, izz, ixy, ixz, iyz]`` of a (3, 3) tensor (:func:`matrix_to_theta`)."""
    return matrix_to_theta(m, check_finite=False)


def _physical_problem(m: np.ndarray) -> str | None:
    """Why ``m`` is not a rigid-body tensor, or None."""
    if not np.all(np.isfinite(m)):
        return 'has non-finite values'
    ev = np.linalg.eigvalsh(m)
    if ev[0] <= 0:
        return f'is not positive definite (principal moments {np.round(ev, 6).tolist()})'
    if ev[0] + ev[1] < ev[2] * (1 - 1e-9):
        return ('violates the triangle inequality I1 + I2 >= I3 (principal moments '
                f'{np.round(ev, 6).tolist()})')
    return None


def make_prior(theta: Any, rel_std: float = 0.2, std: Any = None) -> Prior:
    """Validate a prior.

    Parameters
    ----------
    theta : array_like, shape (6,)
        ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2] (matrix elements).
    rel_std : float
        Relative one-sigma uncertainty (0.2 = 20 %) of the moments; the products get
        ``rel_std * max(|I_ij|, 0.05 trace / 3)``.  Used when ``std`` is None.
    std : array_like, shape (6,), optional
        Absolute one-sigma uncertainty [kg m^2] per element (a previous estimate's).

    Raises
    ------
    ValueError
        One line naming the field: non-finite values, a tensor that is not physical, a
        non-positive ``rel_std`` or negative ``std``.
    """
    th = np.asarray(theta, dtype=float)
    if th.shape != (6,) or not np.all(np.isfinite(th)):
        raise ValueError(f'prior inertia: expected 6 finite numbers ixx iyy izz ixy ixz iyz, '
                         f'got {np.asarray(theta).tolist()}')
    m = th[MATRIX_INDEX]
    why = _physical_problem(m)
    if why is not None:
        raise ValueError(f'prior inertia {th.tolist()} {why}: give a physical tensor')
    if std is None:
        if not (math.isfinite(rel_std) and rel_std > 0):
            raise ValueError(f'prior relative std: must be a finite number > 0, got {rel_std}')
        floor = 0.05 * np.trace(m) / 3.0
        s = rel_std * np.concatenate([np.abs(th[:3]), np.maximum(np.abs(th[3:]), floor)])
    else:
        s = np.asarray(std, dtype=float)
        if s.shape != (6,) or not np.all(np.isfinite(s)) or np.any(s < 0):
            raise ValueError(f'prior std: expected 6 finite numbers >= 0, got {s.tolist()}')
    return Prior(m, s)


@dataclass(frozen=True)
class Limits:
    """Actuator, body-rate and sensor figures (SI).

    Attributes
    ----------
    max_torque : tuple of 3 float
        Peak torque per body axis [N m]; with ``wheels`` (``rotors``), at most what they give
        about each axis alone (:func:`.actuators.axis_peaks`; ``inf`` here: only that).
    max_rate : float
        Largest body rate ``|omega|`` [rad/s].
    gyro_rate, torque_rate : float
        Sample rates [Hz]; the torque is commanded and measured at ``torque_rate``.
    gyro_noise : float
        Gyro white-noise std [rad/s].
    torque_noise : float
        Torque-sample noise std [N m] (held over the sample interval).
    torque_noise_rel : float
        Additional torque noise as a share of the profile's RMS per axis (a scene's
        ``noise_rel``).
    initial_omega : tuple of 3 float
        Body rate at the start [rad/s].
    wheels : tuple of WheelLimit
        Reaction wheels producing the torque, with their torque and speed limits
        (:mod:`.actuators`); empty: the body torque is limited per axis only.
    rotors : RotorLimits, optional
        A hovering multirotor's rotors with their speed ranges (not with ``wheels``).
    """

    max_torque: tuple[float, float, float]
    max_rate: float
    gyro_rate: float = 200.0
    torque_rate: float = 50.0
    gyro_noise: float = 0.002
    torque_noise: float = 0.001
    torque_noise_rel: float = 0.0
    initial_omega: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wheels: tuple[WheelLimit, ...] = ()
    rotors: RotorLimits | None = None

    def __post_init__(self) -> None:
        """Refuse non-finite, zero or negative limits (one line naming the field)."""
        mt = tuple(float(v) for v in np.atleast_1d(np.asarray(self.max_torque, dtype=float)))
        if len(mt) == 1:
            mt = mt * 3
        object.__setattr__(self, 'wheels', tuple(self.wheels))
        if self.wheels and self.rotors is not None:
            raise ValueError('wheels and rotors: give one of them')
        if self.wheels and len(mt) == 3:
            mt = tuple(float(v) for v in np.minimum(mt, axis_peaks(self.wheels)))
        if self.rotors is not None and len(mt) == 3:
            mt = tuple(float(v) for v in np.minimum(mt, self.rotors.axis_peaks()))
        object.__setattr__(self, 'max_torque', mt)
        checks = {'max_torque': mt, 'max_rate': (self.max_rate,),
                  'gyro_rate': (self.gyro_rate,), 'torque_rate': (self.torque_rate,),
                  'gyro_noise': (self.gyro_noise,)}
        for name, vals in checks.items():
            if len(vals) != 3 and name == 'max_torque' or not all(
                    math.isfinite(v) and v > 0 for v in vals):
                raise ValueError(f'{name}: must be finite and > 0, got '
                                 f'{list(vals) if len(vals) > 1 else vals[0]}')
        for name in ('torque_noise', 'torque_noise_rel'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f'{name}: must be finite and >= 0, got {v}')
        w0 = np.asarray(self.initial_omega, dtype=float)
        if w0.shape != (3,) or not np.all(np.isfinite(w0)):
            raise ValueError(f'initial_omega: expected 3 finite numbers, got {w0.tolist()}')
        if np.linalg.norm(w0) >= self.max_rate:
            raise ValueError(f'initial_omega: |omega0| = {np.linalg.norm(w0):g} rad/s is already '
                             f'at the body-rate limit {self.max_rate:g} rad/s: raise max_rate')


@dataclass(frozen=True)
class Target:
    """What the manoeuvre must achieve.

    Attributes
    ----------
    rel_std : float or None
        Relative one-sigma target of every targeted quantity (0.01 = 1 %); None with a
        ``duration`` target.
    elements : tuple of str
        Targeted quantities: ``principal`` (the three principal moments) or element names of
        ``THETA_NAMES``.  A product's relative sigma is against ``trace / 3``.
    duration : float or None
        A fixed manoeuvre length [s] instead of a precision: the design minimises the
        criterion at this length.
    max_duration : float
        Longest acceptable manoeuvre [s].
    """

    rel_std: float | None = 0.01
    elements: tuple[str, ...] = ('principal',)
    duration: float | None = None
    max_duration: float = 300.0

    def __post_init__(self) -> None:
        """Refuse a malformed target (one line naming the field)."""
        if not (math.isfinite(self.max_duration) and self.max_duration > 0):
            raise ValueError(f'max_duration: must be finite and > 0, got {self.max_duration}')
        if (self.rel_std is None) == (self.duration is None):
            raise ValueError('target: give exactly one of a relative std or a duration')
        if self.rel_std is not None and not (math.isfinite(self.rel_std) and self.rel_std > 0):
            raise ValueError(f'target relative std: must be finite and > 0, got {self.rel_std}')
        if self.duration is not None and not (
                math.isfinite(self.duration) and 0 < self.duration <= self.max_duration):
            raise ValueError(f'target duration: must be within (0, max_duration = '
                             f'{self.max_duration:g}] s, got {self.duration}')
        for e in self.elements:
            if e != 'principal' and e not in THETA_NAMES:
                raise ValueError(f'target element {e!r}: must be principal or one of '
                                 f'{", ".join(THETA_NAMES)}')
        if not self.elements:
            raise ValueError('target elements: give at least one')


@dataclass(frozen=True)
class Profile:
    """A torque profile: scene torque components (``docs/SCENES.md``) and a name."""

    name: str
    components: tuple[Mapping[str, Any], ...]

    def scaled(self, factor: Any) -> Profile:
        """The profile with every component's amplitude multiplied by ``factor`` (3,)."""
        f = np.broadcast_to(np.asarray(factor, dtype=float), (3,))
        comps = []
        for c in self.components:
            a = np.broadcast_to(np.asarray(c['amplitude'], dtype=float), (3,)) * f
            comps.append({**c, 'amplitude': [float(v) for v in a]})
        return Profile(self.name, tuple(comps))

    def torque(self, t: np.ndarray, duration: float, seed: int = 0) -> np.ndarray:
        """Commanded torque [N m] at the command times ``t`` (M,), shape (M, 3).

        Random draws (PRBS levels, random phases) follow the simulator's seeding, so a scene
        built by :func:`scene_dict` with the same seed commands the same values.
        """
        r_torque = np.random.default_rng(seed).spawn(7)[0]
        out = np.zeros((t.size, 3))
        rngs = r_torque.spawn(len(self.components))
        for i, (c, r) in enumerate(zip(self.components, rngs, strict=True)):
            try:
                comp = TorqueComponent.from_dict(dict(c), f'torque[{i}]', duration)
            except SceneError as exc:
                raise ValueError(str(exc)) from None
            out += comp.evaluate(t, r)
        return out
