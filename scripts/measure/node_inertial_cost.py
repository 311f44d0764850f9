"""The node's per-update cost with ``inertial_torque`` 'off' against 'auto' (paired, one run).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/measure/node_inertial_cost.py \
        [--seeds 0 1 2] [--repeats 3] [--duration 60] [--case conforming|disturbance]

The estimator the node builds (``make_estimator`` with the node's parameter defaults, hold
'auto'), fed a reference record (``bench.truth_sim``: the honesty scene, or the 5 s scene's
0.01 N m torque fixed in space, ``--duration`` s) in 0.1 s blocks sample by sample with an
estimate and a refresh after each block (the node's cadence).  For each seed the two options
alternate in one process (order flipped per seed), the minimum CPU time (``process_time``) of
``--repeats`` runs each; prints the ms per update of each, their ratio, and the median over
the seeds, with the final statuses.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.nodes import params
from inertia_ros.nodes.selection import make_estimator

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))


def feed(rec, option: str) -> tuple[float, int, str]:
    """CPU seconds of one feed, its updates and the last status."""
    cfg = dict({n: s.default for n, s in params.ESTIMATOR.items()}, inertial_torque=option)
    est = make_estimator(cfg)()
    edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1)
    gi = np.searchsorted(rec.t_gyro, edges, side='right')
    ti = np.searchsorted(rec.t_torque, edges, side='right')
    last = None
    c0 = time.process_time()
    for k in range(1, len(edges)):
        for j in range(ti[k - 1], ti[k]):
            est.add_torque(float(rec.t_torque[j]), rec.torque[j])
        for j in range(gi[k - 1], gi[k]):
            est.add_gyro(float(rec.t_gyro[j]), rec.omega[j])
        last = est.estimate()
        est.refresh()
    return time.process_time() - c0, len(edges) - 1, last.status


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--case', choices=('conforming', 'disturbance'), default='conforming')
    a = ap.parse_args()
    truth = SCENE if a.case == 'conforming' else CASES['disturbance'].truth
    ratios = []
    for i, seed in enumerate(a.seeds):
        rec = simulate_truth(truth.with_(duration=a.duration), [seed])[0]
        best: dict[str, float] = {}
        status: dict[str, str] = {}
        for _ in range(a.repeats):
            for opt in (('off', 'auto') if i % 2 == 0 else ('auto', 'off')):
                cpu, n, status[opt] = feed(rec, opt)
                best[opt] = min(best.get(opt, np.inf), 1e3 * cpu / n)
        ratios.append(best['auto'] / best['off'])
        print(f'seed {seed}: off {best["off"]:.3f} ms/update ({status["off"]}), auto '
              f'{best["auto"]:.3f} ms/update ({status["auto"]}), auto/off {ratios[-1]:.2f}')
    print(f'{a.case} {a.duration:g} s, {len(a.seeds)} seeds: auto/off median '
          f'{statistics.median(ratios):.2f} (range {min(ratios):.2f}-{max(ratios):.2f})')


if __name__ == '__main__':
    main()
