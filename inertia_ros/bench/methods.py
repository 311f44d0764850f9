"""The estimator settings the benchmark compares, each as a callable on one simulated record.

Every entry of :func:`method_specs` maps a :class:`~inertia_ros.core.simulation.SimResult` to an
:class:`Outcome` (status, tensor, compute time).  Only the estimator call is timed, never the
simulation.  Besides the package's :func:`~inertia_ros.core.estimation.estimate` settings there
are two baselines a user would otherwise reach for:

``hand_fd``
    What a user writes by hand: ``np.gradient`` of the gyro, the torque held to the gyro
    times, the differential Euler regressor stacked and solved with ``np.linalg.lstsq``.
``pinocchio``
    Pinocchio's ``bodyRegressor(v, a)`` (the peer library; ``pin`` from PyPI, optional
    ``requirements-bench.txt``) per sample with ``v = (0, w)``, ``a = (0, w_dot)`` from
    finite differences, angular rows and inertia columns stacked, ``np.linalg.lstsq``.
    Skipped with a note when ``pinocchio`` is not importable.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from inertia_ros.core import estimation
from inertia_ros.core.inertia import theta_to_matrix

__all__ = ['DEFAULT_METHOD', 'MethodSpec', 'Outcome', 'hand_fd', 'method_of', 'method_specs',
           'pinocchio_available', 'pinocchio_regressor']

#: Name of the package's default setting in the tables (``method='auto'``: ``ml`` on records
#: of up to ``ML_AUTO_MAX_SAMPLES`` gyro samples, which every bench record is).
DEFAULT_METHOD = 'ml'


@dataclass(frozen=True)
class Outcome:
    """What one estimator setting produced on one record.

    Attributes
    ----------
    status : str
        The estimator's status (``'ok'`` for the baselines, which have no other).
    inertia : numpy.ndarray, shape (3, 3), or None
        Estimated tensor [kg m^2]; None when the estimator returned none.
    seconds : float
        Wall-clock compute time of the estimator call [s].
    inertia_std : numpy.ndarray, shape (3, 3), or None
        The estimator's own one-sigma standard errors [kg m^2], when it gives them.
    """

    status: str
    inertia: np.ndarray | None
    seconds: float
    inertia_std: np.ndarray | None = None


@dataclass(frozen=True)
class MethodSpec:
    """One estimator setting.

    Attributes
    ----------
    name : str
        Unique name used in tables and charts: ``METHOD`` or ``METHOD/VARIANT``, where
        ``METHOD`` is the ``--method`` name of the package setting (``ml``, ``integral``,
        ``integral_sliding``, ...) or a baseline (``recursive``, ``hand_fd``, ``pinocchio``)
        and ``VARIANT`` names the non-default option (``integral_sliding/1s``: 1 s windows).
    family : str
        ``package``, ``recursive`` or ``baseline`` (the advice section compares within
        the package settings).
    description : str
        One line: what the setting is.
    run : callable
        ``run(sim) -> Outcome``.
    """

    name: str
    family: str
    description: str
    run: Callable[[Any], Outcome]

    @property
    def method(self) -> str:
        """The method part of the name (the chart colour and legend group)."""
        return method_of(self.name)


def method_of(name: str) -> str:
    """``'integral_sliding/1s'`` -> ``'integral_sliding'``: the setting's method."""
    return name.split('/', 1)[0]


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    """Call ``fn`` and return ``(result, seconds)``."""
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _package(**kwargs: Any) -> Callable[[Any], Outcome]:
    """An ``estimate(...)`` setting as a runner."""
    def run(sim: Any) -> Outcome:
        res, dt = _timed(lambda: estimation.estimate(sim.t_gyro, sim.omega, sim.t_torque,
                                                     sim.torque, **kwargs))
        I = None if res.inertia is None else np.array(res.inertia, dtype=float)
        S = None if res.inertia_std is None else np.array(res.inertia_std, dtype=float)
        return Outcome(res.status, I, dt, S)
    return run


# Euler regressor by hand: tau = I w_dot + w x (I w), linear in theta
_E = theta_to_matrix(np.eye(6))           # (6, 3, 3)


def hand_fd(t_gyro: np.ndarray, omega: np.ndarray, t_torque: np.ndarray,
            torque: np.ndarray) -> np.ndarray:
    """The finite-difference least-squares estimate a user writes by hand.

    Parameters
    ----------
    t_gyro : numpy.ndarray, shape (N,)
        Gyro times [s].
    omega : numpy.ndarray, shape (N, 3)
        Measured angular velocity [rad/s].
    t_torque : numpy.ndarray, shape (M,)
        Torque times [s].
    torque : numpy.ndarray, shape (M, 3)
        Measured torque [N m], held between samples.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Least-squares tensor [kg m^2] (no checks, no status).
    """
    wd = np.gradient(omega, t_gyro, axis=0)
    j = np.clip(np.searchsorted(t_torque, t_gyro, side='right') - 1, 0, len(t_torque) - 1)
    tau = torque[j]
    Ewd = np.einsum('kij,nj->nik', _E, wd)                     # (N, 3, 6)
    Ew = np.einsum('kij,nj->nki', _E, omega)                   # (N, 6, 3)
    gyro = np.cross(omega[:, None, :], Ew).transpose(0, 2, 1)  # (N, 3, 6)
    Y = (Ewd + gyro).reshape(-1, 6)
    theta = np.linalg.lstsq(Y, tau.reshape(-1), rcond=None)[0]
    return theta_to_matrix(theta)


def _run_hand_fd(sim: Any) -> Outcome:
    """``hand_fd`` as a runner."""
    I, dt = _timed(lambda: hand_fd(sim.t_gyro, sim.omega, sim.t_torque, sim.torque))
    return Outcome('ok', I, dt)


def pinocchio_available() -> tuple[bool, str]:
    """Whether ``pinocchio`` imports, and its version or the import error."""
    try:
        import pinocchio
    except Exception as exc:                # pragma: no cover - depends on the environment
        return False, f'{type(exc).__name__}: {exc}'
    return True, str(getattr(pinocchio, '__version__', '?'))


def pinocchio_regressor(t_gyro: np.ndarray, omega: np.ndarray, t_torque: np.ndarray,
                        torque: np.ndarray) -> np.ndarray:
    """Peer baseline: Pinocchio's body regressor per sample, then ``np.linalg.lstsq``.

    The spatial velocity is ``(0, w)`` and the acceleration ``(0, w_dot)`` (finite
    differences), so the angular rows of ``bodyRegressor`` are ``I w_dot + w x I w`` in the
    rotational inertia columns ``[Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (Pinocchio's order).

    Parameters
    ----------
    t_gyro, omega, t_torque, torque
        As :func:`hand_fd`.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Least-squares tensor [kg m^2].
    """
    import pinocchio as pin

    wd = np.gradient(omega, t_gyro, axis=0)
    j = np.clip(np.searchsorted(t_torque, t_gyro, side='right') - 1, 0, len(t_torque) - 1)
    tau = torque[j]
    zero = np.zeros(3)
    rows = np.empty((len(t_gyro), 3, 6))
    for n in range(len(t_gyro)):
        Y = pin.bodyRegressor(pin.Motion(zero, omega[n]), pin.Motion(zero, wd[n]))
        rows[n] = Y[3:, 4:]
    p = np.linalg.lstsq(rows.reshape(-1, 6), tau.reshape(-1), rcond=None)[0]
    ixx, ixy, iyy, ixz, iyz, izz = p
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def _run_pinocchio(sim: Any) -> Outcome:
    """``pinocchio_regressor`` as a runner."""
    I, dt = _timed(lambda: pinocchio_regressor(sim.t_gyro, sim.omega, sim.t_torque,
                                               sim.torque))
    return Outcome('ok', I, dt)


def _recursive_runner(**kwargs: Any) -> tuple[Callable[[Any], Outcome] | None, str]:
    """A runner for ``RecursiveEstimator(**kwargs)``: the record in 1 s blocks, then estimate."""
    cls = getattr(estimation, 'RecursiveEstimator', None)
    if cls is None:
        return None, 'RecursiveEstimator is not in inertia_ros.core.estimation yet'

    def run(sim: Any) -> Outcome:
        def go() -> Any:
            est = cls(**kwargs)
            tg, ts = sim.t_gyro, sim.t_torque
            edges = np.arange(np.floor(tg[0]), tg[-1] + 1.0, 1.0)
            ig = np.searchsorted(tg, edges)
            it = np.searchsorted(ts, edges)
            for k in range(len(edges) - 1):
                if it[k + 1] > it[k]:
                    est.add_torque(ts[it[k]:it[k + 1]], sim.torque[it[k]:it[k + 1]])
                if ig[k + 1] > ig[k]:
                    est.add_gyro(tg[ig[k]:ig[k + 1]], sim.omega[ig[k]:ig[k + 1]])
            if it[-1] < len(ts):
                est.add_torque(ts[it[-1]:], sim.torque[it[-1]:])
            if ig[-1] < len(tg):
                est.add_gyro(tg[ig[-1]:], sim.omega[ig[-1]:])
            return est.estimate()
        try:
            res, dt = _timed(go)
        except Exception:        # an API mismatch is a skipped point, not a crashed bench
            return Outcome('error', None, float('nan'))
        I = None if res.inertia is None else np.array(res.inertia, dtype=float)
        return Outcome(res.status, I, dt)
    return run, ''


def method_specs(*, include_pinocchio: bool = True, quick: bool = False
                 ) -> tuple[list[MethodSpec], list[str]]:
    """The benchmarked settings and notes on the ones that were skipped.

    Parameters
    ----------
    include_pinocchio : bool
        Add the Pinocchio baseline when ``pinocchio`` imports.
    quick : bool
        Fewer window/segment variants (for ``bench --quick``).

    Returns
    -------
    specs : list of MethodSpec
    notes : list of str
        Why a setting was left out.
    """
    specs = [
        MethodSpec('ml', 'package', "default (method='auto', which is ml on these records): the "
                   'integral estimate refined by maximum likelihood (Gauss-Newton on the '
                   'exact noise model), Fisher-information covariance', _package()),
        MethodSpec('integral', 'package', 'anchored momentum form, weighted, '
                   'EIV-compensated, segment length chosen from the data, model selection, '
                   'physical projection (the starting point of ml)',
                   _package(method='integral')),
        MethodSpec('integral/full', 'package', 'integral, full model and bias off '
                   '(no model selection)', _package(method='integral', model='full',
                                                    torque_bias='off')),
        MethodSpec('integral/unconstrained', 'package', 'integral without the physical '
                   'projection', _package(method='integral', physical=False)),
        MethodSpec('integral/seg5s', 'package', 'integral, anchored segments of 5 s',
                   _package(method='integral', segment=5.0)),
        MethodSpec('integral_ls', 'package', 'anchored momentum form, unweighted, no EIV '
                   'compensation', _package(method='integral_ls')),
        MethodSpec('integral_sliding/1s', 'package', 'overlapping 1 s momentum windows, OLS',
                   _package(method='integral_sliding', window=1.0)),
        MethodSpec('differential_fd', 'package', 'differential form, central '
                   'differences (package baseline)', _package(method='differential_fd')),
        MethodSpec('differential_sg/0.1s', 'package', 'differential form, Savitzky-Golay 0.1 s',
                   _package(method='differential_sg', window=0.1)),
        MethodSpec('filtered', 'package', 'both sides through one low-pass, cutoff from data',
                   _package(method='filtered')),
        MethodSpec('hand_fd', 'baseline', 'by hand: np.gradient + np.linalg.lstsq',
                   _run_hand_fd),
    ]
    if not quick:
        specs += [
            MethodSpec('integral/seg20s', 'package', 'integral, anchored segments of 20 s',
                       _package(method='integral', segment=20.0)),
            MethodSpec('integral_sliding/0.25s', 'package', 'overlapping 0.25 s momentum windows',
                       _package(method='integral_sliding', window=0.25)),
            MethodSpec('integral_sliding/4s', 'package', 'overlapping 4 s momentum windows',
                       _package(method='integral_sliding', window=4.0)),
            MethodSpec('differential_sg/0.5s', 'package',
                       'differential form, Savitzky-Golay 0.5 s',
                       _package(method='differential_sg', window=0.5)),
            MethodSpec('differential_sg/2s', 'package', 'differential form, Savitzky-Golay 2 s',
                       _package(method='differential_sg', window=2.0)),
        ]
    notes: list[str] = []
    rec, why = _recursive_runner(model='full', torque_bias='auto', reselect_every=10)
    if rec is not None:
        specs.append(MethodSpec('recursive', 'recursive', 'RecursiveEstimator fed the whole '
                                'record in 1 s blocks, node defaults (full model, '
                                "torque_bias 'auto')", rec))
        rec_n, _ = _recursive_runner(model='full', torque_bias='off')
        assert rec_n is not None
        specs.append(MethodSpec('recursive/nobias', 'recursive', 'RecursiveEstimator as '
                                "above with torque_bias='off'", rec_n))
    else:
        notes.append(f'recursive: skipped ({why})')
    if include_pinocchio:
        ok, info = pinocchio_available()
        if ok:
            specs.append(MethodSpec('pinocchio', 'baseline', f'Pinocchio {info} bodyRegressor '
                                    '+ finite differences + np.linalg.lstsq', _run_pinocchio))
        else:
            notes.append(f'pinocchio: skipped, not importable ({info}); install '
                         'requirements-bench.txt')
    return specs, notes
