"""Seeded Monte Carlo runs of every estimator setting, and their efficiency against the bound.

Each run simulates a scene with seed ``base_seed + i`` and applies every setting to the same
record.  Errors are the relative Frobenius error ``||I_hat - I||_F / ||I||_F``; efficiency is
``CRLB / MSE`` per tensor element and for the trace (``sum_i CRLB_ii / sum_i MSE_i``), with the
bound from :mod:`inertia_ros.core.crlb` averaged over the first few seeds (it depends on the
realised torque profile, not on the noise draw).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from inertia_ros.core.crlb import scene_fisher
from inertia_ros.core.inertia import matrix_to_theta
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

from .methods import MethodSpec

__all__ = ['Bound', 'Run', 'Summary', 'as_records', 'pareto_front', 'relative_error',
           'run_monte_carlo', 'scene_bound', 'summarize']


@dataclass(frozen=True)
class Run:
    """One setting on one record.

    Attributes
    ----------
    scene, method : str
        Names.
    seed : int
        Simulation seed.
    status : str
        Estimator status.
    error : float
        Relative Frobenius error (NaN when no complete tensor was returned).
    theta_error : numpy.ndarray, shape (6,)
        ``theta_hat - theta`` [kg m^2] (NaN when none).
    seconds : float
        Compute time of the estimator call [s].
    """

    scene: str
    method: str
    seed: int
    status: str
    error: float
    theta_error: np.ndarray
    seconds: float


@dataclass(frozen=True)
class Bound:
    """Cramer-Rao bound of a scene.

    Attributes
    ----------
    theta_var : numpy.ndarray, shape (6,)
        Bound on the variance of each element [kg^2 m^4], mean over the seeds used.
    rel_frobenius : float
        ``sqrt(E||dI||_F^2 bound) / ||I||_F``: the smallest RMS relative Frobenius error.
    spread : float
        Relative spread (max/min - 1) of the trace of the bound over the seeds used.
    seeds : int
        Number of records the bound was averaged over.
    nuisances : tuple of str
        Nuisance parameters in the model (initial rate, and the bias when estimated).
    """

    theta_var: np.ndarray
    rel_frobenius: float
    spread: float
    nuisances: tuple[str, ...]
    seeds: int = 1


def relative_error(I_hat: np.ndarray | None, I_true: np.ndarray) -> float:
    """``||I_hat - I||_F / ||I||_F``, NaN when ``I_hat`` is None or not finite."""
    if I_hat is None or not np.all(np.isfinite(I_hat)):
        return float('nan')
    return float(np.linalg.norm(I_hat - I_true) / np.linalg.norm(I_true))


def scene_bound(scene: Scene, seeds: Sequence[int]) -> Bound:
    """The Cramer-Rao bound of ``scene`` averaged over the records of ``seeds``.

    The bound depends on the realised torque profile (random for PRBS or steps), not on the
    noise draw; for an estimator run on the same records, ``E[err^2] >= mean(CRLB)``.

    Parameters
    ----------
    scene : Scene
        A scene with gyro noise and a constant tensor.
    seeds : sequence of int
        Simulation seeds (only the torque profile matters).

    Returns
    -------
    Bound
    """
    if len(seeds) == 0:
        raise ValueError('seeds: need at least one seed')
    vars_, frob = [], []
    names: tuple[str, ...] = ()
    I = None
    for s in seeds:
        sim = simulate(scene, seed=int(s))
        fr = scene_fisher(sim)
        vars_.append(np.diag(fr.theta_covariance()))
        frob.append(fr.frobenius_mse())
        names = fr.names[6:]
        I = sim.inertia
    v = np.mean(vars_, axis=0)
    tr = np.sum(vars_, axis=1)
    assert I is not None
    return Bound(theta_var=v, rel_frobenius=float(np.sqrt(np.mean(frob)) / np.linalg.norm(I)),
                 spread=float(np.max(tr) / np.min(tr) - 1.0), nuisances=names,
                 seeds=len(seeds))


def run_monte_carlo(scenes: dict[str, Scene], specs: Sequence[MethodSpec],
                    runs: dict[str, int], base_seed: int = 1000,
                    progress: Callable[[str], None] | None = None) -> list[Run]:
    """Run every setting on ``runs[name]`` seeded records of every scene.

    Parameters
    ----------
    scenes : dict of str to Scene
        Scenes by name.
    specs : sequence of MethodSpec
        Settings.
    runs : dict of str to int
        Records per scene (>= 1).
    base_seed : int
        Record ``i`` uses seed ``base_seed + i``.
    progress : callable, optional
        Called with a short label after every estimate.

    Returns
    -------
    list of Run
    """
    out: list[Run] = []
    for name, scene in scenes.items():
        n = int(runs[name])
        if n < 1:
            raise ValueError(f'runs[{name!r}]: must be >= 1, got {n}')
        for i in range(n):
            seed = base_seed + i
            sim = simulate(scene, seed=seed)
            theta = matrix_to_theta(sim.inertia)
            for spec in specs:
                if i == 0:
                    spec.run(sim)               # warm-up: imports, caches, first-call costs
                o = spec.run(sim)
                err = relative_error(o.inertia, sim.inertia)
                th = (matrix_to_theta(o.inertia) - theta if np.isfinite(err)
                      else np.full(6, np.nan))
                out.append(Run(name, spec.name, seed, o.status, err, th, o.seconds))
                if progress is not None:
                    progress(f'{name} {spec.name}')
    return out


@dataclass(frozen=True)
class Summary:
    """Statistics of one setting on one scene.

    Attributes
    ----------
    scene, method : str
    runs, ok : int
        Records, and records with status ``ok`` and a complete tensor.
    median_error, p90_error : float
        Relative Frobenius error over the ok records.
    median_seconds : float
        Median compute time over all records [s].
    mse : numpy.ndarray, shape (6,)
        Mean squared element error over the ok records [kg^2 m^4].
    efficiency : float
        ``trace(CRLB) / trace(MSE)``.
    efficiency_se : float
        Monte Carlo standard error of ``efficiency`` (delta method).
    efficiency_elements : numpy.ndarray, shape (6,)
        ``CRLB_ii / MSE_i``.
    silent : int
        Records with status ok and error above the silent-failure threshold.
    """

    scene: str
    method: str
    runs: int
    ok: int
    median_error: float
    p90_error: float
    median_seconds: float
    mse: np.ndarray
    efficiency: float
    efficiency_se: float
    efficiency_elements: np.ndarray
    silent: int


def summarize(runs: Sequence[Run], bounds: dict[str, Bound], silent_threshold: float = 0.1
              ) -> list[Summary]:
    """Per (scene, method) statistics in the order first seen.

    Parameters
    ----------
    runs : sequence of Run
    bounds : dict of str to Bound
        Bound per scene (scenes without one get NaN efficiencies).
    silent_threshold : float
        Relative error above which an ok result counts as a silent failure.

    Returns
    -------
    list of Summary
    """
    keys: list[tuple[str, str]] = []
    groups: dict[tuple[str, str], list[Run]] = {}
    for r in runs:
        k = (r.scene, r.method)
        if k not in groups:
            keys.append(k)
            groups[k] = []
        groups[k].append(r)
    out = []
    for k in keys:
        g = groups[k]
        ok = [r for r in g if r.status == 'ok' and np.isfinite(r.error)]
        errs = np.array([r.error for r in ok])
        secs = np.array([r.seconds for r in g if np.isfinite(r.seconds)])
        nan6 = np.full(6, np.nan)
        if ok:
            th = np.array([r.theta_error for r in ok])
            mse = np.mean(th ** 2, axis=0)
            per_run = np.sum(th ** 2, axis=1)
        else:
            mse, per_run = nan6, np.array([np.nan])
        b = bounds.get(k[0])
        if b is not None and ok:
            eff = float(np.sum(b.theta_var) / np.sum(mse))
            rel_se = float(np.std(per_run, ddof=1) / np.sqrt(len(per_run)) / np.mean(per_run)
                           ) if len(per_run) > 1 else float('nan')
            eff_se = eff * rel_se
            with np.errstate(divide='ignore', invalid='ignore'):
                eff_el = b.theta_var / mse
        else:
            eff, eff_se, eff_el = float('nan'), float('nan'), nan6
        out.append(Summary(
            scene=k[0], method=k[1], runs=len(g), ok=len(ok),
            median_error=float(np.median(errs)) if ok else float('nan'),
            p90_error=float(np.percentile(errs, 90)) if ok else float('nan'),
            median_seconds=float(np.median(secs)) if len(secs) else float('nan'),
            mse=mse, efficiency=eff, efficiency_se=eff_se, efficiency_elements=eff_el,
            silent=int(np.sum(errs > silent_threshold)) if ok else 0))
    return out


def pareto_front(points: Sequence[tuple[float, float]]) -> list[int]:
    """Indices of the points not dominated in (time, error), sorted by time.

    A point is dominated when another is at least as fast and at least as accurate and
    strictly better in one.  NaN points are never on the front.
    """
    idx = [i for i, (t, e) in enumerate(points) if np.isfinite(t) and np.isfinite(e)]
    front = []
    for i in idx:
        ti, ei = points[i]
        dominated = any((points[j][0] <= ti and points[j][1] <= ei)
                        and (points[j][0] < ti or points[j][1] < ei) for j in idx if j != i)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def as_records(summaries: Sequence[Summary]) -> list[dict[str, Any]]:
    """Plain dicts of the summaries (for JSON)."""
    return [{'scene': s.scene, 'method': s.method, 'runs': s.runs, 'ok': s.ok,
             'median_error': s.median_error, 'p90_error': s.p90_error,
             'median_seconds': s.median_seconds, 'mse': s.mse.tolist(),
             'efficiency': s.efficiency, 'efficiency_se': s.efficiency_se,
             'efficiency_elements': s.efficiency_elements.tolist(), 'silent': s.silent}
            for s in summaries]
