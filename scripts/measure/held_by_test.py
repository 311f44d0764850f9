"""A zero chosen by a test: the default scene (20 s) with a diagonal truth, seeds 2000..2000+n-1.

    python scripts/measure/held_by_test.py METHOD N      # METHOD: integral, auto, ...

Prints the model choice, the status, the calibration of the products' Wald p-values (the
diagonal candidate's plain p: the share below 1e-3, 1e-2, 0.05, 0.1, 0.5 and the
Kolmogorov-Smirnov p against uniform; the mean Wald statistic, 3 if the covariance is true),
the kept elements' sigma over the restricted fit's own
(the reported covariance less diagnostics.model_selection.held_covariance_added), their RMS z
with and without the held covariance, and, for model='diagonal' on the integral method, the
largest |torque_bias='auto' - 'off'| over the full fit's sigma among the records whose bias
test drops the bias.  The noise is test/test_estimation.py's ``add_noise`` (gyro 0.002 rad/s,
torque 2 % of its RMS).
"""
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import yaml

from inertia_ros.core.estimation import estimate
from inertia_ros.core.inertia import matrix_to_theta
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

TRUTH = np.array([1.0, 1.2, 0.9, 0.0, 0.0, 0.0])
method, n = sys.argv[1], int(sys.argv[2])
d = yaml.safe_load((Path(__file__).parents[2] / 'config/scenes/default.yaml').read_text())
d.update(duration=20.0, body=dict(d.get('body', {}), inertia=TRUTH.tolist()))
d['gyro'] = dict(d.get('gyro', {}), noise_std=0.0)
d['torque_sensor'] = dict(d.get('torque_sensor', {}), noise_std=0.0, noise_rel=0.0)
sim = simulate(Scene.from_dict(d))
models, status, ratio, z, z0, dep, pv, wv = Counter(), Counter(), [], [], [], [], [], []
for seed in range(2000, 2000 + n):
    rng = np.random.default_rng(seed)
    omega = sim.omega_true + rng.normal(0.0, 0.002, sim.omega_true.shape)
    rms = np.sqrt(np.mean(sim.torque_command ** 2, axis=0))
    tau = sim.torque_command + rng.normal(0.0, 1.0, sim.torque_command.shape) * 0.02 * rms
    data = (sim.t_gyro, omega, sim.t_torque, tau)
    e = estimate(*data, method=method)
    models[e.model] += 1
    status[e.status] += 1
    tested = (e.diagnostics.get('model_selection') or {}).get('models', {}).get('diagonal')
    if tested is not None:
        pv.append(tested['p_value'])
        wv.append(tested['wald'])
    if e.model == 'diagonal':
        held = np.asarray(e.diagnostics['model_selection']['held_covariance_added'])[:6, :6]
        sd = np.sqrt(np.diag(np.asarray(e.covariance)))[:3]
        sd0 = np.sqrt(np.diag(np.asarray(e.covariance) - held))[:3]
        err = matrix_to_theta(e.inertia)[:3] - TRUTH[:3]
        ratio.append(sd / sd0)
        z.append(err / sd)
        z0.append(err / sd0)
    if method == 'integral':
        a, o = (estimate(*data, method='integral', model='diagonal', torque_bias=b)
                for b in ('auto', 'off'))
        if a.torque_bias is None:
            f = estimate(*data, method='integral', model='full', torque_bias='off')
            dep.append(np.max(np.abs(np.diag(a.inertia) - np.diag(o.inertia))
                              / np.diag(f.inertia_std)))
print(f'{method}, {n} seeds: models {dict(models)} status {dict(status)}')
if pv:
    from scipy.stats import kstest
    print(f'products Wald p ({len(pv)}): share below 1e-3, 1e-2, 0.05, 0.1, 0.5',
          [round(float(np.mean(np.less(pv, a))), 4) for a in (1e-3, 1e-2, 0.05, 0.1, 0.5)],
          f'KS p {kstest(pv, "uniform").pvalue:.3g}, mean W {np.mean(wv):.2f} (3 expected)')
print('kept sigma / restricted own: median', np.round(np.median(ratio, axis=0), 3),
      'max', np.round(np.max(ratio, axis=0), 3))
print('kept RMS z:', np.round(np.sqrt(np.mean(np.square(z), axis=0)), 3),
      'without the held covariance:', np.round(np.sqrt(np.mean(np.square(z0), axis=0)), 3))
if dep:
    print(f'diagonal, bias dropped ({len(dep)} records): max |auto - off| / full sigma '
          f'{max(dep):.3g}, over 0.1 in {sum(x > 0.1 for x in dep)}')
