"""Torque-free status and sigma on the reference simulator (issue 27 item 4, the torque-free rule).

    python scripts/measure/honest_torque_free.py SEEDS DURATION [GYRO_BIAS] [api|node|oneblock]

A tumble of the body diag(2.0, 1.5, 3.0) x 1e-3 kg m^2 from (3, 4, 5) rad/s, 100 Hz gyro with
0.01 rad/s noise and no torque (as test_torque_free_calibration's reference records), a gyro
bias of GYRO_BIAS rad/s on x (default 0) added, seeds ``0 .. SEEDS - 1``.  ``api`` (default):
``estimate(method='integral')``; ``node``: ``RecursiveEstimator`` fed in 0.1 s blocks with an
estimate after each, as the node does (the honesty benchmark's node options: 10 Hz estimates,
adequacy re-run once a second and deferred), the last estimate kept; ``oneblock``: the same
estimator fed the whole record as one block, one estimate at the end (a log replayed at once).
Prints the statuses, the RMS z of the six element ratios (trace-normalised), the largest sigma
widening and the records ``scale_unobservable`` with some |z| > 5.
"""

import dataclasses
import sys

import numpy as np

from inertia_ros.bench.honesty import feed_online
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import RecursiveEstimator, estimate

ROWS, COLS = [0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]
NODE_OPTIONS = {'model': 'full', 'torque_bias': 'auto', 'hold': 'zoh', 'reselect_every': 10,
                'defer_adequacy': True}


def main() -> None:
    n, dur = int(sys.argv[1]), float(sys.argv[2])
    bias = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
    path = sys.argv[4] if len(sys.argv) > 4 else 'api'
    case = TruthCase(inertia=np.diag([2.0e-3, 1.5e-3, 3.0e-3]), omega0=(3.0, 4.0, 5.0),
                     duration=dur, gyro_rate=100, torque_rate=100, gyro_noise=0.01,
                     torque_noise=0.0, amplitude=0.0)
    st: dict[str, int] = {}
    zs, widened, far = [], [1.0], 0
    for r in simulate_truth(case, range(n)):
        omega = r.omega + np.array([bias, 0.0, 0.0])
        if path == 'node':
            e = feed_online(RecursiveEstimator(**NODE_OPTIONS),
                            dataclasses.replace(r, omega=omega), 10.0)
        elif path == 'oneblock':
            est = RecursiveEstimator(**NODE_OPTIONS)
            est.add_gyro(r.t_gyro, omega)
            est.add_torque(r.t_torque, r.torque)
            e = est.estimate()
        else:
            e = estimate(r.t_gyro, omega, np.zeros(0), np.zeros((0, 3)), method='integral')
        st[e.status] = st.get(e.status, 0) + 1
        if e.ratios is None:
            continue
        truth = r.inertia[ROWS, COLS] / np.trace(r.inertia)
        z = (e.ratios[ROWS, COLS] - truth) / e.ratios_std[ROWS, COLS]
        zs.append(z)
        widened.append(e.diagnostics.get('adequacy', {}).get('sigma_widened_by', 1.0))
        far += e.status == 'scale_unobservable' and bool(np.max(np.abs(z)) > 5)
    print(f'torque-free {path} {n} x {dur:g} s, gyro bias {bias:g} rad/s: {st} RMS z '
          f'{np.sqrt(np.mean(np.concatenate(zs) ** 2)):.2f}, sigma widened up to '
          f'{max(widened):.2f}x, scale_unobservable with |z|>5: {far}')


if __name__ == '__main__':
    main()
