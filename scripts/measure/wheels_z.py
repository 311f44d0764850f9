"""Is the momentum path's sigma true per element? (issue 27 "sigma true", the wheels' products)

    python scripts/measure/wheels_z.py [--path wheels|rotors|torque] [--seeds N]
        [--truth diag,prod] [--method integral|default|ml|auto] [--model full|default]
        [--bias off|auto] [--noise both|gyro|speed] [--first S] [--check]

``wheels``: the scene of ``test/test_wheels.scene_dict`` (three reaction wheels, no other
torque), 20 s, gyro 200 Hz sigma 2e-3 rad/s, JointState 100 Hz sigma 0.2 rad/s, estimated by
``estimate_with_momentum``.  ``rotors``: ``test/test_rotors.quad_scene`` (20 s, 200 Hz, exact
coefficients, ``--rotors`` in the CLI).  ``torque``: the wheels scene's body and gyro without
wheels, a multisine torque of 0.2 N m per axis (0.05-0.3 Hz, 100 Hz, sigma 0.01 N m), by
``batch.estimate``.  ``diag``: the scene's moments with the products set to 0; ``prod``: with
the scene's products.  ``--method default`` and ``--model default`` leave the option out (the
estimator's default); ``--noise gyro`` / ``speed`` keeps one source (the other's sigma x 0.01).

The wheels and rotors truths do not depend on the seed, so each is simulated once and every
seed only draws the simulator's own noise on it (its gyro and JointState readers, the
simulator's generators: ``--check`` asserts the first seed bit for bit against
``simulate(scene, seed)``); the torque path simulates every seed (its multisine's phases are
drawn).  Seeds ``S .. S+N-1`` (``--first``, default 0).

Output, one block per truth (MC 1-sigma of an RMS z about ``1 / sqrt(2 n)``; ``rms z nm``
with the noise model's sigma, before the adequacy tests widened it (``sigma_widened_by``);
``var ratio`` the estimates' mean squared error over the noise model's mean variance;
``mean W`` the products' Wald statistic against 0, reported and noise-model covariance, 3
dof on a diagonal truth).  This tree, ``--truth diag`` (main 6cbe252 read Ixz 1.29 / 1.42,
Iyz 1.25 / 1.57, W 4.22 / 5.80)::

    wheels diag method=integral model=full bias=off noise=both n=60 3s chosen={'full': 60}
       rms z      Ixx=1.08 Iyy=1.01 Izz=0.90 Ixy=0.91 Ixz=0.92 Iyz=0.94  (MC 1-sigma ~0.09)
       mean z     Ixx=+0.08 Iyy=-0.09 Izz=-0.04 Ixy=+0.05 Ixz=+0.10 Iyz=-0.06
       rms z nm   Ixx=1.13 Iyy=1.07 Izz=1.02 Ixy=0.97 Ixz=1.00 Iyz=1.12  (widened 12 of 60, ...)
       var ratio  Ixx=1.28 Iyy=1.15 Izz=1.04 Ixy=0.92 Ixz=1.01 Iyz=1.29
       products' mean W 2.45, of the noise model 3.09 (diag truth: expect 3 +- 0.32)
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'test'))
sys.path.insert(0, str(ROOT))

from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import _gyro_reading, simulate  # noqa: E402
from inertia_ros.core.wheel_sim import wheel_streams  # noqa: E402

NAMES = ('Ixx', 'Iyy', 'Izz', 'Ixy', 'Ixz', 'Iyz')
THETA_IDX = ([0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2])


def scene_for(path: str, truth: str, noise: str) -> tuple[Scene, Scene]:
    """The path's scene for the truth (the simulated one, the one whose noise is drawn)."""
    from test_rotors import quad_scene
    from test_wheels import scene_dict

    d = quad_scene(20.0, 200.0).source if path == 'rotors' else scene_dict(duration=20.0)
    d = dict(d)
    inertia = np.array(d['body']['inertia'], dtype=float)
    if truth == 'diag':
        inertia[3:] = 0.0
    d['body'] = dict(d['body'], inertia=inertia.tolist())
    if path == 'torque':
        d.pop('wheels')
        d['torque'] = [{'type': 'multisine', 'amplitude': 0.2, 'axes': ['x', 'y', 'z'],
                        'f_min': 0.05, 'f_max': 0.3}]
        d['torque_sensor'] = {'rate': 100.0, 'noise_std': 0.01}
        d['command_rate'] = 100.0
    drawn = dict(d)
    if noise != 'both':
        key = 'rotors' if path == 'rotors' else 'wheels'
        if noise == 'gyro' and path != 'torque':
            drawn[key] = dict(d[key], speed_noise_std=0.01 * d[key]['speed_noise_std'])
        if noise == 'speed':
            drawn['gyro'] = dict(d['gyro'], noise_std=0.01 * d['gyro']['noise_std'])
    return Scene.from_dict(d), Scene.from_dict(drawn)


def draw(truth_run, scene: Scene, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The simulator's gyro and JointState readings of one seed on a seed-free truth."""
    r_gnoise = np.random.default_rng(int(seed)).spawn(7)[1]
    omega = _gyro_reading(scene, truth_run.omega_true, r_gnoise)
    _, speed, _ = wheel_streams(scene.wheels, scene.duration,
                                np.random.default_rng([int(seed), 0x77686565]))
    return omega, speed


def estimate_one(path: str, run, omega, speed, opts: dict):
    """The path's batch estimate of one record."""
    from inertia_ros.core.estimation.batch import estimate
    from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum
    from inertia_ros.core.estimation.rotors import rotors_momentum

    if path == 'torque':
        return estimate(run.t_gyro, run.omega, run.t_torque, run.torque, **opts)
    sc = run.scene
    if path == 'rotors':
        mom = rotors_momentum(run.t_wheel, speed, sc.wheels.rotors)
    else:
        mom = wheels_momentum(run.t_wheel, speed,
                              [Wheel(w.joint, w.axis, w.inertia) for w in sc.wheels.wheels])
    return estimate_with_momentum(run.t_gyro, omega, [], np.zeros((0, 3)), mom, **opts)


def measure(args: argparse.Namespace, truth: str) -> None:
    """One truth's block of output (see the module docstring)."""
    sim_scene, noise_scene = scene_for(args.path, truth, args.noise)
    opts = {'torque_bias': args.bias}
    if args.method != 'default':
        opts['method'] = args.method
    if args.model != 'default':
        opts['model'] = args.model
    base = None if args.path == 'torque' else simulate(sim_scene, args.first)
    t0 = time.time()
    z, err, var, wald, chosen, widen, wald_nm = [], [], [], [], {}, [], []
    for seed in range(args.first, args.first + args.seeds):
        if base is None:
            run = simulate(noise_scene, seed)
            omega = speed = None
        else:
            run = base
            omega, speed = draw(base, noise_scene, seed)
            if args.check and seed == args.first:
                full = simulate(noise_scene, seed)
                assert np.array_equal(full.omega, omega), 'gyro draw differs from simulate'
                assert np.array_equal(full.wheel_speed, speed), 'speed draw differs'
        est = estimate_one(args.path, run, omega, speed, opts)
        chosen[est.model] = chosen.get(est.model, 0) + 1
        if est.theta is None:
            continue
        e = np.asarray(est.theta) - sim_scene.inertia[THETA_IDX]
        s = np.asarray(est.theta_std)
        ok = s > 0
        z.append(np.where(ok, e / np.where(ok, s, 1.0), np.nan))
        err.append(np.where(ok, e, np.nan))
        var.append(np.where(ok, s ** 2, np.nan))
        widen.append(float(est.diagnostics.get('adequacy', {}).get('sigma_widened_by', 1.0)))
        cov = np.asarray(est.covariance)[3:, 3:]
        if np.all(ok[3:]):
            wald.append(float(e[3:] @ np.linalg.solve(cov, e[3:])))
            wald_nm.append(wald[-1] * widen[-1] ** 2)
    z, err, var, widen = np.array(z), np.array(err), np.array(var), np.array(widen)
    n = len(z)
    rms = np.sqrt(np.nanmean(z ** 2, axis=0))
    rms_nm = np.sqrt(np.nanmean((z * widen[:, None]) ** 2, axis=0))
    ratio = np.nanmean(err ** 2, axis=0) / np.nanmean(var / widen[:, None] ** 2, axis=0)
    print(f'{args.path} {truth} method={args.method} model={args.model} bias={args.bias} '
          f'noise={args.noise} n={n} {time.time() - t0:.0f}s chosen={chosen}')
    print('   rms z     ', ' '.join(f'{a}={v:.2f}' for a, v in zip(NAMES, rms, strict=True)),
          f' (MC 1-sigma ~{1 / np.sqrt(2 * max(n, 1)):.2f})')
    print('   mean z    ', ' '.join(f'{a}={v:+.2f}' for a, v in zip(NAMES, np.nanmean(z, 0), strict=True)))
    print('   rms z nm  ', ' '.join(f'{a}={v:.2f}' for a, v in zip(NAMES, rms_nm, strict=True)),
          f' (widened {np.sum(widen > 1)} of {n}, by up to {np.max(widen, initial=1):.2f})')
    print('   var ratio ', ' '.join(f'{a}={v:.2f}' for a, v in zip(NAMES, ratio, strict=True)))
    if wald:
        note = f' (diag truth: expect 3 +- {np.sqrt(6 / len(wald)):.2f})'
        print(f"   products' mean W {np.mean(wald):.2f}, of the noise model "
              f"{np.mean(wald_nm):.2f}" + (note if truth == 'diag' else ''))
    sys.stdout.flush()


def main() -> None:
    """Parse the options and print one block per truth."""
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--path', choices=('wheels', 'rotors', 'torque'), default='wheels')
    p.add_argument('--seeds', type=int, default=60)
    p.add_argument('--first', type=int, default=0)
    p.add_argument('--truth', default='diag,prod')
    p.add_argument('--method', default='integral')
    p.add_argument('--model', default='full')
    p.add_argument('--bias', default='off')
    p.add_argument('--noise', choices=('both', 'gyro', 'speed'), default='both')
    p.add_argument('--check', action='store_true')
    args = p.parse_args()
    for truth in args.truth.split(','):
        measure(args, truth)


if __name__ == '__main__':
    main()
