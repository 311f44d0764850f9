"""Issue 28 benchmark on bodies drawn from a prior: designed vs best standard profile.

    .venv/bin/python scripts/measure/plan_drawn.py [--scene default] [--seeds 20]

The planner sees only the prior (the scene's tensor +- 20 %); limits and target as in
plan_vs_standard.py (the scene's sensors, its profile's peak torque per axis, 1.2x its
simulated peak rate; target = the principal sigma the scene's own profile reaches).  One plan
serves every seed.  Per seed the true body is a draw from the prior, and on it:

* the time to target of the designed profile and of the standard profiles at the same limits
  that come close on the prior value (sines, random and Schroeder multisines)
  (each scaled to the rate limit on the prior bodies, as the plan does), from the Cramer-Rao
  curve on the true body at 60 times (the criterion of a multisine falls unevenly: on the
  plan's 14 times the crossing moves by up to 10 % with the grid);
* the achieved time: the project's estimator (``estimate``, the plan's model, torque bias off)
  on the simulated designed scene, cut at 0.5-1.5x the predicted time, log-log interpolated;
  the plan's prediction (made on the prior value) against it.
"""

import argparse
import time

import numpy as np

from inertia_ros.core import excitation as ex
from inertia_ros.core.crlb import scene_fisher
from inertia_ros.core.estimation.batch import estimate
from inertia_ros.core.excitation.design import check_times, enforce_limits
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene

FRACTIONS = np.round(np.arange(0.5, 2.0001, 0.05), 2)
CONTENDERS = ('sines', 'random multisine', 'schroeder multisine')


def setup(name: str):
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
    prior = ex.make_prior(sc.inertia[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]], 0.2)
    goal = ex.criterion(scene_fisher(own, estimate_bias=False).information, sc.inertia,
                        ex.Target(rel_std=0.01), 'full')
    return sc, lim, prior, ex.Target(rel_std=float(goal), max_duration=2 * sc.duration)


def time_on(prof, body, prior, lim, target, model, t_end, rate=10.0, limit=True):
    """Predicted time to target [s] of ``prof`` on ``body``: a standard profile limited on the
    prior bodies as the plan limits it (``limit``), the plan's profile as it is (already
    limited: limiting it again would scale every axis back to the torque limit)."""
    limited = enforce_limits(prof, prior.bodies(3, 0), lim, t_end, rate)[0] if limit else prof
    return float(check_times(limited, [body], lim, target, model, t_end, rate, n=120)[0])


def achieved(p, body, lim, target, seed, t_pred):
    """The estimator's time to target on the simulated planned scene (``seed``) [s]: the
    first crossing of the target by its sigma on the records cut at 0.5, 0.55, ..., 2x
    ``t_pred`` [s] (the prediction on the body), log-log interpolated; and how many of the
    cuts before it had their sigma widened by the estimator's window-scatter check."""
    sim = simulate(Scene.from_dict(ex.scene_dict(p.profile, lim, FRACTIONS[-1] * t_pred + 1,
                                                 body, seed)), seed)
    crit, widened = [], 0
    for te in FRACTIONS * t_pred:
        g, s = sim.t_gyro <= te, sim.t_torque <= te
        e = estimate(sim.t_gyro[g], sim.omega[g], sim.t_torque[s], sim.torque[s],
                     model=p.model, torque_bias='off')
        cov = np.nan_to_num(np.asarray(e.covariance, dtype=float), nan=np.inf) \
            if e.covariance is not None else np.full((6, 6), np.inf)
        est = e.inertia if e.inertia is not None and np.all(np.isfinite(e.inertia)) else body
        crit.append(max(ex.targeted_rel_std(cov, est, target.elements).values()))
        widened += any('sigma widened' in w for w in e.diagnostics.get('warnings', []))
        if crit[-1] <= target.rel_std:
            break
    t = FRACTIONS[:len(crit)] * t_pred
    return ex.time_to_reach(t, np.array(crit), target.rel_std), widened


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument('--scene', default='default')
    ap.add_argument('--seeds', type=int, default=20)
    a = ap.parse_args()
    sc, lim, prior, target = setup(a.scene)
    t0 = time.process_time()
    p = ex.plan(prior, lim, target, n_bodies=3, seed=0)
    cpu = time.process_time() - t0
    # constant, chirp and PRBS are 3.6x slower or never reach the target on the prior value:
    # only the three that come close are timed on each body
    stds = [s for s in ex.standard_profiles(lim.max_torque) if s.name in CONTENDERS]
    t_end = target.max_duration
    chk = p.design.get('check', {})
    print(f'{a.scene}: target {100 * target.rel_std:.3g} %, model {p.model}, plan '
          f"{p.design['family']} ({p.profile.name}), {cpu:.1f} s CPU; predicted "
          f'{p.time_to_target:.1f} s on the prior value, median {chk.get("median", 0):.1f} s '
          f'on {chk.get("check_bodies", 0)} prior draws', flush=True)
    rows = []
    for seed in range(1, a.seeds + 1):
        body = prior.bodies(2, 5000 + seed)[1]
        t_des = time_on(p.profile, body, prior, lim, target, p.model, t_end, limit=False)
        t_std = {s.name: time_on(s, body, prior, lim, target, p.model, t_end) for s in stds}
        best = min(t_std, key=t_std.get)
        t_ach, wide = achieved(p, body, lim, target, seed, t_des)
        rows.append((t_std[best] / t_des, p.time_to_target / t_ach,
                     chk.get('median', np.nan) / t_ach, t_des / t_ach))
        print(f'seed {seed:2d}: planned {t_des:5.1f} s, best standard {best} '
              f'{t_std[best]:5.1f} s (ratio {rows[-1][0]:.3f}); achieved {t_ach:5.1f} s, '
              f'predicted/achieved: prior value {rows[-1][1]:.2f}, prior median '
              f'{rows[-1][2]:.2f}, on the body {rows[-1][3]:.2f}; widened before: {wide}',
              flush=True)
    r = np.array(rows)
    print(f'ratio best standard / planned: median {np.median(r[:, 0]):.3f}, min '
          f'{r[:, 0].min():.3f}, max {r[:, 0].max():.3f}, later on {int(np.sum(r[:, 0] < 1))}')
    for j, what in ((1, 'prior value'), (2, 'prior median'), (3, 'on the body')):
        q = r[:, j]
        print(f'predicted ({what}) / achieved: median {np.median(q):.2f}, range '
              f'{q.min():.2f}-{q.max():.2f}, within 25 %: {int(np.sum(np.abs(q - 1) <= 0.25))} '
              f'of {q.size}')

if __name__ == '__main__':
    main()
