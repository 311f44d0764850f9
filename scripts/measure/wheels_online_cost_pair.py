"""The online wheels path's cost, paired between two source trees in one run.

    python scripts/measure/wheels_online_cost_pair.py TREE_A TREE_B [--rounds N]

The record: ``scripts/measure/wheels_z.py``'s wheels scene with products (20 s, gyro 200 Hz,
JointState 100 Hz), seed 0, built once by this tree.  Each round runs one process per tree
(``PYTHONPATH=TREE`` and run in TREE, one BLAS thread) that feeds it to a fresh
``MomentumRecursiveEstimator(other_torque=False, model='full', torque_bias=False)`` in 0.1 s
blocks (gyro, then the wheels' momentum), estimating after every block (the node at
``publish_rate`` 10 Hz) or every 10th (``every``), and prints the least CPU time of 5 feeds;
the rounds alternate the trees, and each line gives B / A.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
TIMER = '''
import sys, time, numpy as np
from inertia_ros.core.estimation.momentum import Wheel, wheel_inputs
from inertia_ros.core.estimation.recursive_momentum import MomentumRecursiveEstimator
z = np.load(sys.argv[1])
every = int(sys.argv[2])
wheels = [Wheel(str(j), a, float(i)) for j, a, i in zip(z['joints'], z['axes'], z['inertia'])]
kg = np.floor(z['t_gyro'] / 0.1 + 1e-9).astype(int)
kw = np.floor(z['t_wheel'] / 0.1 + 1e-9).astype(int)
best = 1e9
for _ in range(5):
    t0 = time.process_time()
    est = MomentumRecursiveEstimator(other_torque=False, model='full', torque_bias=False)
    for b in range(int(max(kg[-1], kw[-1])) + 1):
        g, w = kg == b, kw == b
        if g.any():
            est.add_gyro(z['t_gyro'][g], z['omega'][g])
        if w.any():
            est.add_momentum(wheel_inputs(z['t_wheel'][w], z['speed'][w], wheels))
        if b % every == every - 1:
            est.estimate()
    best = min(best, time.process_time() - t0)
print(best * 1e3)
'''


def _record(path: str) -> None:
    """Simulate the record once and save it to ``path`` (npz)."""
    sys.path[:0] = [str(HERE), str(HERE.parent.parent / 'test')]
    sys.path.insert(0, str(HERE.parent.parent))
    from wheels_z import scene_for

    from inertia_ros.core.simulation import simulate

    r = simulate(scene_for('wheels', 'prod', 'both')[0], 0)
    ws = r.scene.wheels.wheels
    np.savez(path, t_gyro=r.t_gyro, omega=r.omega, t_wheel=r.t_wheel, speed=r.wheel_speed,
             joints=np.array([w.joint for w in ws]), axes=np.array([w.axis for w in ws]),
             inertia=np.array([w.inertia for w in ws]))


def main() -> None:
    """Alternate the trees' timing processes; print each round's CPU times and B / A."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('tree_a')
    p.add_argument('tree_b')
    p.add_argument('--rounds', type=int, default=3)
    args = p.parse_args()
    env = dict(os.environ, OMP_NUM_THREADS='1', OPENBLAS_NUM_THREADS='1', MKL_NUM_THREADS='1')
    with tempfile.TemporaryDirectory() as tmp:
        rec = str(Path(tmp) / 'wheels.npz')
        _record(rec)
        for every in (1, 10):
            for k in range(args.rounds):
                ms = {}
                for tree in (args.tree_a, args.tree_b) if k % 2 == 0 else (args.tree_b,
                                                                            args.tree_a):
                    out = subprocess.run([sys.executable, '-c', TIMER, rec, str(every)],
                                         env=dict(env, PYTHONPATH=tree), cwd=tree,
                                         capture_output=True, text=True, check=True)
                    ms[tree] = float(out.stdout.strip().splitlines()[-1])
                a, b = ms[args.tree_a], ms[args.tree_b]
                print(f'estimate every {every:2d} block(s), round {k}: A {a:.0f} ms, '
                      f'B {b:.0f} ms, B / A {b / a:.2f}')


if __name__ == '__main__':
    main()
