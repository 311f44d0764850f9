"""Estimators on Euler's equations: batch :func:`estimate` and :class:`RecursiveEstimator`.

Public API::

    estimate(t_gyro, omega, t_torque, torque, *, method='auto', model='auto',
             torque_bias='auto', symmetry_axis=None, hold='zoh', ...) -> InertiaEstimate
    RecursiveEstimator(model='full', torque_bias=False, forgetting=1.0, window=None,
                       hold='zoh')

``METHODS`` lists the batch methods, ``STATUSES`` the result statuses (DESIGN.md).
"""
from .batch import HOLDS, METHODS, ML_AUTO_MAX_SAMPLES, MODELS, TORQUE_BIAS, estimate, model_basis
from .recursive import RecursiveEstimator
from .result import STATUSES, InertiaEstimate, to_jsonable

__all__ = ['HOLDS', 'METHODS', 'ML_AUTO_MAX_SAMPLES', 'MODELS', 'STATUSES', 'TORQUE_BIAS',
           'InertiaEstimate', 'RecursiveEstimator', 'estimate', 'model_basis', 'to_jsonable']
