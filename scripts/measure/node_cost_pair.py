"""Paired CPU cost of the node's estimator per 60 s record: two source trees, alternated.

    .venv/bin/python scripts/measure/node_cost_pair.py TREE_A TREE_B [--rounds 6]
        [--seeds 0 1 2] [--holds default zoh] [--repeats 3]
    .venv/bin/python scripts/measure/node_cost_pair.py A B --table OUTPUT.txt  (re-summarise)

CPU seconds (``time.process_time``) to feed a 60 s reference record (``bench.truth_sim``,
200 Hz gyro, 50 Hz torque, the scene of docs/BENCHMARKS.md "The node's estimator per record
against the issue's start") to the estimator the node builds (``make_estimator`` with the
node's parameter defaults; ``--holds``: ``default`` or a hold; ``batchD``: instead the batch
``estimate()`` at its defaults on a D-second record) in 0.1 s blocks, sample by
sample, with an estimate and a refresh after each block (the node's cadence).  Each
measurement is one process with ``PYTHONPATH`` set to the tree (``OPENBLAS_NUM_THREADS=1``),
the minimum of ``--repeats`` runs in it; the trees alternate within each (round, seed, hold)
and their order flips every round.  Prints one line per measurement and a table of the
per-pair ratios B / A (median and range) and the median CPU seconds of each tree.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

#: One tree's measurement, run in a child process (argv: hold, seed, repeats).
_CHILD = r'''
import sys, time
import numpy as np
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.nodes import params
try:
    from inertia_ros.nodes.selection import make_estimator
except ImportError:                       # the trees before nodes/selection.py
    from inertia_ros.nodes.estimator import make_estimator
hold, seed, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
if hold.startswith('batch'):              # the batch estimate() at its defaults instead
    from inertia_ros.core.estimation import estimate
    rec = simulate_truth(SCENE.with_(duration=float(hold[5:])), [seed])[0]
    best = None
    for _ in range(repeats):
        c0 = time.process_time()
        last = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
        cpu = time.process_time() - c0
        best = cpu if best is None else min(best, cpu)
    print(f'{best:.4f} {last.status} {hold}')
    sys.exit(0)
rec = simulate_truth(SCENE.with_(duration=60.0), [seed])[0]
cfg = {n: s.default for n, s in params.ESTIMATOR.items()}
if hold != 'default':
    cfg['hold'] = hold
edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1)
gi = np.searchsorted(rec.t_gyro, edges, side='right')
ti = np.searchsorted(rec.t_torque, edges, side='right')
best = None
for _ in range(repeats):
    est = make_estimator(cfg)()
    c0 = time.process_time()
    for k in range(1, len(edges)):
        for j in range(ti[k - 1], ti[k]):
            est.add_torque(float(rec.t_torque[j]), rec.torque[j])
        for j in range(gi[k - 1], gi[k]):
            est.add_gyro(float(rec.t_gyro[j]), rec.omega[j])
        last = est.estimate()
        if hasattr(est, 'refresh'):
            est.refresh()
    cpu = time.process_time() - c0
    best = cpu if best is None else min(best, cpu)
print(f'{best:.4f} {last.status} {cfg["hold"]}')
'''


def measure(tree: Path, hold: str, seed: int, repeats: int) -> tuple[float, str]:
    """CPU seconds of one tree's run (the minimum of ``repeats``) and its final status."""
    env = dict(os.environ, PYTHONPATH=str(tree), OPENBLAS_NUM_THREADS='1')
    out = subprocess.run([sys.executable, '-c', _CHILD, hold, str(seed), str(repeats)],
                         env=env, cwd=tree, capture_output=True, text=True, check=True)
    cpu, status, _ = out.stdout.split()[-3:]
    return float(cpu), status


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('tree_a', type=Path)
    ap.add_argument('tree_b', type=Path)
    ap.add_argument('--rounds', type=int, default=6)
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    ap.add_argument('--holds', nargs='+', default=['default', 'zoh'])
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--table', type=Path, help='summarise the lines of an earlier run (its '
                    'printed output) instead of measuring')
    a = ap.parse_args()
    if a.table is not None:
        cpu_t: dict[tuple[str, int], dict[tuple[int, int], float]] = {}
        names: list[str] = []
        for line in a.table.read_text().splitlines():
            f = line.split()
            if len(f) == 6 and f[0].isdigit():
                names += [f[3]] if f[3] not in names else []
                cpu_t.setdefault((f[2], names.index(f[3])), {})[(int(f[0]), int(f[1]))] = \
                    float(f[4])
        summarise(cpu_t, [h for h in a.holds if (h, 0) in cpu_t], names[0], names[1])
        return
    trees = [a.tree_a.resolve(), a.tree_b.resolve()]
    for tree in trees:
        if not (tree / 'inertia_ros' / '__init__.py').is_file():
            sys.exit(f'{tree}: not a source tree (no inertia_ros/__init__.py); give a '
                     'checkout or worktree')
    cpu: dict[tuple[str, int], dict[tuple[int, int], float]] = {}
    for r in range(a.rounds):
        for seed in a.seeds:
            for hold in a.holds:
                for i in (0, 1) if r % 2 == 0 else (1, 0):
                    c, status = measure(trees[i], hold, seed, a.repeats)
                    cpu.setdefault((hold, i), {})[(r, seed)] = c
                    print(f'{r} {seed} {hold} {trees[i].name} {c:.4f} {status}', flush=True)
    summarise(cpu, a.holds, trees[0].name, trees[1].name)


def summarise(cpu: dict[tuple[str, int], dict[tuple[int, int], float]], holds: list[str],
              name_a: str, name_b: str) -> None:
    """The table: per hold the median and the least CPU seconds of each tree (the least is
    the run the other processes disturbed least: their load only adds time) and the ratios
    B / A, per pair (median, range) and of the least."""
    print(f'\n| hold | {name_a} median (least) | {name_b} median (least) | {name_b} / {name_a}: '
          'median of pairs (range) | of the least | pairs |\n|---|---|---|---|---|---|')
    for hold in holds:
        A, B = cpu[(hold, 0)], cpu[(hold, 1)]
        ratios = [B[k] / A[k] for k in sorted(A) if k in B]
        print(f'| {hold} | {statistics.median(A.values()):.3f} s ({min(A.values()):.3f} s) | '
              f'{statistics.median(B.values()):.3f} s ({min(B.values()):.3f} s) | '
              f'{statistics.median(ratios):.3f} ({min(ratios):.2f}-{max(ratios):.2f}) | '
              f'{min(B.values()) / min(A.values()):.3f} | {len(ratios)} |')


if __name__ == '__main__':
    main()
