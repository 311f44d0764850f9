"""First-order uncertainty of derived quantities from the covariance of ``theta``.

Principal moments and axes (perturbation of the symmetric eigenproblem) and the ratios
``theta / trace``; every function takes the tensor (3, 3) or ``theta`` (6,) and the
covariance of ``theta`` (6, 6) [kg^2 m^4].
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..tensor import THETA_COLS, THETA_ROWS, principal_axes, theta_to_matrix
from .model import TRACE

__all__ = ['axis_std', 'moment_std', 'principal_with_std', 'ratio_cov', 'widen']


def moment_std(I: np.ndarray, cov6: np.ndarray,
               eig: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """First-order std of the principal moments from the theta covariance (``eig``: the
    ``np.linalg.eigh(I)`` already computed)."""
    _, vec = np.linalg.eigh(I) if eig is None else eig
    out = np.empty(3)
    for i in range(3):
        v = vec[:, i]
        grad = np.array([v[0] ** 2, v[1] ** 2, v[2] ** 2, 2 * v[0] * v[1], 2 * v[0] * v[2],
                         2 * v[1] * v[2]])
        out[i] = np.sqrt(max(float(grad @ cov6 @ grad), 0.0))
    return out


def axis_std(I: np.ndarray, cov6: np.ndarray,
             eig: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """First-order angular std [rad] of each principal axis (ascending moments' order).

    Perturbation of a symmetric eigenproblem: ``dv_i = sum_{j != i} (v_j' dI v_i) /
    (l_i - l_j) v_j``, so ``E|dv_i|^2 = sum_j var(v_j' dI v_i) / (l_i - l_j)^2``: the RMS
    angle between the estimated and the true axis.  Infinite for repeated moments (the axes
    of a degenerate subspace are not determined).  ``eig``: ``np.linalg.eigh(I)`` if known.
    """
    lam, vec = np.linalg.eigh(I) if eig is None else eig
    out = np.empty(3)
    for i in range(3):
        var = 0.0
        for j in range(3):
            if j == i:
                continue
            a, b = vec[:, i], vec[:, j]
            g = np.array([a[0] * b[0], a[1] * b[1], a[2] * b[2], a[0] * b[1] + a[1] * b[0],
                          a[0] * b[2] + a[2] * b[0], a[1] * b[2] + a[2] * b[1]])
            gap = float(lam[i] - lam[j])
            var += max(float(g @ cov6 @ g), 0.0) / gap ** 2 if gap != 0.0 else np.inf
        out[i] = np.sqrt(var)
    return out


def ratio_cov(theta: np.ndarray, cov6: np.ndarray) -> np.ndarray:
    """First-order covariance (6, 6) of ``theta / trace`` from that of ``theta``."""
    tr = float(TRACE @ theta)
    J = (np.eye(6) - np.outer(theta / tr, TRACE)) / tr
    return J @ cov6 @ J.T


def principal_with_std(I: np.ndarray, cov6: np.ndarray,
                       diag: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes of ``I`` (3, 3), their std recorded in ``diag``.

    Sets ``diag['principal_moments_std']`` (3,) and ``diag['principal_axes_std']`` (3,) [rad].

    Returns
    -------
    moments : ndarray, shape (3,)
        Ascending principal moments (units of ``I``).
    axes : ndarray, shape (3, 3)
        Principal axes as the columns of a proper rotation.
    """
    moments, axes = principal_axes(I)
    eig = np.linalg.eigh(I)             # one decomposition for both (the same numbers)
    diag['principal_moments_std'] = moment_std(I, cov6, eig)
    diag['principal_axes_std'] = axis_std(I, cov6, eig)
    return moments, axes


def widen(est: Any, added: np.ndarray) -> Any:
    """``est`` with ``added`` (6, 6) [kg^2 m^4] in its covariance and every standard error
    derived from it (the tensor's, the principal moments' and axes', the ratios'): the one
    widening of the nuisance terms and of the stated inputs, batch and online alike.

    Elements the parameter set holds (zero variance) stay held; an estimate without a
    covariance or a tensor is returned as it is.
    """
    if est.covariance is None or est.inertia is None:
        return est
    cov = np.asarray(est.covariance, dtype=float)
    fixed = np.diag(cov) == 0.0                   # elements the model holds (diagonal: products)
    cov6 = cov + np.where(fixed[:, None] | fixed[None, :], 0.0, added)
    std = np.sqrt(np.maximum(np.diag(cov6), 0.0))
    diag = dict(est.diagnostics)
    out: dict[str, Any] = {'covariance': cov6, 'diagnostics': diag,
                           'inertia_std': theta_to_matrix(std, check_finite=False)}
    I = np.asarray(est.inertia)
    if est.principal_moments is not None:
        out['principal_moments'], out['principal_axes'] = principal_with_std(
            I, np.nan_to_num(cov6), diag)
    if est.ratios_std is not None and np.all(np.isfinite(I)):
        r_cov = ratio_cov(I[THETA_ROWS, THETA_COLS], np.nan_to_num(cov6))
        out['ratios_std'] = theta_to_matrix(np.where(np.isfinite(std), np.sqrt(
            np.maximum(np.diag(r_cov), 0.0)), np.nan), check_finite=False)
    return replace(est, **out)
