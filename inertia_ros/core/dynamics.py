"""Rigid-body dynamics on arrays: Euler's equations, momentum, energy, power, pendulum, and
the parallel-axis theorem.

SI units throughout (kg, m, kg m^2, rad/s, rad/s^2, N, N m, W); every function accepts a
(3, 3) inertia matrix or anything with ``.matrix`` (an :class:`~.inertia.InertiaTensor`) and
is vectorised over leading dimensions where its docstring says so.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ._validate import (
    as_float_array,
    as_mass,
    as_unit_axis,
    as_vector3,
    as_vectors,
    require_finite,
)
from .tensor import as_inertia_matrix

__all__ = [
    'STANDARD_GRAVITY',
    'angular_momentum',
    'angular_momentum_about_point',
    'euler_omega_dot',
    'euler_torque',
    'kinetic_energy',
    'kinetic_energy_rate',
    'mechanical_power',
    'moment_about_axis',
    'parallel_axis',
    'parallel_axis_to_com',
    'pendulum_period',
    'power_identity_residual',
    'rotational_kinetic_energy',
]


# ---------------------------------------------------------------------------------------------
# Euler's equations
# ---------------------------------------------------------------------------------------------
def _matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m @ v`` for m (3, 3) or (..., 3, 3) and v (..., 3), broadcasting leading dims."""
    if m.ndim == 2:
        return v @ m.T
    return np.einsum('...ij,...j->...i', m, v)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (faster than np.cross for small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _as_stack_matrix(I: Any) -> np.ndarray:
    """Validated (3, 3) or (..., 3, 3) inertia for broadcasting in Euler's equations."""
    return as_inertia_matrix(I, 'I', stacked=True)


def euler_torque(I: Any, omega: Any, omega_dot: Any) -> np.ndarray:
    """Torque from Euler's rotational equation, ``tau = I w_dot + w x (I w)``.

    All quantities about the centre of mass, in body axes.  Vectorised: leading dimensions
    of ``omega`` and ``omega_dot`` (and of ``I`` if stacked) broadcast.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    omega_dot : array_like, shape (..., 3)
        Angular acceleration [rad/s^2].

    Returns
    -------
    ndarray, shape (..., 3)
        Torque about the centre of mass [N m].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I``, or shapes that do not broadcast.
    """
    m = _as_stack_matrix(I)
    w = as_vectors(omega, 'omega')
    wd = as_vectors(omega_dot, 'omega_dot')
    try:
        return _matvec(m, wd) + _cross(w, _matvec(m, w))
    except ValueError as exc:
        raise ValueError(f'omega, omega_dot: shapes {w.shape}, {wd.shape} and I {m.shape} do '
                         f'not broadcast ({exc})') from None


def euler_omega_dot(I: Any, omega: Any, tau: Any) -> np.ndarray:
    """Angular acceleration from Euler's equation, ``w_dot = I^-1 (tau - w x (I w))``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2]; must be invertible.
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    tau : array_like, shape (..., 3)
        Torque about the centre of mass [N m].

    Returns
    -------
    ndarray, shape (..., 3)
        Angular acceleration [rad/s^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric or singular ``I``.
    """
    m = _as_stack_matrix(I)
    w = as_vectors(omega, 'omega')
    t = as_vectors(tau, 'tau')
    try:
        rhs = t - _cross(w, _matvec(m, w))
    except ValueError as exc:
        raise ValueError(f'omega, tau: shapes {w.shape}, {t.shape} and I {m.shape} do not '
                         f'broadcast ({exc})') from None
    lam = np.linalg.eigvalsh(m)
    scale = np.max(np.abs(lam), axis=-1)
    if np.any(np.abs(lam).min(axis=-1) <= 1e-14 * scale) or np.any(scale == 0.0):
        raise ValueError('I: singular (a principal moment is zero), so Euler\'s equation cannot '
                         'be solved for omega_dot')
    if m.ndim == 2:                                    # one inertia: invert once, multiply
        return _matvec(np.linalg.inv(m), rhs)
    batch = np.broadcast_shapes(m.shape[:-2], rhs.shape[:-1])
    m_b = np.broadcast_to(m, batch + (3, 3))
    rhs_b = np.broadcast_to(rhs, batch + (3,))[..., None]
    return np.linalg.solve(m_b, rhs_b)[..., 0]


# ---------------------------------------------------------------------------------------------
# parallel-axis theorem and scalar helpers on arrays
# ---------------------------------------------------------------------------------------------
#: Standard gravity [m/s^2] (the default for pendulum periods).
STANDARD_GRAVITY = 9.80665




def shift_term(mass: float, r: np.ndarray) -> np.ndarray:
    """``m (|r|^2 1 - r r^T)``, shape (3, 3) [kg m^2]."""
    return mass * (np.dot(r, r) * np.eye(3) - np.outer(r, r))


def parallel_axis(I_com: Any, mass: Any, r: Any) -> np.ndarray:
    """Parallel-axis theorem in tensor form: inertia about a point P from that about the CoM.

    ``I_P = I_C + m (|r|^2 1 - r r^T)`` with ``r = P - C`` (the sign of ``r`` does not matter).

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass C [kg m^2].
    mass : float
        Mass [kg], >= 0.
    r : array_like, shape (3,)
        Offset between P and C [m], in the frame of ``I_com``.

    Returns
    -------
    ndarray, shape (3, 3)
        Inertia about P [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I_com`` or negative ``mass``.
    """
    return as_inertia_matrix(I_com, 'I_com') + shift_term(as_mass(mass), as_vector3(r, 'r'))


def parallel_axis_to_com(I_point: Any, mass: Any, r: Any) -> np.ndarray:
    """Inverse parallel-axis theorem: inertia about the CoM from that about a point P.

    ``I_C = I_P - m (|r|^2 1 - r r^T)`` with ``r = P - C``.

    Parameters
    ----------
    I_point : array_like, shape (3, 3), or InertiaTensor
        Inertia about P [kg m^2].
    mass : float
        Mass [kg], >= 0.
    r : array_like, shape (3,)
        Offset between P and C [m].

    Returns
    -------
    ndarray, shape (3, 3)
        Inertia about the centre of mass [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I_point`` or negative ``mass``.
    """
    return (as_inertia_matrix(I_point, 'I_point')
            - shift_term(as_mass(mass), as_vector3(r, 'r')))


def moment_about_axis(I: Any, axis: Any) -> np.ndarray | float:
    """Moment of inertia about an axis through the reference point, ``n^T I n`` with |n| = 1.

    Parameters
    ----------
    I : array_like, shape (3, 3), or InertiaTensor
        Inertia matrix [kg m^2].
    axis : array_like, shape (3,) or (..., 3)
        Axis direction(s), any non-zero length (normalised here).

    Returns
    -------
    float or ndarray, shape (...)
        Moment(s) of inertia [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I`` or a zero axis.
    """
    m = as_inertia_matrix(I, 'I')
    n = as_unit_axis(axis)
    val = np.einsum('...i,ij,...j->...', n, m, n)
    return float(val) if val.ndim == 0 else val



# ---------------------------------------------------------------------------------------------
# dynamics on arrays
# ---------------------------------------------------------------------------------------------
def angular_momentum(I: Any, omega: Any) -> np.ndarray:
    """Angular momentum about the centre of mass, ``L = I w``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s], same frame as ``I``.

    Returns
    -------
    ndarray, shape (..., 3)
        Angular momentum [kg m^2/s].
    """
    return np.einsum('...ij,...j->...i', _as_stack_matrix(I), as_vectors(omega, 'omega'))


def angular_momentum_about_point(I_com: Any, mass: Any, omega: Any, r_pc: Any,
                                 v_com: Any) -> np.ndarray:
    """Angular momentum about a point P, ``L_P = I_C w + m r_PC x v_C``.

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass C [kg m^2].
    mass : float
        Mass [kg].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    r_pc : array_like, shape (..., 3)
        Position of C relative to P, ``C - P`` [m].
    v_com : array_like, shape (..., 3)
        Velocity of C [m/s] (relative to the frame P is fixed in).

    Returns
    -------
    ndarray, shape (..., 3)
        Angular momentum about P [kg m^2/s]; all vectors in one frame.
    """
    m = as_mass(mass)
    r = as_vectors(r_pc, 'r_pc')
    v = as_vectors(v_com, 'v_com')
    return angular_momentum(I_com, omega) + m * np.cross(r, v)


def rotational_kinetic_energy(I: Any, omega: Any) -> np.ndarray | float:
    """Rotational kinetic energy ``T_rot = 1/2 w . (I w)``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].

    Returns
    -------
    float or ndarray, shape (...)
        Energy [J].
    """
    w = as_vectors(omega, 'omega')
    val = 0.5 * np.einsum('...i,...i->...', w, angular_momentum(I, w))
    return float(val) if np.ndim(val) == 0 else val


def kinetic_energy(I_com: Any, mass: Any, omega: Any, v_com: Any) -> np.ndarray | float:
    """Total kinetic energy ``T = 1/2 m |v_C|^2 + 1/2 w . (I_C w)`` (Koenig's theorem).

    Parameters
    ----------
    I_com : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    mass : float
        Mass [kg].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    v_com : array_like, shape (..., 3)
        Velocity of the centre of mass [m/s].

    Returns
    -------
    float or ndarray, shape (...)
        Energy [J].
    """
    v = as_vectors(v_com, 'v_com')
    val = 0.5 * as_mass(mass) * np.einsum('...i,...i->...', v, v) \
        + rotational_kinetic_energy(I_com, omega)
    return float(val) if np.ndim(val) == 0 else val


def pendulum_period(I_pivot: Any, mass: Any, h: Any,
                    g: float = STANDARD_GRAVITY) -> np.ndarray | float:
    """Small-amplitude period of a physical pendulum, ``2 pi sqrt(I / (m g h))``.

    Parameters
    ----------
    I_pivot : float or array_like
        Moment of inertia about the pivot axis [kg m^2], > 0.
    mass : float
        Mass [kg], > 0.
    h : float or array_like
        Distance from the pivot axis to the centre of mass [m], > 0.
    g : float
        Gravitational acceleration [m/s^2], > 0.

    Returns
    -------
    float or ndarray
        Period [s].

    Raises
    ------
    ValueError
        Non-positive or non-finite inputs.
    """
    i = as_float_array(I_pivot, 'I_pivot')
    hh = as_float_array(h, 'h')
    for arr, name in ((i, 'I_pivot'), (hh, 'h')):
        require_finite(arr, name)
        if np.any(arr <= 0.0):
            raise ValueError(f'{name}: must be > 0, got {arr.min():.6g}')
    m = as_mass(mass, positive=True)
    gg = as_mass(g, 'g', positive=True)
    val = 2.0 * np.pi * np.sqrt(i / (m * gg * hh))
    return float(val) if np.ndim(val) == 0 else val


def mechanical_power(velocity: Any, force: Any, omega: Any, torque: Any) -> np.ndarray | float:
    """Power delivered to a rigid body, ``P = v_C . F + w . M``.

    ``F`` is the resultant force and ``M`` the resultant torque about the centre of mass; ``v_C``
    and ``F`` share one frame, ``w`` and ``M`` share one frame (e.g. body axes).

    Parameters
    ----------
    velocity : array_like, shape (..., 3)
        Velocity of the centre of mass [m/s].
    force : array_like, shape (..., 3)
        Resultant force [N].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    torque : array_like, shape (..., 3)
        Resultant torque about the centre of mass [N m].

    Returns
    -------
    float or ndarray, shape (...)
        Power [W].
    """
    v = as_vectors(velocity, 'velocity')
    f = as_vectors(force, 'force')
    w = as_vectors(omega, 'omega')
    t = as_vectors(torque, 'torque')
    val = np.einsum('...i,...i->...', v, f) + np.einsum('...i,...i->...', w, t)
    return float(val) if np.ndim(val) == 0 else val


def kinetic_energy_rate(I_com: Any, mass: Any, velocity: Any, acceleration: Any, omega: Any,
                        omega_dot: Any) -> np.ndarray | float:
    """Analytic ``dT/dt = m v_C . a_C + w . (I_C w_dot)`` for a rigid body.

    Valid with ``v``, ``a`` in an inertial frame and ``w``, ``w_dot``, ``I_C`` in body axes
    (where ``I_C`` is constant).  By Newton and Euler it equals :func:`mechanical_power`
    (the power identity ``dT/dt = v . F + w . M``), because ``w . (w x I w) = 0``.

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    mass : float
        Mass [kg].
    velocity, acceleration : array_like, shape (..., 3)
        Velocity [m/s] and acceleration [m/s^2] of the centre of mass.
    omega, omega_dot : array_like, shape (..., 3)
        Angular velocity [rad/s] and acceleration [rad/s^2].

    Returns
    -------
    float or ndarray, shape (...)
        Rate of change of kinetic energy [W].
    """
    v = as_vectors(velocity, 'velocity')
    a = as_vectors(acceleration, 'acceleration')
    w = as_vectors(omega, 'omega')
    val = as_mass(mass) * np.einsum('...i,...i->...', v, a) \
        + np.einsum('...i,...i->...', w, angular_momentum(I_com, omega_dot))
    return float(val) if np.ndim(val) == 0 else val


def power_identity_residual(t: Any, energy: Any, velocity: Any, force: Any, omega: Any,
                            torque: Any) -> np.ndarray:
    """Check the power identity on sampled data: ``dT/dt - (v . F + w . M)``.

    ``dT/dt`` is taken from the sampled kinetic energy by second-order finite differences
    (:func:`numpy.gradient`), so the residual is O(dt^2) for smooth motion and exposes
    wrong inertia, wrong frames or unmodelled forces/torques.

    Parameters
    ----------
    t : array_like, shape (N,)
        Strictly increasing sample times [s], N >= 3.
    energy : array_like, shape (N,)
        Kinetic energy at each sample [J] (e.g. from :func:`kinetic_energy`).
    velocity, force, omega, torque : array_like, shape (N, 3)
        As in :func:`mechanical_power` [m/s, N, rad/s, N m].

    Returns
    -------
    ndarray, shape (N,)
        Residual power [W].

    Raises
    ------
    ValueError
        Bad shapes, fewer than 3 samples, non-increasing ``t`` or NaN/inf.
    """
    tt = as_float_array(t, 't')
    e = as_float_array(energy, 'energy')
    if tt.ndim != 1 or tt.size < 3:
        raise ValueError(f't: expected shape (N,) with N >= 3, got {tt.shape}')
    if e.shape != tt.shape:
        raise ValueError(f'energy: expected shape {tt.shape} like t, got {e.shape}')
    require_finite(tt, 't')
    require_finite(e, 'energy')
    if np.any(np.diff(tt) <= 0.0):
        raise ValueError('t: must be strictly increasing')
    p = mechanical_power(velocity, force, omega, torque)
    if np.shape(p) != tt.shape:
        raise ValueError(f'velocity, force, omega, torque: expected shape ({tt.size}, 3), '
                         f'giving power of shape {np.shape(p)}')
    return np.gradient(e, tt, edge_order=2) - p

