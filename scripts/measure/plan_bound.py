"""Issue 28: how much sooner than the best standard profile can ANY profile reach the target?

    .venv/bin/python scripts/measure/plan_bound.py default composite cubesat satellite single_axis

Same scenes and limits as plan_vs_standard.py (prior = the scene's tensor, torque limit = its
profile's peak per axis, rate limit = 1.2x its simulated peak rate).  The Cramer-Rao bound
splits into what the gyro noise costs and what the torque-sensor noise costs.  A scene's
torque sensor has a noise relative to the profile's RMS torque (``noise_rel``): that part does
not shrink with a larger or better-shaped torque, so it is a floor no profile beats.  Per
scene, at the horizon T (the best standard profile's predicted time to the scene's target):

* ``sines`` / ``designed``: the criterion (largest principal relative sigma, model as the plan
  chooses) of the standard sines and of the plan's design;
* ``floor``: the smallest criterion of those profiles with a noiseless gyro (1e-7 rad/s), i.e.
  the torque noise alone; ``noise_rel / sqrt(torque_rate T)`` is its analytic value (the
  relative error of ``I = tau / omega_dot`` with a perfect gyro);
* ``max speed-up`` = ``(criterion of the best standard / floor)^2``: no profile reaches the
  target sooner than the best standard by more than this (the criterion falls as 1 / sqrt(T)).
"""

import math
import sys
from dataclasses import replace

import numpy as np

from inertia_ros.core import excitation as ex
from inertia_ros.core.crlb import scene_fisher
from inertia_ros.core.excitation.design import enforce_limits, information_at
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene


def crit(prof, body, lim, target, model, T, rate):
    """The criterion of ``prof`` held to the limits, at T."""
    p, _ = enforce_limits(prof, [body], lim, T, rate)
    return ex.criterion(information_at(p, body, lim, T, [T], rate)[0], body, target, model)


for name in sys.argv[1:]:
    sc = load_scene(f'config/scenes/{name}.yaml')
    own = simulate(sc, 0)
    mt = np.max(np.abs(own.torque_command), axis=0)
    mt = np.where(mt > 0, mt, mt.max())
    lim = ex.Limits(max_torque=tuple(mt),
                    max_rate=1.2 * float(np.max(np.linalg.norm(own.omega_true, axis=1))),
                    gyro_rate=sc.gyro.rate, torque_rate=sc.torque_sensor.rate,
                    gyro_noise=sc.gyro.noise_std, torque_noise=sc.torque_sensor.noise_std,
                    torque_noise_rel=sc.torque_sensor.noise_rel,
                    initial_omega=tuple(sc.initial_omega))
    th = sc.inertia[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]
    prior = ex.make_prior(th, 0.2)
    goal = ex.criterion(scene_fisher(own, estimate_bias=False).information, sc.inertia,
                        ex.Target(rel_std=0.01), 'full')
    target = ex.Target(rel_std=float(goal), max_duration=2 * sc.duration)
    p = ex.plan(prior, lim, target, n_bodies=3, seed=0)
    best = min(p.comparison[1:], key=lambda r: r['time_to_target'])
    T = float(best['time_to_target'])
    rate = min(10.0, lim.gyro_rate, lim.torque_rate)
    std = {s.name: s for s in ex.standard_profiles(mt)}
    quiet = replace(lim, gyro_noise=1e-7)
    rows = {'best standard': std[best['name']], 'designed': p.profile}
    c = {k: crit(v, sc.inertia, lim, target, p.model, T, rate) for k, v in rows.items()}
    floor = min(crit(v, sc.inertia, quiet, target, p.model, T, rate) for v in rows.values())
    analytic = lim.torque_noise_rel / math.sqrt(lim.torque_rate * T)
    print(f"{name:12s} T {T:6.1f} s ({best['name']}): best standard {100 * c['best standard']:.4f} %,"
          f" designed {100 * c['designed']:.4f} %, torque-noise floor {100 * floor:.4f} % "
          f"(noise_rel/sqrt(rate T) {100 * analytic:.4f} %): max speed-up "
          f"{(c['best standard'] / floor) ** 2:.2f}x, designed reaches "
          f"{(c['best standard'] / c['designed']) ** 2:.2f}x", flush=True)
