"""Node estimator (make_estimator defaults) fed as the node does, 10 seeds per torque kind."""

import numpy as np

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.inertia import matrix_to_theta
from inertia_ros.nodes import params
from inertia_ros.nodes.selection import make_estimator

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
cfg = {n: s.default for n, s in params.ESTIMATOR.items()}
for kind in ("continuous", "zoh"):
    for hold in ("zoh", "auto"):
        rows = []
        for rec in simulate_truth(SCENE.with_(torque_kind=kind, duration=20.0), range(10)):
            est = make_estimator(dict(cfg, hold=hold))()
            edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1)
            gi = np.searchsorted(rec.t_gyro, edges, side="right")
            ti = np.searchsorted(rec.t_torque, edges, side="right")
            for k in range(1, len(edges)):
                est.add_torque(rec.t_torque[ti[k - 1] : ti[k]], rec.torque[ti[k - 1] : ti[k]])
                est.add_gyro(rec.t_gyro[gi[k - 1] : gi[k]], rec.omega[gi[k - 1] : gi[k]])
                e = est.estimate()
                est.refresh()
            e = est.estimate()
            z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
            rows.append((e.status, e.diagnostics.get("hold", "zoh"), z))
        zz = np.array([r[2] for r in rows])
        print(
            f"{kind:10s} hold={hold:4s}: ok {sum(r[0] == 'ok' for r in rows)}/10, linear chosen {sum(r[1] == 'linear' for r in rows)}/10, RMS z {np.sqrt(np.mean(zz**2)):.2f}, max|z| {np.abs(zz).max():.1f}"
        )
