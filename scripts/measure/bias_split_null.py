"""The bias split under its null: model-conforming short records with a body-fixed torque bias.

    python scripts/measure/bias_split_null.py split SEEDS [DURATION]
    python scripts/measure/bias_split_null.py defaults SEEDS [DURATION]
    python scripts/measure/bias_split_null.py constant SEEDS [DURATION]

The scene: ``honest_status.py``'s conforming scene (0.06 N m sines, 0.0012 N m torque noise,
0.002 rad/s gyro noise) with a constant 0.003 N m body-axis disturbance, which the torque
bias models exactly.  ``split``: ``estimate()`` with the bias fitted (integral, zoh, full) and
the bias split's chi2 per dof (9 dof on four pieces; 1 under the model): its mean, median and
how many exceed 4 (``model_mismatch``).  ``defaults``: ``estimate()`` with its defaults, the
statuses, the records not ok or above 4 sigma, and the RMS z.  ``constant``: the honesty
benchmark's constant-torque case (the torque bias is inseparable from the scale there and
left out), the smallest p-value of the adequacy tests of each record: how many fall below
0.05, 0.01 and 1e-3 (a rule on them would cry wolf that often).
"""
import argparse

import numpy as np

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import estimate

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02),
                  disturbance=(0.003, -0.002, 0.002), disturbance_kind='body')


def _constant(n: int, duration: float) -> None:
    """The smallest test p-value per record of the constant-torque case, defaults."""
    from inertia_ros.bench.honesty import CASES
    ps = []
    for rec in simulate_truth(CASES['constant'].truth.with_(duration=duration), range(n)):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
        a = e.diagnostics.get('adequacy', {})
        ps.append(min(a.get('window_p_value', 1.0), a.get('segment_shift_p_value', 1.0),
                      a.get('bias_split_p_value', 1.0)))
    p = np.sort(ps)
    print(f'constant {n} x {duration:g} s: smallest test p < 0.05: {int(np.sum(p < 0.05))}, '
          f'< 0.01: {int(np.sum(p < 0.01))}, < 1e-3: {int(np.sum(p < 1e-3))}; lowest '
          + ' '.join(f'{x:.1e}' for x in p[:4]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('mode', choices=('split', 'defaults', 'constant'))
    ap.add_argument('seeds', type=int, help='records (seeds 0..SEEDS-1)')
    ap.add_argument('duration', type=float, nargs='?', default=5.0, help='[s] (5)')
    args = ap.parse_args()
    mode, n, duration = args.mode, args.seeds, args.duration
    if n < 1 or not duration > 0:
        ap.error(f'seeds must be >= 1 and duration > 0, got {n} and {duration}')
    if mode == 'constant':
        _constant(n, duration)
        return
    forced = dict(torque_bias=True, hold='zoh', method='integral', model='full')
    iu = np.triu_indices(3)
    ratios, zs, statuses = [], [], {}
    for seed, rec in enumerate(simulate_truth(SCENE.with_(duration=duration), range(n))):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque,
                     **(forced if mode == 'split' else {}))
        a = e.diagnostics.get('adequacy', {})
        if np.isfinite(a.get('bias_split_chi2', np.nan)):
            ratios.append(a['bias_split_chi2'] / a['bias_split_dof'])
        statuses[e.status] = statuses.get(e.status, 0) + 1
        if e.inertia_std is None:
            continue
        z = ((e.inertia - rec.inertia) / e.inertia_std)[iu]
        zs.append(z)
        if mode == 'defaults' and (e.status != 'ok' or np.nanmax(np.abs(z)) > 4):
            print(f'seed {seed}: {e.status} max|z| {np.nanmax(np.abs(z)):.1f} split '
                  f"{a.get('bias_split_chi2', np.nan):.1f}/{a.get('bias_split_dof')} shift "
                  f"{a.get('segment_shift_chi2', np.nan):.1f}/{a.get('segment_shift_dof')}")
    r = np.array(ratios)
    print(f'{mode} {n} x {duration:g} s: {statuses}; RMS z '
          f'{np.sqrt(np.nanmean(np.array(zs) ** 2)):.2f}; split ran {len(r)}'
          + (f', chi2/dof mean {r.mean():.2f} median {np.median(r):.2f}, over 4: '
             f'{int(np.sum(r > 4))}' if len(r) else ''))


if __name__ == '__main__':
    main()
