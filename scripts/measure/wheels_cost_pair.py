"""The wheels path's estimate cost, paired between two source trees in one run.

    python scripts/measure/wheels_cost_pair.py TREE_A TREE_B [--rounds N]

The record: ``scripts/measure/wheels_z.py``'s wheels scene with products (20 s, gyro 200 Hz,
JointState 100 Hz), seed 0, built once by this tree.  Each round runs, for ``integral`` and
the defaults, one process per tree (``PYTHONPATH=TREE``, one BLAS thread) that prints the
least CPU time of 10 ``estimate_with_momentum`` calls; the rounds alternate the trees, and
each line gives B / A.
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
from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum
z = np.load(sys.argv[1])
mom = wheels_momentum(z['t_wheel'], z['speed'], [Wheel(str(j), a, float(i)) for j, a, i
                      in zip(z['joints'], z['axes'], z['inertia'])])
kw = {} if sys.argv[2] == 'default' else {'method': sys.argv[2]}
best = 1e9
for _ in range(10):
    t0 = time.process_time()
    estimate_with_momentum(z['t_gyro'], z['omega'], [], np.zeros((0, 3)), mom, **kw)
    best = min(best, time.process_time() - t0)
print(best * 1e3)
'''


def _record(path: str) -> None:
    sys.path[:0] = [str(HERE), str(HERE.parent.parent / 'test')]
    from wheels_z import draw, scene_for

    from inertia_ros.core.simulation import simulate
    sc, drawn = scene_for('wheels', 'prod', 'both')
    run = simulate(sc, seed=0)
    omega, speed = draw(run, drawn, 0)
    ws = sc.wheels.wheels
    np.savez(path, t_gyro=run.t_gyro, omega=omega, t_wheel=run.t_wheel, speed=speed,
             joints=np.array([w.joint for w in ws]), axes=np.array([w.axis for w in ws]),
             inertia=np.array([w.inertia for w in ws]))


def _time(tree: str, rec: str, method: str) -> float:
    env = dict(os.environ, PYTHONPATH=str(Path(tree).resolve()), OMP_NUM_THREADS='1',
               OPENBLAS_NUM_THREADS='1')
    out = subprocess.run([sys.executable, '-c', TIMER, rec, method], env=env, cwd=tempfile.gettempdir(),
                         capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument('tree_a')
    p.add_argument('tree_b')
    p.add_argument('--rounds', type=int, default=3)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        rec = str(Path(d) / 'wheels.npz')
        _record(rec)
        for r in range(args.rounds):
            for method in ('integral', 'default'):
                a, b = _time(args.tree_a, rec, method), _time(args.tree_b, rec, method)
                print(f'round {r} {method:8s} A {a:6.2f} ms  B {b:6.2f} ms  B/A {b / a:.2f}')


if __name__ == '__main__':
    main()
