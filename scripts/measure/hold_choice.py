"""Seeded hold-choice measurement, estimate() defaults; truth_sim, the default scene's body and excitation."""

import sys

import numpy as np

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.inertia import matrix_to_theta

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
kind, n, dur = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
zs, st, holds, meth, errs, ts = [], {}, {}, {}, [], []
for rec in simulate_truth(SCENE.with_(torque_kind=kind, duration=dur), range(n)):
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
    for d, k in ((st, e.status), (holds, e.diagnostics["hold"]), (meth, e.method)):
        d[k] = d.get(k, 0) + 1
    ts.append(e.diagnostics["hold_selection"].get("statistic"))
    zs.append((e.theta - matrix_to_theta(rec.inertia)) / e.theta_std)
    errs.append(np.linalg.norm(e.inertia - rec.inertia) / np.linalg.norm(rec.inertia))
print(
    f"{kind} {n} seeds x {dur:g} s: status {st} hold {holds} method {meth} RMS z {np.sqrt(np.mean(np.square(zs))):.3f} "
    f"max|z| {np.max(np.abs(zs)):.1f} median error {100 * np.median(errs):.3f} % statistic (log excess ratio) in [{min(ts):.3f}, {max(ts):.3f}]"
)
