#!/usr/bin/env python3
"""Speed and accuracy benchmark of the inertia estimators (issue 4); prints the figures.

    .venv/bin/python scripts/bench_estimators.py [--quick] [--seeds N]

* batch: ``estimate()`` on a physically simulated nominal record of 1 000 001 gyro samples
  (200 Hz, 5000 s, 250 000 torque samples), default options and fixed model, best of 3;
* recursive: ``RecursiveEstimator`` fed the same record in 10 ms blocks (as the node's
  callbacks would batch them) and one sample at a time, microseconds per gyro sample;
* accuracy: every method on the nominal scene (60 s) over N seeds: statuses, mean relative
  Frobenius error of the ok results, median time; ml against integral.

Timings depend on the machine's load; the script reports wall-clock best-of-3.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from inertia_ros.core.estimation import METHODS, RecursiveEstimator, estimate  # noqa: E402
from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402


def nominal(duration: float) -> dict:
    """The default scene dict with another duration."""
    d = yaml.safe_load((ROOT / 'config' / 'scenes' / 'default.yaml').read_text())
    d['duration'] = duration
    return d


def best_of(fn, repeat: int = 3) -> tuple[float, object]:
    """Best wall-clock time of ``repeat`` calls and the last result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def rel_err(I_est: np.ndarray, I_true: np.ndarray) -> float:
    """Relative Frobenius error."""
    return float(np.linalg.norm(I_est - I_true) / np.linalg.norm(I_true))


def bench_batch(sim) -> None:
    """Batch estimation on the long record."""
    n = len(sim.t_gyro)
    args = (sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
    print(f'batch: {n} gyro samples, {len(sim.t_torque)} torque samples')
    for label, kw in (('default (auto method, model, bias, segment)', {}),
                      ("model='full', torque_bias='off'", dict(model='full', torque_bias='off')),
                      ("model='full', torque_bias='off', segment=10", dict(
                          model='full', torque_bias='off', segment=10.0))):
        dt, est = best_of(lambda kw=kw: estimate(*args, **kw))
        print(f'  {label:48s} {dt:7.3f} s   method {est.method}, status {est.status}, '
              f'model {est.model}, '
              f'error {rel_err(est.inertia, sim.inertia):.2e}')


def bench_recursive(sim, n_single: int) -> None:
    """Recursive estimator cost per gyro sample."""
    t_g, w, t_t, tau = sim.t_gyro, sim.omega, sim.t_torque, sim.torque
    edges = np.arange(0.0, t_g[-1] + 0.01, 0.01)
    ig = np.searchsorted(t_g, edges)
    it = np.searchsorted(t_t, edges)

    def blocks() -> RecursiveEstimator:
        rec = RecursiveEstimator(model='full')
        for k in range(len(edges) - 1):
            rec.add_torque(t_t[it[k]:it[k + 1]], tau[it[k]:it[k + 1]])
            rec.add_gyro(t_g[ig[k]:ig[k + 1]], w[ig[k]:ig[k + 1]])
        rec.add_torque(t_t[it[-1]:], tau[it[-1]:])
        return rec

    dt, rec = best_of(blocks, repeat=2)
    est = rec.estimate()
    print(f'recursive, 10 ms blocks: {1e6 * dt / len(t_g):6.2f} us per gyro sample '
          f'({len(t_g)} samples), error {rel_err(est.inertia, sim.inertia):.2e}')
    tg_l = t_g[:n_single].tolist()
    w_l = [tuple(r) for r in w[:n_single]]
    tt_l = t_t[:n_single // 4 + 2].tolist()
    tau_l = [tuple(r) for r in tau[:n_single // 4 + 2]]

    def singles() -> RecursiveEstimator:
        rec = RecursiveEstimator(model='full')
        j = 0
        for i in range(n_single):
            while j < len(tt_l) and tt_l[j] <= tg_l[i]:
                rec.add_torque(tt_l[j], tau_l[j])
                j += 1
            rec.add_gyro(tg_l[i], w_l[i])
        return rec

    dt, rec = best_of(singles, repeat=2)
    print(f'recursive, one sample per call: {1e6 * dt / n_single:6.2f} us per gyro sample '
          f'(incl. the torque calls; {n_single} samples)')
    t0 = time.perf_counter()
    for _ in range(10):
        rec.estimate()
    print(f'recursive estimate(): {1e3 * (time.perf_counter() - t0) / 10:.2f} ms per call')


def bench_accuracy(seeds: int) -> None:
    """Mean relative error and median time of every method on the nominal scene."""
    scene = Scene.from_dict(nominal(60.0))
    errs: dict[str, list[float]] = {m: [] for m in METHODS}
    secs: dict[str, list[float]] = {m: [] for m in METHODS}
    statuses: dict[str, dict[str, int]] = {m: {} for m in METHODS}
    for seed in range(seeds):
        sim = simulate(scene, seed=seed)
        for m in METHODS:
            t0 = time.perf_counter()
            est = estimate(sim.t_gyro, sim.omega, sim.t_torque, sim.torque, method=m,
                           model='full', torque_bias='off')
            secs[m].append(time.perf_counter() - t0)
            statuses[m][est.status] = statuses[m].get(est.status, 0) + 1
            if est.status == 'ok':
                errs[m].append(rel_err(est.inertia, sim.inertia))
    print(f'accuracy on the nominal scene (60 s, full model), {seeds} seeds:')
    for m in METHODS:
        e = (f'mean relative Frobenius error {np.mean(errs[m]):.2e} (max {np.max(errs[m]):.2e})'
             if errs[m] else 'no ok result')
        print(f'  {m:18s} {e}, median time {1e3 * np.median(secs[m]):6.1f} ms, '
              f'statuses {statuses[m]}')
    t_ratio = np.median(secs['ml']) / np.median(secs['integral'])
    e_ratio = np.mean(errs['integral']) / np.mean(errs['ml'])
    print(f'  ml: {t_ratio:.1f}x the time of integral, mean error {e_ratio:.2f}x smaller')


def main() -> None:
    """Run the benchmarks."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='100 000 samples instead of 1 000 000')
    ap.add_argument('--seeds', type=int, default=10, help='seeds for the accuracy table')
    a = ap.parse_args()
    duration = 500.0 if a.quick else 5000.0
    t0 = time.perf_counter()
    sim = simulate(Scene.from_dict(nominal(duration)), seed=1)
    print(f'simulated {duration:g} s in {time.perf_counter() - t0:.1f} s')
    bench_batch(sim)
    bench_recursive(sim, n_single=50_000 if a.quick else 200_000)
    bench_accuracy(a.seeds)


if __name__ == '__main__':
    main()
