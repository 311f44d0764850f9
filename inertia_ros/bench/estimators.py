"""``bench estimators``: batch speed on a long record, recursive cost, accuracy per method.

Prints three blocks of figures:

* batch: :func:`~inertia_ros.core.estimation.estimate` on a physically simulated nominal
  record of 1 000 001 gyro samples (200 Hz, 5000 s, 250 000 torque samples; ``--quick``: a
  tenth), default options and a fixed model, best of 3;
* recursive: :class:`~inertia_ros.core.estimation.RecursiveEstimator` fed the same record in
  10 ms blocks (as the node's callbacks batch them) and one sample at a time, microseconds
  per gyro sample, and the cost of one ``estimate()``;
* accuracy: every method of ``--method`` on the nominal scene (60 s, full model, bias off)
  over N seeds: statuses, mean relative Frobenius error of the ok results, median time; ml
  against integral.

Timings depend on the machine's load; the best of several runs is reported.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from inertia_ros.core.estimation import RecursiveEstimator, estimate
from inertia_ros.core.estimation.options import METHODS
from inertia_ros.core.simulation import simulate

from .common import best_of, nominal_scene, relative_error

__all__ = ['bench_accuracy', 'bench_batch', 'bench_recursive_cost', 'run']


def bench_batch(sim: Any) -> None:
    """Print the batch estimate's wall time on the long record, three option sets."""
    args = (sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
    print(f'batch: {len(sim.t_gyro)} gyro samples, {len(sim.t_torque)} torque samples')
    for label, kw in (('default (auto method, model, bias, segment)', {}),
                      ("model='full', torque_bias='off'", {'model': 'full',
                                                            'torque_bias': 'off'}),
                      ("model='full', torque_bias='off', segment=10",
                       {'model': 'full', 'torque_bias': 'off', 'segment': 10.0})):
        dt, est = best_of(lambda kw=kw: estimate(*args, **kw))
        print(f'  {label:48s} {dt:7.3f} s   method {est.method}, status {est.status}, '
              f'model {est.model}, error {relative_error(est.inertia, sim.inertia):.2e}')


def _feed_blocks(sim: Any, block: float = 0.01) -> RecursiveEstimator:
    """The record into a full-model RecursiveEstimator in ``block``-second slices."""
    t_g, w, t_t, tau = sim.t_gyro, sim.omega, sim.t_torque, sim.torque
    edges = np.arange(0.0, t_g[-1] + block, block)
    ig, it = np.searchsorted(t_g, edges), np.searchsorted(t_t, edges)
    rec = RecursiveEstimator(model='full')
    for k in range(len(edges) - 1):
        rec.add_torque(t_t[it[k]:it[k + 1]], tau[it[k]:it[k + 1]])
        rec.add_gyro(t_g[ig[k]:ig[k + 1]], w[ig[k]:ig[k + 1]])
    rec.add_torque(t_t[it[-1]:], tau[it[-1]:])
    return rec


def _feed_singles(sim: Any, n: int) -> RecursiveEstimator:
    """The first ``n`` gyro samples (and their torque) one Python tuple per call."""
    tg = sim.t_gyro[:n].tolist()
    w = [tuple(r) for r in sim.omega[:n]]
    tt = sim.t_torque[:n // 4 + 2].tolist()
    tau = [tuple(r) for r in sim.torque[:n // 4 + 2]]
    rec = RecursiveEstimator(model='full')
    j = 0
    for i in range(len(tg)):
        while j < len(tt) and tt[j] <= tg[i]:
            rec.add_torque(tt[j], tau[j])
            j += 1
        rec.add_gyro(tg[i], w[i])
    return rec


def bench_recursive_cost(sim: Any, n_single: int) -> None:
    """Print the recursive estimator's cost per gyro sample, in blocks and one at a time."""
    n = len(sim.t_gyro)
    dt, rec = best_of(lambda: _feed_blocks(sim), repeat=2)
    est = rec.estimate()
    print(f'recursive, 10 ms blocks: {1e6 * dt / n:6.2f} us per gyro sample ({n} samples), '
          f'error {relative_error(est.inertia, sim.inertia):.2e}')
    n_single = min(n_single, n)
    dt, rec = best_of(lambda: _feed_singles(sim, n_single), repeat=2)
    print(f'recursive, one sample per call: {1e6 * dt / n_single:6.2f} us per gyro sample '
          f'(incl. the torque calls; {n_single} samples)')
    t0 = time.perf_counter()
    for _ in range(10):
        rec.estimate()
    print(f'recursive estimate(): {1e3 * (time.perf_counter() - t0) / 10:.2f} ms per call')


def bench_accuracy(seeds: int) -> dict[str, dict[str, Any]]:
    """Print and return, per method, the mean error, median time and statuses (60 s scene).

    Returns
    -------
    dict
        ``{method: {'errors': [...], 'seconds': [...], 'statuses': {status: count}}}``.
    """
    scene = nominal_scene(60.0)
    out: dict[str, dict[str, Any]] = {m: {'errors': [], 'seconds': [], 'statuses': {}}
                                      for m in METHODS}
    for seed in range(seeds):
        sim = simulate(scene, seed=seed)
        for m in METHODS:
            t0 = time.perf_counter()
            est = estimate(sim.t_gyro, sim.omega, sim.t_torque, sim.torque, method=m,
                           model='full', torque_bias='off')
            out[m]['seconds'].append(time.perf_counter() - t0)
            out[m]['statuses'][est.status] = out[m]['statuses'].get(est.status, 0) + 1
            if est.status == 'ok':
                out[m]['errors'].append(relative_error(est.inertia, sim.inertia))
    print(f'accuracy on the nominal scene (60 s, full model), {seeds} seeds:')
    for m, r in out.items():
        e = (f'mean relative Frobenius error {np.mean(r["errors"]):.2e} '
             f'(max {np.max(r["errors"]):.2e})' if r['errors'] else 'no ok result')
        print(f'  {m:18s} {e}, median time {1e3 * np.median(r["seconds"]):6.1f} ms, '
              f'statuses {r["statuses"]}')
    if out['ml']['errors'] and out['integral']['errors']:
        t_ratio = np.median(out['ml']['seconds']) / np.median(out['integral']['seconds'])
        e_ratio = np.mean(out['integral']['errors']) / np.mean(out['ml']['errors'])
        print(f'  ml: {t_ratio:.1f}x the time of integral, mean error {e_ratio:.2f}x smaller')
    return out


def run(quick: bool = False, seeds: int = 10) -> int:
    """Run the three blocks; return the exit status (0).

    Parameters
    ----------
    quick : bool
        A 500 s record (100 001 gyro samples) and 50 000 single-sample calls instead of
        5000 s and 200 000.
    seeds : int
        Records per method in the accuracy block.
    """
    duration = 500.0 if quick else 5000.0
    t0 = time.perf_counter()
    sim = simulate(nominal_scene(duration), seed=1)
    print(f'simulated {duration:g} s in {time.perf_counter() - t0:.1f} s')
    bench_batch(sim)
    bench_recursive_cost(sim, n_single=50_000 if quick else 200_000)
    bench_accuracy(seeds)
    return 0
