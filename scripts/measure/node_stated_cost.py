"""Node update cost with stated inputs: MomentumRecursiveEstimator as the node builds it.

Usage: ``TREE=<tree> python node_stated_cost.py {rotors|wheels} OUT.npy [gyro_scale_std]``
(run once per tree, alternating, then ``compare A.npy B.npy`` for the paired ratio).  The
quadrotor scene (60 s, the rotors file's 12 stated coefficients) or the three-wheel scene
(60 s, inertias stated at 1 %), fed in 0.1 s blocks with ``estimate()`` and ``refresh()``
every block, as the node does at publish_rate 10 Hz.
"""

import os
import sys
import time
from pathlib import Path

import numpy as np

if os.environ.get('TREE'):      # the tree measured, ahead of an editable install's finder
    sys.meta_path = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]
    sys.path.insert(0, os.environ['TREE'])


def _record(kind: str):
    from inertia_ros.core.estimation.momentum import Wheel, wheel_inputs
    from inertia_ros.core.scene import Scene
    from inertia_ros.io.rotors import load_actuators
    from inertia_ros.io.scene_file import load_scene

    root = Path(__file__).resolve().parents[2]
    if kind == 'rotors':
        d = dict(load_scene(root / 'config' / 'scenes' / 'quadrotor.yaml').source, duration=60.0)
        sc = Scene.from_dict(d)
        act = load_actuators(None, root / 'config' / 'rotors' / 'quadrotor.yaml')
        return sc, _sim(sc, kind), act.block, list(act.names)
    sys.path.insert(0, str(root / 'test'))
    from test_wheels import scene_dict
    sc = Scene.from_dict(scene_dict(duration=60.0, gyro_rate=100.0))
    ws = [Wheel(w.joint, w.axis, w.inertia, 0.01 * w.inertia) for w in sc.wheels.wheels]
    names = list(wheel_inputs(np.zeros(1), np.zeros((1, len(ws))), ws).names)
    return sc, _sim(sc, kind), lambda t, s: wheel_inputs(t, s, ws), names


def _sim(sc, kind: str):
    """The simulated record (None when cached: :func:`run` reads the cache)."""
    from inertia_ros.core.simulation import simulate

    return None if Path(f'/tmp/node_stated_cost_{kind}.npz').exists() else simulate(sc, 0)


def run(kind: str, gscale: float) -> tuple[np.ndarray, object]:
    from types import SimpleNamespace

    from inertia_ros.core.estimation.recursive_momentum import MomentumRecursiveEstimator

    sc, r, block, names = _record(kind)
    cache = Path(f'/tmp/node_stated_cost_{kind}.npz')   # the same record for every tree
    if cache.exists():
        r = SimpleNamespace(**np.load(cache))
    else:
        np.savez(cache, t_gyro=r.t_gyro, omega=r.omega, t_wheel=r.t_wheel,
                 wheel_speed=r.wheel_speed)
    kw = dict(model='full', torque_bias='auto', hold='zoh', reselect_every=10,
              defer_adequacy=True)
    if gscale:
        kw['gyro_scale_std'] = gscale
    est = MomentumRecursiveEstimator(names=names, other_torque=False, **kw)
    edges = np.arange(0.0, r.t_gyro[-1] + 0.1, 0.1)
    gi = np.searchsorted(r.t_gyro, edges, side='right')
    wi = np.searchsorted(r.t_wheel, edges, side='right')
    per, last = [], None
    for k in range(1, len(edges)):
        t0 = time.perf_counter()
        if wi[k] > wi[k - 1]:
            est.add_momentum(block(r.t_wheel[wi[k - 1]:wi[k]], r.wheel_speed[wi[k - 1]:wi[k]]))
        if gi[k] > gi[k - 1]:
            est.add_gyro(r.t_gyro[gi[k - 1]:gi[k]], r.omega[gi[k - 1]:gi[k]])
        last = est.estimate()
        est.refresh()
        per.append(time.perf_counter() - t0)
    return np.array(per), last


if __name__ == '__main__':
    if sys.argv[1] == 'compare':
        a, b = np.load(sys.argv[2]), np.load(sys.argv[3])
        ra = np.median(a, axis=0)
        rb = np.median(b, axis=0)
        print(f'{sys.argv[2]}: median update {1e3 * np.median(ra):.2f} ms, total '
              f'{ra.sum():.2f} s; {sys.argv[3]}: {1e3 * np.median(rb):.2f} ms, {rb.sum():.2f} s;'
              f' paired per-update ratio median {np.median(ra / rb):.2f}, total ratio '
              f'{ra.sum() / rb.sum():.2f}')
        sys.exit(0)
    reps = []
    for _ in range(int(os.environ.get('REPS', '3'))):
        per, e = run(sys.argv[1], float(sys.argv[3]) if len(sys.argv) > 3 else 0.0)
        reps.append(per)
    np.save(sys.argv[2], np.array(reps))
    print(sys.argv[1], e.status, 'median update', f'{1e3 * np.median(reps):.2f} ms')
