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
    momentum : bool, optional
        Wheels or rotors: blocks of their momentum input arrive through :meth:`add_momentum`
        and every solve is :func:`.momentum.estimate_with_momentum` (the batch momentum
        estimator) on the window.  Default False.
    other_torque : bool, optional
        With ``momentum``: another known torque arrives through :meth:`add_torque` (True,
        default) or the momentum input is the only known torque (False).

    Raises
    ------
    ValueError
        Naming the option that is not one of its vocabulary, a non-positive window, or an
        axisymmetric model without axis.
    """

    def __init__(self, window: float, *, method: str = 'integral', model: str = 'full',
                 torque_bias: str = 'auto', hold: str = 'zoh',
                 symmetry_axis: str | None = None, torque_scale_std: float = 0.0,
                 gyro_scale_std: float = 0.0, nuisance: Any = 'off', momentum: bool = False,
                 other_torque: bool = True) -> None:
        if not (isinstance(window, (int, float)) and np.isfinite(window) and window > 0):
            raise ValueError(f'window: must be a positive number of seconds, got {window!r}')
        check_choice('method', method, METHODS)
        self.momentum, self.other_torque = bool(momentum), bool(other_torque) or not momentum
        kind = 'torque' if not momentum else 'wheels_torque' if other_torque else 'wheels'
        require('window', kind, dict(
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
        self.reset()

    def reset(self) -> None:
        """Forget every buffered sample."""
        self._g: list[tuple[np.ndarray, np.ndarray]] = []
        self._q: list[tuple[np.ndarray, np.ndarray]] = []
        self._m: list[Any] = []           # momentum blocks (.momentum.Momentum)

    def add_momentum(self, m: Any) -> None:
        """Buffer a block of the momentum input (a :class:`.momentum.Momentum`, as
        :meth:`.recursive_momentum.MomentumRecursiveEstimator.add_momentum` takes)."""
        if not self.momentum:
            raise ValueError('momentum: this window was built without momentum=True (give it '
                             'for wheels or rotors)')
        if len(np.atleast_1d(m.t)):
            self._m.append(m)

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Buffer gyro samples ``t`` (n,) [s], ``omega`` (n, 3) [rad/s]."""
        self._g.append((np.atleast_1d(t), np.atleast_2d(omega)))

    def add_torque(self, t: Any, tau: Any) -> None:
        """Buffer torque samples ``t`` (n,) [s], ``tau`` (n, 3) [N m]."""
        if not self.other_torque:
            raise ValueError('torque: this window was built with other_torque=False (the '
                             'momentum input is the only known torque)')
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
        t_end = max([b[0][-1] for b in self._g + self._q if len(b[0])]
                    + [float(np.atleast_1d(m.t)[-1]) for m in self._m], default=0.0)
        tg, w = self._trim(self._g, t_end - self.window)
        tq, q = self._trim(self._q, t_end - self.window)
        # imported here: the node loads this module, and the batch estimator pulls in scipy
        if self.momentum:
            from inertia_ros.core.estimation.momentum import estimate_with_momentum

            opts = {k: v for k, v in self.options.items() if k != 'nuisance'}   # 'off' here
            return estimate_with_momentum(tg, w, tq, q, self._trim_momentum(
                t_end - self.window), **opts)
        from inertia_ros.core.estimation.batch import estimate as batch_estimate

        return batch_estimate(tg, w, tq, q, **self.options)

    def _trim_momentum(self, t_min: float) -> Any:
        """The momentum samples at or after ``t_min`` [s] as one block (replacing the
        buffered ones); its noise left to the batch estimator (from ``h``)."""
        from inertia_ros.core.estimation.momentum import Momentum

        if not self._m:
            raise ValueError('momentum: no wheel/rotor sample in the window yet')
        ms = self._m
        t = np.concatenate([np.atleast_1d(m.t) for m in ms])
        keep = t >= t_min
        torque = None if ms[0].torque is None else np.concatenate([m.torque for m in ms])[keep]
        tq_std = None if ms[0].torque_std is None else \
            np.concatenate([m.torque_std for m in ms], axis=1)[:, keep]
        m = Momentum(t[keep], np.concatenate([m.h for m in ms])[keep],
                     np.concatenate([m.h_std for m in ms], axis=1)[:, keep], ms[0].names,
                     torque=torque, torque_std=tq_std)
        self._m = [m] if len(m.t) else []
        return m
