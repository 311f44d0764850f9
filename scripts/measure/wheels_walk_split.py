"""Where the wheels' products sigma went short (issue 27 "sigma true"): the walk, per term.

    python scripts/measure/wheels_walk_split.py split|synthetic [N]

The wheels scene of ``scripts/measure/wheels_z.py`` (diagonal truth, the speed noise only:
the gyro's x 0.01), ``integral``, model full, no bias, 5 s segments, N draws (default 200).

``split``: the speed noise enters the equivalent torque twice, through ``-dh/dt`` (white in
``y``) and through the ``w x h`` integral (the ``w x e`` walk); the draws put it in both, in
``dh`` only and in ``w x h`` only.  ``synthetic``: no speed noise; white torque noise is added
to the equivalent torque, of the record-mean diagonal variance of ``w x e`` (``diag``, what
the stationary model assumes), of its full record-mean covariance (``full``), or
time-varying as ``w(t) x e`` is (``tv``).  Each prints the empirical variance of the six
elements about the truth, the mean noise-model variance (reported / ``sigma_widened_by``^2)
and their ratio (Ixx Iyy Izz Ixy Ixz Iyz), main 6cbe252 -> this tree, 200 draws:

    speed noise in both     1.02 0.94 1.04 1.55 2.06 2.25 -> 1.11 1.10 1.16 1.06 0.96 1.05
    speed noise in w x h    0.89 0.75 0.88 1.37 1.96 2.11 -> 0.96 0.87 0.98 0.94 0.91 0.99
    speed noise in dh       0.08 0.09 0.10 0.10 0.06 0.05 (the white part is small)
    synthetic walk diag     1.00 0.73 0.88 0.88 1.01 0.99 (stationary: what main assumed)
    synthetic walk tv       0.87 0.85 0.88 1.47 2.72 2.02 -> 0.94 0.99 0.98 1.01 1.27 0.95
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(ROOT))

import wheels_z as wz  # noqa: E402

from inertia_ros.core.estimation import momentum as mo  # noqa: E402
from inertia_ros.core.estimation.align import cross_matrices  # noqa: E402
from inertia_ros.core.estimation.batch import estimate_arrays  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402

OPTS = dict(method='integral', model='full', torque_bias='off', segment=5.0)


class Record:
    """The seed-free truth, its reduction and the noise model's inputs."""

    def __init__(self) -> None:
        self.sim, self.scene = wz.scene_for('wheels', 'diag', 'speed')
        self.base = simulate(self.sim, 0)
        ws = self.sim.wheels.wheels
        self.rows = np.array([w.inertia * np.asarray(w.axis) for w in ws])
        ss = self.scene.wheels.speed_noise_std
        self.hcov = sum((w.inertia * ss) ** 2 * np.outer(w.axis, w.axis) for w in ws)
        self.truth = self.sim.inertia[wz.THETA_IDX]
        self.h_true = self.base.wheel_speed_true @ self.rows

    def momentum(self, h: np.ndarray) -> mo.Momentum:
        """The momentum input of ``h`` with the stated noise covariance."""
        t = self.base.t_wheel
        return mo.as_momentum(mo.Momentum(t, h, np.zeros((0, len(t), 3)), (), self.hcov))

    def estimate(self, omega: np.ndarray, h: np.ndarray, torque=None):
        """``estimate_with_momentum``'s batch call, the equivalent torque replaceable."""
        mom = self.momentum(h)
        tg = self.base.t_gyro
        red = mo.Reduction(tg, mom.t, np.zeros(0), 'zoh')
        grid, tq, inside = red(omega, mom.h, np.zeros((0, 3)))
        if torque is not None:
            tq = torque(red, grid, tq, omega)
        opts = dict(OPTS, gyro_noise=self.scene.gyro.noise_std)
        terms = mo._noise_terms(red, omega, mom, np.zeros(0), np.zeros((0, 3)), opts)
        tn, kw = terms[0], {}
        if len(terms) > 2:                 # this tree (main 6cbe252: the record mean only)
            kw['walk_cov'] = mo.interval_walk(grid, terms[2], grid)
            kw['walk_wh'] = mo.interval_walk(grid, terms[3], grid)
        return estimate_arrays(tg[inside], omega[inside], grid, tq, hold='zoh',
                               torque_noise=tn, **kw, **opts)


def report(name: str, rec: Record, results: list) -> None:
    """Empirical against noise-model variance per element."""
    err = np.array([e.theta - rec.truth for e in results])
    emp = np.mean(err ** 2, axis=0)
    model = np.mean([np.diag(np.asarray(e.covariance))
                     / e.diagnostics['adequacy']['sigma_widened_by'] ** 2 for e in results], 0)
    print(f'--- {name} n={len(results)}')
    print('  empirical var  ', np.array2string(emp, precision=3))
    print('  noise model var', np.array2string(model, precision=3))
    print('  ratio          ', np.array2string(emp / model, precision=2))
    sys.stdout.flush()


def split(rec: Record, n: int) -> None:
    """The speed noise in both places, in ``dh`` only, in ``w x h`` only."""
    def only(which: str, h_noisy: np.ndarray):
        def torque(red, grid, tq, omega):
            hn = mo._interp_h(red.t_h, h_noisy, grid, red.gaps, red.basis)
            ht = mo._interp_h(red.t_h, rec.h_true, grid, red.gaps, red.basis)
            hd, hc = (hn, ht) if which == 'dh' else (ht, hn)
            out = tq.copy()
            out[:-1] = mo.interval_torque(grid, red.rates(omega), hc)
            out[:-1] += (np.diff(hc, axis=0) - np.diff(hd, axis=0)) / np.diff(grid)[:, None]
            out[-1] = out[-2]
            return out
        return torque
    for which in ('both', 'dh', 'w x h'):
        res = []
        for seed in range(n):
            omega, speed = wz.draw(rec.base, rec.scene, seed)
            h = speed @ rec.rows
            res.append(rec.estimate(omega, h, None if which == 'both' else only(which, h)))
        report(f'speed noise in {which}', rec, res)


def synthetic(rec: Record, n: int) -> None:
    """White torque noise of the ``w x e`` walk's variance: stationary or time-varying."""
    share = 2.0                                   # gyro samples per wheel sample (200/100 Hz)
    for kind in ('diag', 'full', 'tv'):
        res = []
        for seed in range(n):
            rng = np.random.default_rng(1000 + seed)
            omega = rec.base.omega_true + rng.normal(0.0, rec.scene.gyro.noise_std,
                                                     rec.base.omega_true.shape)

            def torque(red, grid, tq, om, rng=rng, kind=kind):
                wx = cross_matrices(red.rates(rec.base.omega_true))
                S = share * (wx @ rec.hcov) @ wx.transpose(0, 2, 1)
                z = rng.standard_normal((len(grid) - 1, 3))
                if kind == 'diag':
                    u = z * np.sqrt(np.diag(S.mean(0)))
                elif kind == 'full':
                    u = z @ np.linalg.cholesky(S.mean(0)).T
                else:
                    e = z @ np.linalg.cholesky(share * rec.hcov).T
                    u = np.einsum('nij,nj->ni', wx[:-1], e)
                out = tq.copy()
                out[:-1] += u
                out[-1] = out[-2]
                return out
            res.append(rec.estimate(omega, rec.h_true, torque))
        report(f'synthetic walk {kind}', rec, res)


def main() -> None:
    """``split`` or ``synthetic`` (see the module docstring)."""
    mode = sys.argv[1] if len(sys.argv) > 1 else 'split'
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 200
    {'split': split, 'synthetic': synthetic}[mode](Record(), n)


if __name__ == '__main__':
    main()
