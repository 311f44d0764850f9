"""Paired node update cost: hold zoh vs auto, the node's estimator (make_estimator defaults)."""

import sys
import time

import numpy as np

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.nodes import params
from inertia_ros.nodes.selection import make_estimator

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
rec = simulate_truth(SCENE.with_(torque_kind="continuous", duration=60.0), [0])[0]
cfg = {n: s.default for n, s in params.ESTIMATOR.items()}


def run(hold):
    est = make_estimator(dict(cfg, hold=hold))()
    edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1)
    gi = np.searchsorted(rec.t_gyro, edges, side="right")
    ti = np.searchsorted(rec.t_torque, edges, side="right")
    per, est_t, last = [], [], None
    for k in range(1, len(edges)):
        t0 = time.perf_counter()
        for j in range(ti[k - 1], ti[k]):
            est.add_torque(float(rec.t_torque[j]), rec.torque[j])
        for j in range(gi[k - 1], gi[k]):
            est.add_gyro(float(rec.t_gyro[j]), rec.omega[j])
        t1 = time.perf_counter()
        last = est.estimate()
        t2 = time.perf_counter()
        est.refresh()
        t3 = time.perf_counter()
        per.append(t3 - t0)
        est_t.append(t2 - t1)
    return np.array(per), np.array(est_t), last


res = {"zoh": [], "auto": []}
for r in range(int(sys.argv[1]) if len(sys.argv) > 1 else 3):
    for h in ("zoh", "auto") if r % 2 == 0 else ("auto", "zoh"):
        res[h].append(run(h))
for h, rs in res.items():
    per = np.concatenate([x[0] for x in rs]) * 1e3
    et = np.concatenate([x[1] for x in rs]) * 1e3
    e = rs[-1][2]
    print(
        f"{h:5s} update (adds+estimate+refresh) median {np.median(per):.2f} ms  p95 {np.percentile(per, 95):.2f} ms  max {per.max():.1f} ms | estimate() median {np.median(et):.2f} ms p95 {np.percentile(et, 95):.2f} | total {per.sum() / len(rs):.0f} ms/60 s run | final {e.status} hold {e.diagnostics.get('hold')}"
    )
# paired ratio per update index (same data, same update)
a = np.array([x[0] for x in res["auto"]]).mean(0)
z = np.array([x[0] for x in res["zoh"]]).mean(0)
print(f"paired per-update ratio auto/zoh: median {np.median(a / z):.2f}  (updates {len(a)})")
