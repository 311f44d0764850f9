"""The online wheels path against the batch: noise-model sigma ratio and RMS z (issue 27).

    python scripts/measure/wheels_online_z.py [--seeds N] [--first S] [--truth diag|prod]
        [--segment S] [--time]

The scene of ``scripts/measure/wheels_z.py`` (``test/test_wheels.scene_dict``, 20 s, three
reaction wheels, no other torque), simulated once; every seed draws the simulator's gyro and
JointState noise on it.  Each seed is estimated by the batch (``estimate_with_momentum``,
``method='integral'``, ``model='full'``, ``torque_bias='off'``, the segment given) and by
:class:`.recursive_momentum.MomentumRecursiveEstimator` (``other_torque=False``, the same
model and segment) fed as the node feeds it (0.1 s blocks, an estimate every second,
``test/test_momentum_online.feed_blocks``).

Output: per element the median (and range) over seeds of the online / batch noise-model
sigma (each sigma divided by its adequacy widening), the online estimates' RMS z of the
noise-model sigma (and the batch's) and of the reported sigma.  ``--time``: the wall time of feeding one 20 s
record in 0.1 s blocks with an estimate every second (best of 5, one BLAS thread advised:
``OMP_NUM_THREADS=1``).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'test'))
sys.path.insert(0, str(ROOT / 'scripts' / 'measure'))
sys.path.insert(0, str(ROOT))

from wheels_z import NAMES, THETA_IDX, draw, scene_for  # noqa: E402

from inertia_ros.core.estimation.momentum import (  # noqa: E402
    Wheel,
    estimate_with_momentum,
    wheels_momentum,
)
from inertia_ros.core.estimation.recursive_momentum import (  # noqa: E402
    MomentumRecursiveEstimator,
)
from inertia_ros.core.simulation import simulate  # noqa: E402


def noise_sigma(est) -> np.ndarray:
    """The estimate's sigma (6,) before the adequacy widening."""
    return np.asarray(est.theta_std) / float(
        est.diagnostics.get('adequacy', {}).get('sigma_widened_by', 1.0))


def main() -> None:
    """Parse the options, print the comparison."""
    from test_momentum_online import feed_blocks

    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=40)
    p.add_argument('--first', type=int, default=0)
    p.add_argument('--truth', default='diag')
    p.add_argument('--segment', type=float, default=10.0)
    p.add_argument('--time', action='store_true')
    args = p.parse_args()
    sim_scene, noise_scene = scene_for('wheels', args.truth, 'both')
    base = simulate(sim_scene, args.first)
    wheels = [Wheel(w.joint, w.axis, w.inertia) for w in base.scene.wheels.wheels]
    opts = dict(model='full', segment=args.segment)

    def online():
        return MomentumRecursiveEstimator(other_torque=False, torque_bias=False, **opts)

    if args.time:
        runs = []
        for _ in range(5):
            t0 = time.perf_counter()
            feed_blocks(online(), base, wheels)
            runs.append(time.perf_counter() - t0)
        print(f'feed 20 s in 0.1 s blocks: best {min(runs) * 1e3:.0f} ms, '
              f'median {np.median(runs) * 1e3:.0f} ms (of 5)')
    truth = sim_scene.inertia[THETA_IDX]
    ratios, z_nm, z, zb = [], [], [], []
    t0 = time.time()
    for seed in range(args.first, args.first + args.seeds):
        omega, speed = draw(base, noise_scene, seed)
        b = estimate_with_momentum(base.t_gyro, omega, [], np.zeros((0, 3)),
                                   wheels_momentum(base.t_wheel, speed, wheels),
                                   method='integral', torque_bias='off', **opts)
        run = SimpleNamespace(t_gyro=base.t_gyro, omega=omega, t_wheel=base.t_wheel,
                              wheel_speed=speed)
        o = feed_blocks(online(), run, wheels)
        if o.theta is None or b.theta is None:
            continue
        ratios.append(noise_sigma(o) / noise_sigma(b))
        e = np.asarray(o.theta) - truth
        z_nm.append(e / noise_sigma(o))
        z.append(e / np.asarray(o.theta_std))
        zb.append((np.asarray(b.theta) - truth) / noise_sigma(b))
    ratios, z_nm, z, zb = np.array(ratios), np.array(z_nm), np.array(z), np.array(zb)
    n = len(ratios)
    print(f'wheels {args.truth} segment={args.segment} n={n} {time.time() - t0:.0f}s')
    fmt = ' '.join
    print('   sigma online/batch median', fmt(f'{a}={v:.3f}' for a, v in
                                             zip(NAMES, np.median(ratios, 0), strict=True)))
    print('   sigma online/batch range ', fmt(f'{a}={lo:.3f}-{hi:.3f}' for a, lo, hi in
                                             zip(NAMES, ratios.min(0), ratios.max(0),
                                                 strict=True)))
    print('   online rms z noise model ', fmt(f'{a}={v:.2f}' for a, v in
                                             zip(NAMES, np.sqrt(np.mean(z_nm ** 2, 0)),
                                                 strict=True)),
          f' (MC 1-sigma ~{1 / np.sqrt(2 * max(n, 1)):.2f})')
    print('   batch rms z noise model  ', fmt(f'{a}={v:.2f}' for a, v in
                                             zip(NAMES, np.sqrt(np.mean(zb ** 2, 0)),
                                                 strict=True)))
    print('   online rms z reported    ', fmt(f'{a}={v:.2f}' for a, v in
                                             zip(NAMES, np.sqrt(np.mean(z ** 2, 0)),
                                                 strict=True)))


if __name__ == '__main__':
    main()
