"""Parameter sets of the estimators: bases, names, the selector onto the equation columns.

A parameter set (``model``) is a basis ``T`` (6, k) with ``theta = T @ psi``
(:func:`model_basis`); the fitted parameters are ``psi`` followed by the optional constant
torque bias ``d`` (3).  :func:`selector` maps ``[psi, d, 1]`` onto the 10 columns
``[X6 | Xd | y]`` of an equation block (:mod:`.regressors`), optionally with a fixed part of
``theta`` moved to the right-hand side.  Torque-free fits use the trace-free directions
(:data:`TRACE_FREE`) around ``TRACE / 3``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..tensor import THETA_COLS, THETA_NAMES, THETA_ROWS
from .options import MODELS

__all__ = ['BIAS_NAMES', 'INERTIAL_NAMES', 'TRACE', 'TRACE_FREE', 'describe_direction',
           'model_basis', 'model_name', 'model_parts', 'parameter_names', 'selector',
           'symmetry_axis']

#: Names of the constant torque-bias parameters [N m].
BIAS_NAMES: tuple[str, ...] = ('dx', 'dy', 'dz')
#: Names of the torque fixed in inertial axes (body axes at the start of the gyro run) [N m].
INERTIAL_NAMES: tuple[str, ...] = ('ix_d', 'iy_d', 'iz_d')
#: ``theta -> trace`` of the tensor, shape (6,).
TRACE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])

_AXES = {'x': np.array([1.0, 0.0, 0.0]), 'y': np.array([0.0, 1.0, 0.0]),
         'z': np.array([0.0, 0.0, 1.0])}


def model_parts(name: str | None) -> tuple[str, bool, bool]:
    """A result's ``model`` string split into its parameter set and its disturbance terms.

    Parameters
    ----------
    name : str or None
        E.g. ``'full'``, ``'diagonal+bias'``, ``'full+bias+inertial'``, ``'full+inertial'``
        (:func:`model_name`); ``None`` or ``''`` reads as ``'full'``.

    Returns
    -------
    parameter_set : str
        ``'full'``, ``'diagonal'``, ``'axisymmetric'`` (or ``'homogeneous'``, ``'none'``).
    bias : bool
        The constant body-axis torque bias was fitted.
    inertial : bool
        The torque fixed in inertial axes was fitted.
    """
    parts = (name or 'full').split('+')
    return parts[0], 'bias' in parts[1:], 'inertial' in parts[1:]


def model_name(parameter_set: str, bias: bool, inertial: bool = False) -> str:
    """The ``model`` string of a result (the inverse of :func:`model_parts`)."""
    return parameter_set + ('+bias' if bias else '') + ('+inertial' if inertial else '')


def symmetry_axis(value: Any) -> np.ndarray | None:
    """Unit symmetry axis from ``'x'``/``'y'``/``'z'`` or a 3-vector, or None (validated
    before, by :func:`.config.require`).

    Parameters
    ----------
    value : {'x', 'y', 'z'} or array_like (3,) or None
        Body axis of symmetry (any non-zero length).

    Returns
    -------
    ndarray, shape (3,), or None
        The unit axis.
    """
    if value is None:
        return None
    if isinstance(value, str):
        return _AXES[value]
    v = np.asarray(value, dtype=float)
    return v / np.linalg.norm(v)


def model_basis(model: str, symmetry_axis: np.ndarray | None = None) -> np.ndarray:
    """Basis ``T`` (6, k) of a parameter set: ``theta = T @ psi``.

    Parameters
    ----------
    model : {'full', 'diagonal', 'axisymmetric'}
        ``full``: the six elements; ``diagonal``: ixx, iyy, izz; ``axisymmetric``:
        ``I = a (1 - n n') + b n n'`` with ``psi = [a, b]`` (transverse, axial) [kg m^2].
    symmetry_axis : ndarray, shape (3,), optional
        Unit axis ``n``, required for ``axisymmetric``.

    Returns
    -------
    ndarray, shape (6, k)
    """
    if model == 'full':
        return np.eye(6)
    if model == 'diagonal':
        return np.eye(6)[:, :3]
    if model == 'axisymmetric':
        if symmetry_axis is None:
            raise ValueError("symmetry_axis: required for model='axisymmetric'")
        nn = np.outer(symmetry_axis, symmetry_axis)
        return np.column_stack([(np.eye(3) - nn)[THETA_ROWS, THETA_COLS],
                                nn[THETA_ROWS, THETA_COLS]])
    raise ValueError(f'model: must be one of {MODELS}, got {model!r}')


def parameter_names(basis: np.ndarray, bias: bool, model: str,
                    inertial: bool = False) -> list[str]:
    """Names of the fitted parameters ``[psi, d]`` of a parameter set.

    Parameters
    ----------
    basis : ndarray, shape (6, k)
        The set's basis (:func:`model_basis`, or columns of the identity).
    bias : bool
        Whether the torque bias is fitted.
    model : str
        ``'axisymmetric'`` names ``i_transverse, i_axial``; otherwise the elements.
    inertial : bool
        Whether the torque fixed in inertial axes is fitted (after the bias).

    Returns
    -------
    list of str
        ``k`` (+ 3) (+ 3) names.
    """
    if model == 'axisymmetric':
        names = ['i_transverse', 'i_axial']
    else:
        names = [THETA_NAMES[int(np.argmax(basis[:, i]))] for i in range(basis.shape[1])]
    return names + (list(BIAS_NAMES) if bias else []) + (list(INERTIAL_NAMES) if inertial
                                                          else [])


def selector(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None,
             inertial: bool = False, width: int = 10, held: np.ndarray | None = None
             ) -> np.ndarray:
    """Map (10, p + 1) from ``[psi, d, 1]`` to the columns ``[X6 | Xd | y]`` of a block.

    With ``width=13`` the blocks are the wide ones ``[X6 | Xd | y | Xi]`` of a torque fixed
    in inertial axes (:data:`.regressors.VARIABLE_MAP_WIDE`) and, with ``inertial``, the
    parameters ``[psi, d, d_i, 1]``; without it the ``Xi`` columns get 0 (the narrow fit on
    wide statistics).

    Parameters
    ----------
    basis : ndarray, shape (6, k)
        Parameter set.
    bias : bool
        Fit the torque bias (``p = k + 3``; else ``p = k``).
    offset : ndarray, shape (6,), optional
        A fixed part of ``theta`` moved to the right-hand side.
    inertial : bool
        Fit the torque fixed in inertial axes (3 more parameters after the bias; needs
        ``width=13``).
    width : {10, 13}
        Columns of the blocks.
    held : ndarray, shape (3,), optional
        With ``width=13`` and ``inertial`` False: the torque fixed in inertial axes held at
        these values [N m], moved to the right-hand side.

    Returns
    -------
    ndarray, shape (width, p + 1)
    """
    if width not in (10, 13) or (inertial and width != 13):
        raise ValueError(f'selector: width 10, or 13 with the inertial columns; got {width} '
                         f'(inertial={inertial})')
    k = basis.shape[1]
    b = k + (3 if bias else 0)
    p = b + (3 if inertial else 0)
    T = np.zeros((width, p + 1))
    T[:6, :k] = basis
    if bias:
        T[6:9, k:k + 3] = np.eye(3)
    if inertial:
        T[10:13, b:b + 3] = np.eye(3)
    T[9, p] = 1.0
    if offset is not None:
        T[:6, p] = -offset
    if held is not None and width == 13 and not inertial:
        T[10:13, p] = -held
    return T


def _trace_free_basis() -> np.ndarray:
    """Orthonormal basis (6, 5) of the theta directions that leave the trace unchanged."""
    q, _ = np.linalg.qr(np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, -1.0]]))
    basis = np.zeros((6, 5))
    basis[:3, :2] = q
    basis[3:, 2:] = np.eye(3)
    return basis


#: Orthonormal basis (6, 5) of the trace-free directions of ``theta``.
TRACE_FREE = _trace_free_basis()


def describe_direction(v: np.ndarray, names: list[str]) -> str:
    """A parameter direction as readable text, largest coefficients first.

    Parameters
    ----------
    v : ndarray, shape (p,)
        Direction in parameter space (any scale).
    names : list of str
        The ``p`` parameter names.

    Returns
    -------
    str
        E.g. ``'+1.00 ixx -0.50 iyy'`` (coefficients under 0.05 of the largest left out).
    """
    v = v / np.max(np.abs(v))
    order = np.argsort(-np.abs(v))
    parts = [f'{v[i]:+.2f} {names[i]}' for i in order if abs(v[i]) >= 0.05]
    return ' '.join(parts)
