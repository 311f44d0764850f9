"""The tracker's innovation tests on model-conforming records (issue 27, session 6).

    python scripts/measure/tracker_innovations.py matrix DURATIONS SEEDS [truth]
    python scripts/measure/tracker_innovations.py startup SEEDS DURATION

``matrix``: the capability matrix's torque cell (``test/test_capability_matrix.py``: 100 Hz
gyro, 50 Hz torque, amplitude 0.2, the tracker at window 1000 s, full model, no torque bias,
zero-order hold, fed in 0.5 s blocks), seeds 0..SEEDS-1 at each of the comma-separated
DURATIONS [s]; prints how many records the whiteness test rejects at ``ALPHA`` and the average
NIS per dof.  ``truth``: the true gyro noise level given instead of estimated.
``startup``: ``honest_status.py``'s conforming scene (node tracker defaults, hold zoh, 10 Hz
blocks): the mean NIS per dof of the blocks in the first ``SKIP_S`` after the filter is armed
(the blocks the tests skip) and of the later ones.
"""

import sys

import numpy as np

from inertia_ros.bench.honesty import feed_online
from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import tracking_consistency as tc
from inertia_ros.core.estimation.options import ALPHA
from inertia_ros.core.estimation.tracking import TrackingEstimator


def _feed(est: TrackingEstimator, rec, block: float = 0.5):
    """The capability matrix's feed: every ``block`` s the gyro and torque samples, then
    estimate."""
    edges = np.arange(0.0, rec.t_gyro[-1] + 1.5 * block, block)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        g = (rec.t_gyro >= a) & (rec.t_gyro < b)
        if g.any():
            est.add_gyro(rec.t_gyro[g], rec.omega[g])
        q = (rec.t_torque >= a) & (rec.t_torque < b)
        if q.any():
            est.add_torque(rec.t_torque[q], rec.torque[q])
    return est.estimate()


def matrix(durations: list[float], seeds: int, truth: bool) -> None:
    for dur in durations:
        case = TruthCase(duration=dur, gyro_rate=100, torque_rate=50, torque_kind='zoh',
                         amplitude=0.2, omega0=(0.1, -0.05, 0.08))
        ps, anis = [], []
        for rec in simulate_truth(case, list(range(seeds))):
            kw = {'gyro_noise': case.gyro_noise} if truth else {}
            e = _feed(TrackingEstimator(window=1000.0, model='full', torque_bias='off',
                                        hold='zoh', **kw), rec)
            ad = (e.diagnostics or {}).get('adequacy') or {}
            if 'whiteness_p_value' in ad:
                ps.append(ad['whiteness_p_value'])
                anis.append(ad['anis_chi2'] / ad['anis_dof'])
        p = np.array(ps)
        print(f'{dur:g} s x {seeds}: whiteness p < {ALPHA:g} in {int(np.sum(p < ALPHA))} of '
              f'{len(p)} tested (min p {p.min() if len(p) else np.nan:.2g}); average NIS/dof '
              f'median {np.median(anis) if anis else np.nan:.2f}, max '
              f'{max(anis) if anis else np.nan:.2f}')


def startup(seeds: int, duration: float) -> None:
    from honest_status import SCENE
    early: list[float] = []
    late: list[float] = []
    orig = tc.InnovationTests.add

    def add(self, t, nu, S, armed):
        if armed:
            t0 = self._t0 if self._t0 is not None else t
            e = np.linalg.solve(np.linalg.cholesky(S), nu)
            (early if t < t0 + tc.SKIP_S else late).append(float(e @ e) / 3)
        return orig(self, t, nu, S, armed)

    tc.InnovationTests.add = add
    per = []
    for rec in simulate_truth(SCENE.with_(duration=duration), list(range(seeds))):
        early.clear()
        feed_online(TrackingEstimator(window=10.0, model='full', torque_bias='auto',
                                      hold='zoh'), rec, 10.0)
        if early:
            per.append(np.mean(early))
    print(f'{seeds} x {duration:g} s: NIS/dof in the first {tc.SKIP_S:g} s after arming: mean '
          f'{np.mean(per):.3f} over {len(per)} records; later blocks {np.mean(late):.3f}')


if __name__ == '__main__':
    if sys.argv[1] == 'matrix':
        matrix([float(d) for d in sys.argv[2].split(',')], int(sys.argv[3]),
               len(sys.argv) > 4 and sys.argv[4] == 'truth')
    else:
        startup(int(sys.argv[2]), float(sys.argv[3]))
