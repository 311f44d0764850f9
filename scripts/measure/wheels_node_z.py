"""The node's wheels estimators with its defaults: RMS z per element, tracking and recursive
(issue 27, the torque-noise walk per grid interval).

    python scripts/measure/wheels_node_z.py [--seeds N] [--first S] [--truth diag|prod]
        [--path tracking,recursive] [--window W] [--noise both|gyro|speed]

The scene of ``scripts/measure/wheels_z.py`` (``test/test_wheels.scene_dict``, 20 s, three
reaction wheels with exact inertias, no other torque: the node's ``torque_topic: none``),
simulated once; every seed draws the simulator's gyro and JointState noise on it.  Each seed
is fed as the node feeds it (:func:`feed`: 0.1 s blocks of gyro and wheel momentum,
``publish_rate`` 10 Hz, an estimate after every block, then ``refresh()`` where there is one)
to the estimator :func:`inertia_ros.nodes.selection.make_estimator` builds from the node's
parameter defaults with ``method`` set (``tracking``: :class:`.MomentumTrackingEstimator`,
memory ``window`` or 10 s; ``recursive``: :class:`.MomentumRecursiveEstimator`).  The last
estimate is scored against the scene's tensor.  ``--noise gyro`` / ``speed`` keeps one noise
source (the other's sigma x 0.01, as ``wheels_z.py``).

Output per path: the statuses, the per-element RMS z of the reported sigma and of the noise
model's (the reported divided by ``diagnostics['adequacy']['sigma_widened_by']``), over the
seeds with a tensor (MC 1-sigma of an RMS z about ``1 / sqrt(2 n)``), and the seconds taken.

Main 32c11e8 (the tracker's filter noise holding the wheels' record-mean walk),
``OMP_NUM_THREADS=1 python scripts/measure/wheels_node_z.py --seeds 60``::

    tracking wheels diag noise=both n=60 28s statuses={'ok': 60} widened 15 of 60 (max 1.69)
       rms z reported     Ixx=1.22 Iyy=1.03 Izz=1.22 Ixy=1.20 Ixz=1.66 Iyz=1.74  (MC 1-sigma ~0.09)
       rms z noise model  Ixx=1.34 Iyy=1.13 Izz=1.28 Ixy=1.32 Ixz=1.76 Iyz=1.94
       max |z| reported   6.00
    recursive wheels diag noise=both n=60 44s statuses={'ok': 60} widened 10 of 60 (max 2.75)
       rms z reported     Ixx=1.15 Iyy=0.92 Izz=0.94 Ixy=0.93 Ixz=0.88 Iyz=0.94  (MC 1-sigma ~0.09)
       rms z noise model  Ixx=1.19 Iyy=0.97 Izz=0.96 Ixy=1.00 Ixz=0.93 Iyz=1.04
       max |z| reported   3.18

The tracker's products were also low with one noise source (``--noise gyro``: Ixz 1.37,
Iyz 1.53 noise model; ``--noise speed``: 1.84, 2.15), as the ``n x h`` and ``w x e`` walks'
record mean explains; seeds 60-119 Ixz 1.79, Iyz 1.77 reported (max |z| 4.95, 2
model_mismatch); ``--truth prod`` Ixz 1.63, Iyz 1.62 (an ok at |z| 5.99).

With each block's walk from its grid intervals (``MomentumTrackingEstimator._block_walk``,
:func:`.online_walk.walk_deviation`), the same command::

    tracking wheels diag noise=both n=60 30s statuses={'ok': 60} widened 5 of 60 (max 1.61)
       rms z reported     Ixx=0.96 Iyy=0.94 Izz=1.03 Ixy=0.90 Ixz=1.07 Iyz=1.04  (MC 1-sigma ~0.09)
       rms z noise model  Ixx=1.01 Iyy=0.94 Izz=1.04 Ixy=0.93 Ixz=1.08 Iyz=1.04
       max |z| reported   3.33

(the recursive's unchanged); seeds 60-119 (``--first 60``) products 1.12, 1.08, 1.11
reported (Ixx 1.19; 60 ok, max |z| 3.50); ``--truth prod`` 1.04, 1.06, 1.11 (60 ok, max |z|
3.30; the recursive's 0.89, 0.89, 0.92).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'scripts' / 'measure'))
sys.path.insert(0, str(ROOT / 'test'))
sys.path.insert(0, str(ROOT))

from wheels_z import NAMES, THETA_IDX, draw, scene_for  # noqa: E402

from inertia_ros.core.estimation.momentum import Wheel, wheel_inputs  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402

BLOCK = 0.1          # s, the node's update period at its default publish_rate 10 Hz


def node_factory(method: str, window: float) -> Any:
    """The node's estimator factory for ``method`` with its parameter defaults, wheels on
    ``joint_states`` and no torque topic."""
    from inertia_ros.nodes.params import ESTIMATOR
    from inertia_ros.nodes.selection import make_estimator

    cfg = {k: spec.default for k, spec in ESTIMATOR.items()}
    cfg.update(method=method, torque_topic='none', window=window)
    return make_estimator(cfg, SimpleNamespace(names=()))


def feed(est: Any, run: Any, wheels: list[Wheel]) -> Any:
    """Feed ``run`` in :data:`BLOCK` blocks as the node does; the last estimate."""
    kg = np.floor(run.t_gyro / BLOCK + 1e-9).astype(int)
    kw = np.floor(run.t_wheel / BLOCK + 1e-9).astype(int)
    last = None
    for b in range(int(max(kg[-1], kw[-1])) + 1):
        g, w = kg == b, kw == b
        if g.any():
            est.add_gyro(run.t_gyro[g], run.omega[g])
        if w.any():
            est.add_momentum(wheel_inputs(run.t_wheel[w], run.wheel_speed[w], wheels))
        try:
            last = est.estimate()
        except ValueError:
            continue
        if hasattr(est, 'refresh'):
            est.refresh()
    return last


def widened_by(est: Any) -> float:
    """The adequacy widening of the estimate's sigma (1 without a verdict)."""
    return float(est.diagnostics.get('adequacy', {}).get('sigma_widened_by', 1.0))


def rms(z: np.ndarray) -> str:
    """Per-element RMS of ``z`` (n, 6), formatted."""
    return ' '.join(f'{a}={v:.2f}' for a, v in
                    zip(NAMES, np.sqrt(np.nanmean(z ** 2, 0)), strict=True))


def main() -> None:
    """Parse the options, print the comparison."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=40)
    p.add_argument('--first', type=int, default=0)
    p.add_argument('--truth', default='diag')
    p.add_argument('--path', default='tracking,recursive')
    p.add_argument('--window', type=float, default=0.0,
                   help="the node's window parameter [s] (0: its default)")
    p.add_argument('--noise', default='both')
    args = p.parse_args()
    sim_scene, noise_scene = scene_for('wheels', args.truth, args.noise)
    base = simulate(sim_scene, args.first)
    wheels = [Wheel(w.joint, w.axis, w.inertia) for w in base.scene.wheels.wheels]
    truth = sim_scene.inertia[THETA_IDX]
    runs = []
    for seed in range(args.first, args.first + args.seeds):
        omega, speed = draw(base, noise_scene, seed)
        runs.append(SimpleNamespace(t_gyro=base.t_gyro, omega=omega, t_wheel=base.t_wheel,
                                    wheel_speed=speed))
    for path in args.path.split(','):
        make = node_factory(path, args.window)
        t0 = time.time()
        z, z_nm, statuses, widen = [], [], {}, []
        for run in runs:
            est = feed(make(), run, wheels)
            status = 'none' if est is None else est.status
            statuses[status] = statuses.get(status, 0) + 1
            if est is None or est.theta is None:
                continue
            e = np.asarray(est.theta) - truth
            s = np.asarray(est.theta_std)
            z.append(e / s)
            z_nm.append(e * widened_by(est) / s)
            widen.append(widened_by(est))
        z, z_nm = np.array(z), np.array(z_nm)
        n = len(z)
        print(f'{path} wheels {args.truth} noise={args.noise} n={n} {time.time() - t0:.0f}s statuses={statuses} '
              f'widened {sum(w > 1.0 for w in widen)} of {n} (max {max(widen, default=1):.2f})')
        if n:
            print(f'   rms z reported     {rms(z)}  (MC 1-sigma ~{1 / np.sqrt(2 * n):.2f})')
            print(f'   rms z noise model  {rms(z_nm)}')
            print(f'   max |z| reported   {np.max(np.abs(z)):.2f}')


if __name__ == '__main__':
    main()
