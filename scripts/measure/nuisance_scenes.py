"""The nuisance figures of DESIGN.md: the 20 s scenes of test/test_nuisance.py with each term
in the data, ``estimate(method='integral', nuisance='auto')``, seeds 100 .. 100 + N - 1.

    python scripts/measure/nuisance_scenes.py TERM N

Prints how often TERM was chosen, the RMS z of its values, the RMS z of the tensor and the
statuses.  Run from the repository root (it reads the scenes from test/test_nuisance.py).
"""
import sys

import numpy as np

from inertia_ros.core.estimation import estimate
from inertia_ros.core.simulation import simulate
from inertia_ros.core.tensor import matrix_to_theta

sys.path.insert(0, 'test')
from test_nuisance import PRESENT, _scene


def main() -> None:
    term, n = sys.argv[1], int(sys.argv[2])
    changes, truth = PRESENT[term]
    found, zt, zv, st = 0, [], [], {}
    for seed in range(100, 100 + n):
        r = simulate(_scene(**changes), seed=seed)
        e = estimate(r.t_gyro, r.omega, r.t_torque, r.torque, method='integral',
                     nuisance='auto')
        nd = e.diagnostics['nuisance']
        st[e.status] = st.get(e.status, 0) + 1
        if term in nd.get('chosen', []):
            found += 1
            zv += list((np.atleast_1d(nd['values'][term]) - np.atleast_1d(truth))
                       / np.atleast_1d(nd['sigma'][term]))
        if e.theta is not None and e.theta_std is not None:
            zt += list((e.theta - matrix_to_theta(r.inertia)) / e.theta_std)
    print(term, 'found', found, '/', n, 'value z RMS', rms(zv), 'tensor z RMS', rms(zt), st)


def rms(z: list) -> float | None:
    """Root mean square of ``z`` (2 decimals; None when empty)."""
    return round(float(np.sqrt(np.mean(np.square(z)))), 2) if z else None


if __name__ == '__main__':
    main()
