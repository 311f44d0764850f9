"""Issue 28 part 1 measurement: designed vs best standard profile time to target, and the
predicted time against the project's estimator on the simulator (3 seeds), per scene.

Per scene: prior = the scene's tensor +- 20 %; limits = the scene's sensors, its profile's peak
torque per axis and 1.2 x its simulated peak |omega|; target = the principal-moment relative
CRLB the scene's own profile reaches at its full duration; max duration = 2 x that.
"""

import sys
import time

import numpy as np

from inertia_ros.core import excitation as ex
from inertia_ros.core.crlb import scene_fisher
from inertia_ros.core.estimation.batch import estimate
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene

for name in sys.argv[1:]:
    sc = load_scene(f"config/scenes/{name}.yaml")
    own = simulate(sc, 0)
    cmd = own.torque_command
    mt = np.max(np.abs(cmd), axis=0)
    mt = np.where(mt > 0, mt, mt.max())
    th = sc.inertia[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]
    lim = ex.Limits(
        max_torque=tuple(mt),
        max_rate=1.2 * float(np.max(np.linalg.norm(own.omega_true, axis=1))),
        gyro_rate=sc.gyro.rate,
        torque_rate=sc.torque_sensor.rate,
        gyro_noise=sc.gyro.noise_std,
        torque_noise=sc.torque_sensor.noise_std,
        torque_noise_rel=sc.torque_sensor.noise_rel,
        initial_omega=tuple(sc.initial_omega),
    )
    prior = ex.make_prior(th, 0.2)
    model = ex.choose_model(prior, ex.Target(rel_std=0.01))
    F = scene_fisher(own, estimate_bias=False).information
    goal = ex.criterion(F, sc.inertia, ex.Target(rel_std=0.01), "full")
    target = ex.Target(rel_std=float(goal), max_duration=2 * sc.duration)
    t0 = time.time()
    p = ex.plan(prior, lim, target, n_bodies=3, seed=0)
    dt = time.time() - t0
    rows = p.comparison
    best = min(rows[1:], key=lambda r: r["time_to_target"])
    ach = []
    fr = np.array([0.5, 0.75, 1.0, 1.25, 1.5])
    for seed in (1, 2, 3):
        sim = simulate(
            Scene.from_dict(
                ex.scene_dict(p.profile, lim, 1.6 * p.time_to_target, sc.inertia, seed)
            ),
            seed,
        )
        crit = []
        for te in fr * p.time_to_target:
            g, s = sim.t_gyro <= te, sim.t_torque <= te
            e = estimate(
                sim.t_gyro[g],
                sim.omega[g],
                sim.t_torque[s],
                sim.torque[s],
                model=p.model,
                torque_bias="off",
            )
            cov = (
                np.nan_to_num(np.asarray(e.covariance, dtype=float), nan=np.inf)
                if e.covariance is not None
                else np.full((6, 6), np.inf)
            )
            crit.append(
                max(
                    ex.targeted_rel_std(
                        cov,
                        e.inertia
                        if e.inertia is not None and np.all(np.isfinite(e.inertia))
                        else sc.inertia,
                        target.elements,
                    ).values()
                )
            )
        ach.append(ex.time_to_reach(fr * p.time_to_target, np.array(crit), goal))
    print(
        f"{name:12s} target {100 * goal:.3g} % model {p.model}: designed {p.time_to_target:6.1f} s "
        + (f"({p.design['n_per_axis']}/axis {p.design['spread']} f0 {p.design['f0']:.3g}); "
           if p.design.get('family', 'multisine') == 'multisine' else f"(standard {p.design['family']}); ")
        + f"best standard "
        f"{best['name']} {best['time_to_target']:6.1f} s (ratio {best['time_to_target'] / p.time_to_target:.2f}); "
        f"scene own profile {sc.duration:g} s; achieved {[round(a, 1) for a in ach]} s "
        f"(pred/ach {[round(p.time_to_target / a, 2) for a in ach]}); plan {dt:.0f} s",
        flush=True,
    )
    for r in rows:
        print(
            f"     {r['name']:50s} crit {100 * r['criterion']:.3g} %  t {r['time_to_target']:.1f} s  peak rate {r['peak_rate']:.3g}",
            flush=True,
        )
