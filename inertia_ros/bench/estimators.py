"""``bench estimators``: batch speed on a long record, recursive cost, accuracy per method.

Prints four blocks of figures:

* default: the default method's time per 60 s record (median of 25 calls) and its
  efficiency against the Cramer-Rao bound (:func:`bench_default_record`; alone:
  ``python -m inertia_ros.bench.estimators [--hour]``);
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
from inertia_ros.runtime import keep_freed_memory

from .common import ROOT, best_of, nominal_scene, process_env, relative_error, timed_process

__all__ = ['PAIRED_CALLS', 'bench_accuracy', 'bench_batch', 'bench_default_record',
           'bench_paired', 'bench_recursive_cost', 'main', 'run']


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
    bench_default_record(seeds=max(seeds, 2))
    bench_batch(sim)
    bench_recursive_cost(sim, n_single=50_000 if quick else 200_000)
    bench_accuracy(seeds)
    return 0


def _timings(fn: Any, runs: int) -> np.ndarray:
    """Wall times [s] of ``runs`` calls of ``fn`` after one warm-up call."""
    fn()
    out = np.empty(runs)
    for i in range(runs):
        t0 = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t0
    return out


def bench_default_record(runs: int = 25, seeds: int = 30, hour: bool = False
                         ) -> dict[str, float]:
    """Print and return the default method's time per 60 s record and its efficiency.

    Time: ``estimate()`` with default options on the nominal record (60 s, gyro 200 Hz,
    torque 50 Hz, seed 1), median of ``runs`` calls after a warm-up (also ``integral`` for
    reference; with ``hour``, the one-hour record, median of 5).  Efficiency:
    ``trace(CRLB) / trace(MSE)`` of the default method over ``seeds`` records of the nominal
    scene (seeds 1000, 1001, ...; the bound of the first two), as ``make bench`` computes it.

    Returns
    -------
    dict
        ``median_ms``, ``integral_median_ms``, ``efficiency``, ``efficiency_se``,
        ``mse_over_crlb`` (and ``hour_median_s``).
    """
    from .methods import DEFAULT_METHOD, method_specs
    from .montecarlo import run_monte_carlo, scene_bound, summarize

    sim = simulate(nominal_scene(60.0), seed=1)
    args = (sim.t_gyro, sim.omega, sim.t_torque, sim.torque)
    est = estimate(*args)
    t_def = _timings(lambda: estimate(*args), runs)
    t_int = _timings(lambda: estimate(*args, method='integral'), runs)
    print(f'default method per record: {len(sim.t_gyro)} gyro + {len(sim.t_torque)} torque '
          f'samples (60 s), method {est.method}, status {est.status}, {runs} runs')
    print(f'  default  median {1e3 * np.median(t_def):7.2f} ms (min {1e3 * np.min(t_def):.2f},'
          f' 90th percentile {1e3 * np.percentile(t_def, 90):.2f})')
    print(f'  integral median {1e3 * np.median(t_int):7.2f} ms (min {1e3 * np.min(t_int):.2f})')
    out = {'median_ms': 1e3 * float(np.median(t_def)),
           'integral_median_ms': 1e3 * float(np.median(t_int))}
    if hour:
        long = simulate(nominal_scene(3600.0), seed=1)
        t_h = _timings(lambda: estimate(long.t_gyro, long.omega, long.t_torque, long.torque), 5)
        out['hour_median_s'] = float(np.median(t_h))
        print(f'  one-hour record ({len(long.t_gyro)} gyro samples): median '
              f'{np.median(t_h):.3f} s of 5 (min {np.min(t_h):.3f})')
    scene = nominal_scene(60.0)
    spec = next(s for s in method_specs(include_pinocchio=False, quick=True)[0]
                if s.name == DEFAULT_METHOD)
    mc = run_monte_carlo({'nominal': scene}, [spec], {'nominal': seeds})
    s = summarize(mc, {'nominal': scene_bound(scene, [1000, 1001])})[0]
    out.update(efficiency=s.efficiency, efficiency_se=s.efficiency_se,
               mse_over_crlb=1.0 / s.efficiency)
    print(f'  efficiency trace(CRLB)/trace(MSE) {s.efficiency:.2f} +- {s.efficiency_se:.2f} '
          f'over {s.ok}/{s.runs} ok records: MSE = {1.0 / s.efficiency:.2f} x the bound; '
          f'median compute time there {1e3 * s.median_seconds:.1f} ms')
    return out


#: Timer run in a fresh interpreter on one source tree (older trees too: it imports only
#: ``estimate``, and the heap setting where the tree has it, "as it ran" otherwise).
_PAIRED_TIMER = """
import json, sys, time
import numpy as np
try:
    from inertia_ros.runtime import keep_freed_memory
    keep_freed_memory()
except ImportError:
    pass
from inertia_ros.core.estimation import estimate
z = np.load(sys.argv[1])
args = (z['tg'], z['w'], z['ts'], z['tau'])
runs = int(sys.argv[2])
out, cpu = {}, {}
for label, kw in json.loads(sys.argv[3]).items():
    try:
        estimate(*args, **kw)
    except (TypeError, ValueError):           # an option the tree does not have
        out[label] = cpu[label] = None
        continue
    t, c = [], []
    for _ in range(runs):
        c0, t0 = time.process_time(), time.perf_counter()
        estimate(*args, **kw)
        t.append(time.perf_counter() - t0)
        c.append(time.process_time() - c0)
    out[label] = 1e3 * float(np.median(t))
    cpu[label] = 1e3 * float(np.median(c))
print(json.dumps({'wall': out, 'cpu': cpu}))
"""

#: The calls the paired comparison times (label: ``estimate`` options).
PAIRED_CALLS = {'default': {}, 'ml, hold zoh': {'hold': 'zoh'},
                'integral': {'method': 'integral'},
                'integral, hold zoh': {'method': 'integral', 'hold': 'zoh'}}
#: Speed-up over the other tree each call should reach (``other / this``), where one is set:
#: the default estimate per record at least twice as fast as the code of the day issue 26
#: was filed (5a72dae).
PAIRED_TARGETS = {'default': 2.0}


#: ``--long``: the default call on longer nominal records (seconds: timed calls per round).
LONG_RECORDS = {300.0: 7, 3600.0: 5}


def bench_paired(other: str, runs: int = 25, rounds: int = 3, seconds: float = 60.0,
                 calls: dict[str, dict] | None = None) -> dict[str, list]:
    """Time :data:`PAIRED_CALLS` (or ``calls``) on a nominal record in this tree and ``other``.

    Each round runs ``other`` and then this tree, each in a fresh interpreter with its own
    bytecode cache (median of ``runs`` calls after a warm-up), so both meet the same machine
    load; the record is simulated here once and given to both.  Each call is timed as wall
    time and as the process's CPU time (on a shared, loaded machine the CPU time waits for
    no other process: the steadier ratio); the ratios ``other / this`` of the medians over
    the rounds are printed, with :data:`PAIRED_TARGETS`.

    Parameters
    ----------
    other : str
        Root of another source tree of the package (e.g. a ``git worktree`` of an old commit).
    runs, rounds : int
        Timed calls per median; alternating rounds.
    seconds : float
        Length of the nominal record (60 s; ``--long``: :data:`LONG_RECORDS`).
    calls : dict, optional
        The calls to time (default :data:`PAIRED_CALLS`).

    Returns
    -------
    dict
        ``{'other': [...], 'this': [...], 'other_cpu': [...], 'this_cpu': [...]}``: per
        round, ``{label: median wall (or CPU) ms, or None}``.
    """
    import json
    import os
    import sys
    import tempfile

    calls = PAIRED_CALLS if calls is None else calls
    sim = simulate(nominal_scene(seconds), seed=1)
    print(f'nominal record of {seconds:g} s ({len(sim.t_gyro)} gyro samples), {runs} calls')
    res: dict[str, list] = {'other': [], 'this': [], 'other_cpu': [], 'this_cpu': []}
    with tempfile.TemporaryDirectory(prefix='inertia_paired_') as tmp:
        rec = os.path.join(tmp, 'record.npz')
        np.savez(rec, tg=sim.t_gyro, w=sim.omega, ts=sim.t_torque, tau=sim.torque)
        cmd = [sys.executable, '-c', _PAIRED_TIMER, rec, str(runs), json.dumps(calls)]
        for r in range(rounds):
            for name, tree in (('other', other), ('this', ROOT)):
                env = process_env(pycache=os.path.join(tmp, 'pyc_' + name), tree=tree)
                try:
                    out = timed_process(cmd, env, cwd=tmp)[1]
                except RuntimeError as exc:
                    raise RuntimeError(f'{tree}: the timer failed: {exc}') from None
                got = json.loads(out)
                res[name].append(got['wall'])
                res[name + '_cpu'].append(got['cpu'])
                row = ', '.join(f'{k} {v:.1f} ms' if v is not None else f'{k} -'
                                for k, v in got['wall'].items())
                print(f'  round {r + 1} {name:5s} {row}')
    for label in calls:
        _print_ratio(label, res, target=seconds == 60.0)   # the target: per 60 s
    return res


def _print_ratio(label: str, res: dict[str, list], target: bool = True) -> None:
    """One line of :func:`bench_paired`: both trees' wall and CPU medians, ``other / this``."""
    parts = []
    for kind in ('', '_cpu'):
        a = [d[label] for d in res['other' + kind] if d[label] is not None]
        b = [d[label] for d in res['this' + kind] if d[label] is not None]
        if not (a and b):
            return
        parts.append(f'{"cpu" if kind else "wall"}: other {min(a):6.1f}-{max(a):6.1f} ms, '
                     f'this {min(b):6.1f}-{max(b):6.1f} ms, {np.median(a) / np.median(b):.2f}x')
    goal = PAIRED_TARGETS.get(label) if target else None
    print(f'  {label:20s} ' + '; '.join(parts)
          + (f' (target {goal:g}x)' if goal is not None else ''))


def main(argv: list[str] | None = None) -> int:
    """``python -m inertia_ros.bench.estimators [--runs N] [--seeds N] [--hour] [--vs TREE
    [--long]]``.

    The default method's per-record time and efficiency alone (:func:`bench_default_record`);
    with ``--vs``, its time paired with another source tree's (:func:`bench_paired`).
    """
    import argparse

    p = argparse.ArgumentParser(prog='python -m inertia_ros.bench.estimators',
                                description='the default method per 60 s record: time '
                                '(median of --runs) and efficiency against the bound')
    p.add_argument('--runs', type=int, default=25, help='timed calls (25)')
    p.add_argument('--seeds', type=int, default=30, help='records for the efficiency (30)')
    p.add_argument('--hour', action='store_true', help='also time the one-hour record')
    p.add_argument('--vs', metavar='TREE', help='instead: time the nominal record in this '
                   'source tree and in TREE (e.g. a git worktree of an older commit), '
                   'alternating')
    p.add_argument('--rounds', type=int, default=3, help='alternating rounds with --vs (3)')
    p.add_argument('--long', action='store_true', help='with --vs: also the default call on '
                   'the 300 s and 3600 s records (7 and 5 calls per round)')
    a = p.parse_args(argv)
    keep_freed_memory()               # as the CLI and the nodes run
    if a.runs < 20 or a.seeds < 2 or a.rounds < 1:
        p.error('--runs must be >= 20, --seeds >= 2 and --rounds >= 1')
    if a.vs is not None:
        from pathlib import Path

        if not (Path(a.vs) / 'inertia_ros' / 'core' / 'estimation').is_dir():
            p.error(f'--vs {a.vs}: not a source tree of inertia_ros (no '
                    'inertia_ros/core/estimation there); make one with git worktree add')
        try:
            bench_paired(a.vs, a.runs, a.rounds)
            for seconds, n in (LONG_RECORDS.items() if a.long else ()):
                bench_paired(a.vs, n, a.rounds, seconds, {'default': {}})
        except RuntimeError as exc:
            p.exit(1, f'{p.prog}: error: {exc}\n')
        return 0
    bench_default_record(a.runs, a.seeds, a.hour)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
