"""Estimators on Euler's equations: batch :func:`estimate` and :class:`RecursiveEstimator`.

Public API::

    estimate(t_gyro, omega, t_torque, torque, *, method='auto', model='auto',
             torque_bias='auto', symmetry_axis=None, hold='auto', ...) -> InertiaEstimate
    RecursiveEstimator(model='full', torque_bias=False, forgetting=1.0, window=None,
                       hold='zoh')

``METHODS`` lists the batch methods, ``STATUSES`` the result statuses (DESIGN.md).

A lazy face (PEP 562): the vocabularies come from :mod:`.options`, which imports nothing, and
the numerical modules are imported on the first use of a name that needs them, so that
``from inertia_ros.core.estimation import METHODS`` stays instant.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .options import (
    BATCH_HOLDS,
    HOLDS,
    METHODS,
    ML_AUTO_MAX_SAMPLES,
    MODELS,
    STATUSES,
    TORQUE_BIAS,
)

if TYPE_CHECKING:
    from .batch import estimate
    from .model import model_basis
    from .recursive import RecursiveEstimator
    from .result import InertiaEstimate, to_jsonable

__all__ = ['BATCH_HOLDS', 'HOLDS', 'METHODS', 'ML_AUTO_MAX_SAMPLES', 'MODELS', 'STATUSES',
           'TORQUE_BIAS', 'InertiaEstimate', 'RecursiveEstimator', 'estimate', 'model_basis',
           'to_jsonable']

#: Lazily imported names and the module that defines each.
_LAZY = {'estimate': 'batch', 'model_basis': 'model', 'RecursiveEstimator': 'recursive',
         'InertiaEstimate': 'result', 'to_jsonable': 'result'}


def __getattr__(name: str) -> Any:
    """Import a numerical name on first use (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public names (lazy ones included)."""
    return sorted(set(globals()) | set(__all__))
