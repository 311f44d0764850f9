"""The estimator result type and its JSON contract (DESIGN.md, "Offline command").

:class:`InertiaEstimate` is what every estimator returns, whatever the data allowed: a status
string (never an exception for a property of the data), the tensor with NaN where an element is
not identifiable (or ``None`` when the scale is unobservable), one-sigma standard errors, the
principal moments and axes, ratios, which elements are identifiable, the torque bias, the model
and method used, sample counts and free-form diagnostics.  :meth:`InertiaEstimate.to_dict`
gives exactly the JSON object of the contract (NaN -> null, numpy -> plain lists and floats).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..tensor import THETA_COLS, THETA_NAMES, THETA_ROWS
from .options import STATUSES

__all__ = ['STATUSES', 'InertiaEstimate', 'to_jsonable']



def to_jsonable(value: Any) -> Any:
    """Convert ``value`` to plain JSON types: NaN/inf -> None, numpy -> lists/floats/ints.

    Parameters
    ----------
    value : Any
        Nested dicts, lists, tuples, numpy arrays and scalars, floats, ints, bools, strings.

    Returns
    -------
    Any
        The same structure made of dict, list, float, int, bool, str and None only.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.ndarray):
        return [to_jsonable(v) for v in value.tolist()] if value.ndim else to_jsonable(
            value.item())
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    return str(value)


def _opt_array(x: Any, shape: tuple[int, ...], name: str) -> np.ndarray | None:
    """``None`` or a read-only float64 copy of ``x`` with the given shape."""
    if x is None:
        return None
    arr = np.array(x, dtype=float)
    if arr.shape != shape:
        raise ValueError(f'{name}: expected shape {shape}, got {arr.shape}')
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class InertiaEstimate:
    """Result of an inertia estimation (batch or recursive).

    Attributes
    ----------
    status : str
        One of :data:`STATUSES`: ``ok``; ``scale_unobservable`` (torque-free data: only
        ``ratios`` and ``principal_axes``); ``partially_identifiable`` (some elements NaN);
        ``insufficient_excitation``; ``insufficient_data``.
    inertia : ndarray, shape (3, 3), or None
        Estimated tensor about the centre of mass in the gyro frame [kg m^2]; NaN where an
        element is not identifiable; ``None`` when the scale is unobservable or nothing could be
        estimated.
    inertia_std : ndarray, shape (3, 3), or None
        One-sigma standard errors of ``inertia`` [kg m^2], same NaN/None pattern.  Elements the
        model fixes (products of inertia of the diagonal model) have std 0.
    principal_moments : ndarray, shape (3,), or None
        Ascending principal moments [kg m^2]; ``None`` unless every element is identified.
    principal_axes : ndarray, shape (3, 3), or None
        Principal axes as columns (proper rotation, DESIGN.md sign convention).  Also given
        when only the scale is unobservable.
    ratios : ndarray, shape (3, 3), or None
        ``inertia / trace(inertia)`` (dimensionless); given also when the scale is unobservable.
    ratios_std : ndarray, shape (3, 3), or None
        One-sigma standard errors of ``ratios`` (dimensionless), same pattern.
    identifiable : dict of str to bool
        One entry per name in ``THETA_NAMES``.
    torque_bias : ndarray, shape (3,), or None
        Estimated constant disturbance torque [N m] when the model has a bias term.
    inertial_torque : ndarray, shape (3,), or None
        Estimated disturbance torque constant in inertial axes [N m] when the model has that
        term (``inertial_torque`` option), given in the body axes at the first gyro sample of
        the epoch (the first gyro sample the estimate used): at time ``t`` it acts on the
        body as ``R(t)' d``, ``R(t)`` the rotation from body axes at ``t`` to those at the
        epoch's start.  Not a body-fixed torque like ``torque_bias``.
    model : str
        Parameter set used: ``full``, ``diagonal``, ``axisymmetric``, each optionally
        ``+bias`` then ``+inertial`` (:func:`.model.model_parts`); ``homogeneous`` for the
        scale-free torque-free solution; ``none``.
    method : str
        Estimator name (one of ``METHODS`` or ``recursive``).
    samples_used : int
        Gyro samples that entered the equations.
    samples_dropped : int
        Gyro samples left out (outside the torque coverage, across gaps).
    diagnostics : dict
        Free-form: condition number, weakest direction, residual RMS, noise estimates, model
        selection statistics, warnings, ...
    covariance : ndarray, shape (6, 6), or None
        Covariance of ``theta = [ixx, iyy, izz, ixy, ixz, iyz]`` [kg^2 m^4] (NaN rows and
        columns for unidentified elements; zeros for elements the model fixes); its diagonal
        is ``theta_std ** 2``.
    """

    status: str
    inertia: np.ndarray | None = None
    inertia_std: np.ndarray | None = None
    principal_moments: np.ndarray | None = None
    principal_axes: np.ndarray | None = None
    ratios: np.ndarray | None = None
    ratios_std: np.ndarray | None = None
    identifiable: dict[str, bool] = field(
        default_factory=lambda: dict.fromkeys(THETA_NAMES, False))
    torque_bias: np.ndarray | None = None
    model: str = 'none'
    method: str = ''
    samples_used: int = 0
    samples_dropped: int = 0
    diagnostics: dict[str, Any] = field(default_factory=dict)
    covariance: np.ndarray | None = None
    inertial_torque: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Validate the status and freeze the arrays (read-only float64 copies)."""
        if self.status not in STATUSES:
            raise ValueError(f'status: must be one of {STATUSES}, got {self.status!r}')
        for name, shape in (('inertia', (3, 3)), ('inertia_std', (3, 3)),
                            ('principal_moments', (3,)), ('principal_axes', (3, 3)),
                            ('ratios', (3, 3)), ('ratios_std', (3, 3)),
                            ('torque_bias', (3,)), ('covariance', (6, 6)),
                            ('inertial_torque', (3,))):
            object.__setattr__(self, name, _opt_array(getattr(self, name), shape, name))
        ident = {k: bool(self.identifiable.get(k, False)) for k in THETA_NAMES}
        object.__setattr__(self, 'identifiable', ident)

    @property
    def ok(self) -> bool:
        """True when the status is ``ok``."""
        return self.status == 'ok'

    @property
    def theta(self) -> np.ndarray | None:
        """``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2] (NaN where unidentified), or None."""
        if self.inertia is None:
            return None
        return self.inertia[THETA_ROWS, THETA_COLS]

    @property
    def theta_std(self) -> np.ndarray | None:
        """One-sigma standard errors in ``theta`` order [kg m^2], or None."""
        if self.inertia_std is None:
            return None
        return self.inertia_std[THETA_ROWS, THETA_COLS]

    def to_dict(self) -> dict[str, Any]:
        """The JSON contract of DESIGN.md as plain Python types.

        Returns
        -------
        dict
            Keys ``status, inertia, inertia_std, principal_moments, principal_axes, ratios,
            ratios_std, identifiable, torque_bias, inertial_torque, model, method, samples,
            covariance, diagnostics``; NaN -> None.
        """
        out: dict[str, Any] = {'status': self.status}
        for name in ('inertia', 'inertia_std', 'principal_moments', 'principal_axes', 'ratios',
                     'ratios_std', 'identifiable', 'torque_bias', 'inertial_torque', 'model',
                     'method'):
            out[name] = to_jsonable(getattr(self, name))
        out['samples'] = {'used': int(self.samples_used), 'dropped': int(self.samples_dropped)}
        out['covariance'] = to_jsonable(self.covariance)
        out['diagnostics'] = to_jsonable(self.diagnostics)
        return out
