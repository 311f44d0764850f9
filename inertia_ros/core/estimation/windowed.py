"""Online estimators: the :class:`OnlineEstimator` interface and the sliding-window
:class:`BatchWindow`.

An online estimator takes gyro and torque samples in blocks as they arrive and gives an
:class:`~inertia_ros.core.estimation.result.InertiaEstimate` whenever asked.  Two implement
the interface:

- :class:`~inertia_ros.core.estimation.recursive.RecursiveEstimator`: sufficient statistics
  over all data (or an exponential memory), a few microseconds per sample;
- :class:`BatchWindow`: buffers the newest ``window`` seconds of both streams and re-solves
  them with the batch :func:`~inertia_ros.core.estimation.batch.estimate` at each call.

:data:`ONLINE_METHODS` names them (the ROS node's ``method`` parameter).
"""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from inertia_ros.core.estimation.config import require
from inertia_ros.core.estimation.options import METHODS, check_choice
from inertia_ros.core.estimation.result import InertiaEstimate

__all__ = ['ONLINE_METHODS', 'BatchWindow', 'OnlineEstimator']

#: Online estimators by name: ``'recursive'`` (RecursiveEstimator) or ``'batch'``
#: (:class:`BatchWindow`).
ONLINE_METHODS: tuple[str, ...] = ('recursive', 'batch')


@runtime_checkable
class OnlineEstimator(Protocol):
    """What a streaming consumer (the ROS node) calls on an online estimator.

    Times are seconds on one clock shared by both streams; blocks need not alternate, and
    the estimator aligns the streams itself.
    """

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples: ``t`` (n,) [s], ``omega`` (n, 3) [rad/s] in the body frame."""
        ...

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add torque samples: ``t`` (n,) [s], ``tau`` (n, 3) [N m] about the centre of mass."""
        ...

    def estimate(self) -> InertiaEstimate:
        """The estimate from the samples so far (``ValueError`` when there is too little)."""
        ...

    def reset(self) -> None:
        """Forget every sample; the configuration is kept."""
        ...


class BatchWindow:
    """Sliding-window buffer re-solved by the batch :func:`estimate` at each :meth:`estimate`.

    Parameters
    ----------
    window : float
        Length of the window [s] (> 0), counted back from the newest sample of either stream.
    method : str, optional
        Batch method, one of :data:`~inertia_ros.core.estimation.options.METHODS`.
    model : str, optional
        One of :data:`~inertia_ros.core.estimation.options.MODELS`.
    torque_bias : str, optional
        One of :data:`~inertia_ros.core.estimation.options.TORQUE_BIAS`.
    hold : str, optional
        One of :data:`~inertia_ros.core.estimation.options.BATCH_HOLDS` (``auto``: both,
        as the batch estimator).
    symmetry_axis : {'x', 'y', 'z'} or None, optional
        Required for ``model='axisymmetric'``.
    torque_scale_std, gyro_scale_std : float, optional
        Stated relative scale uncertainties, as the batch estimator.
    nuisance : 'auto', 'off' or list of str, optional
        Sensor nuisance terms of every batch solve (as the batch estimator).

    Raises
    ------
    ValueError
        Naming the option that is not one of its vocabulary, a non-positive window, or an
        axisymmetric model without axis.
    """

    def __init__(self, window: float, *, method: str = 'integral', model: str = 'full',
                 torque_bias: str = 'auto', hold: str = 'zoh',
                 symmetry_axis: str | None = None, torque_scale_std: float = 0.0,
                 gyro_scale_std: float = 0.0, nuisance: Any = 'off') -> None:
        if not (isinstance(window, (int, float)) and np.isfinite(window) and window > 0):
            raise ValueError(f'window: must be a positive number of seconds, got {window!r}')
        check_choice('method', method, METHODS)
        require('window', 'torque', dict(
            model=model, torque_bias=torque_bias, hold=hold, symmetry_axis=symmetry_axis,
            torque_scale_std=torque_scale_std, gyro_scale_std=gyro_scale_std, nuisance=nuisance))
        self.window = float(window)
        #: keyword arguments of every batch solve
        self.options: dict[str, Any] = dict(method=method, model=model,
                                            torque_bias=torque_bias, hold=hold,
                                            symmetry_axis=symmetry_axis,
                                            torque_scale_std=torque_scale_std,
                                            gyro_scale_std=gyro_scale_std,
                                            nuisance=nuisance)
        self._g: list[tuple[np.ndarray, np.ndarray]] = []
        self._q: list[tuple[np.ndarray, np.ndarray]] = []

    def reset(self) -> None:
        """Forget every buffered sample."""
        self._g = []
        self._q = []

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Buffer gyro samples ``t`` (n,) [s], ``omega`` (n, 3) [rad/s]."""
        self._g.append((np.atleast_1d(t), np.atleast_2d(omega)))

    def add_torque(self, t: Any, tau: Any) -> None:
        """Buffer torque samples ``t`` (n,) [s], ``tau`` (n, 3) [N m]."""
        self._q.append((np.atleast_1d(t), np.atleast_2d(tau)))

    @staticmethod
    def _trim(blocks: list[tuple[np.ndarray, np.ndarray]], t_min: float
              ) -> tuple[np.ndarray, np.ndarray]:
        """Samples at or after ``t_min`` [s], as one block that replaces ``blocks``."""
        t = np.concatenate([b[0] for b in blocks]) if blocks else np.zeros(0)
        v = np.concatenate([b[1] for b in blocks]) if blocks else np.zeros((0, 3))
        keep = t >= t_min
        t, v = t[keep], v[keep]
        blocks[:] = [(t, v)] if len(t) else []
        return t, v

    def estimate(self) -> InertiaEstimate:
        """Batch estimate over the newest ``window`` seconds of both streams.

        Raises
        ------
        ValueError
            From the batch estimator, when the window holds too little data.
        """
        t_end = max((b[0][-1] for b in self._g + self._q if len(b[0])), default=0.0)
        tg, w = self._trim(self._g, t_end - self.window)
        tq, q = self._trim(self._q, t_end - self.window)
        # imported here: the node loads this module, and the batch estimator pulls in scipy
        from inertia_ros.core.estimation.batch import estimate as batch_estimate

        return batch_estimate(tg, w, tq, q, **self.options)
