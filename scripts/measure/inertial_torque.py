"""Measure ``estimate(..., inertial_torque=...)`` on the reference simulator (issue 27).

    python scripts/measure/inertial_torque.py SCENE DURATION SEEDS [--option auto|on|off]
        [--method integral] [--hold auto] [--show]

SCENE: ``inertial`` (``bench.honesty.CASES['disturbance']``: 0.01 N m per axis fixed in
inertial axes), ``zero`` (the same scene without disturbance) or ``body`` (the same
disturbance constant in body axes); SEEDS a count (``40``: seeds 0-39) or a list (``3,31``).
Prints per scene: the statuses, the disturbance chosen (``diagnostics.disturbance.chosen``),
the methods reported (``--method auto`` and ``ml`` report ``integral`` when the inertial
torque is kept), the median relative Frobenius error of the tensor, the RMS z of its six
elements, the largest |z| of the ``ok`` records and how many of them have some |z| > 4;
``--show`` one line per record.

Measured (hspace2 15dce70, 2026-11-28, method integral, hold auto, 5 s, seeds 0-39):

    inertial  off   model_mismatch 35, ok 5   3.28 %  RMS z 1.27  ok beyond 4 sigma: 4
    inertial  auto  ok 40 (inertial 38, both 2)  0.40 %  RMS z 0.98  ok beyond 4 sigma: 0
    zero      off   ok 40                        0.41 %  RMS z 1.07
    zero      auto  ok 40 (none 38, both 2)      0.41 %  RMS z 0.99
    body      auto  ok 40 (body 38, both 2)      0.43 %  RMS z 1.00
"""
from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.tensor import THETA_COLS, THETA_ROWS


def _seeds(text: str) -> list[int]:
    return [int(s) for s in text.split(',')] if ',' in text else list(range(int(text)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene', choices=('inertial', 'zero', 'body'))
    ap.add_argument('duration', type=float)
    ap.add_argument('seeds', type=_seeds)
    ap.add_argument('--option', default='auto', choices=('auto', 'on', 'off'))
    ap.add_argument('--method', default='integral')
    ap.add_argument('--hold', default='auto')
    ap.add_argument('--show', action='store_true')
    a = ap.parse_args()
    case = CASES['disturbance'].truth.with_(duration=a.duration)
    if a.scene == 'zero':
        case = case.with_(disturbance=(0.0, 0.0, 0.0))
    elif a.scene == 'body':
        case = case.with_(disturbance_kind='body')
    status, chosen, used, zs, errs, far, ok_z = Counter(), Counter(), Counter(), [], [], 0, 0.0
    for rec in simulate_truth(case, a.seeds):
        e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method=a.method,
                     hold=a.hold, inertial_torque=a.option)
        truth = rec.inertia_end[THETA_ROWS, THETA_COLS]
        z = (e.inertia[THETA_ROWS, THETA_COLS] - truth) / e.inertia_std[THETA_ROWS, THETA_COLS]
        err = np.linalg.norm(e.inertia - rec.inertia_end) / np.linalg.norm(rec.inertia_end)
        dist = e.diagnostics.get('disturbance', {})
        status[e.status] += 1
        chosen[str(dist.get('chosen', '-'))] += 1
        used[e.method] += 1
        if e.status == 'ok':
            ok_z = max(ok_z, float(np.abs(z).max()))
        zs.append(z)
        errs.append(err)
        far += int(e.status == 'ok' and np.abs(z).max() > 4.0)
        if a.show:
            tests = ', '.join(f'{k} p {v["p_value"]:.1e}' for k, v in dist.get('tests', {}).items())
            print(f'  seed {rec.seed}: {e.status} {e.model} hold {e.diagnostics.get("hold")} '
                  f'{100 * err:.2f} % max|z| {np.abs(z).max():.2f} [{tests}]')
    z = np.array(zs)
    print(f'{a.scene} {a.duration:g} s {a.option} method {a.method}: {dict(status)} chosen '
          f'{dict(chosen)} reported {dict(used)} err {100 * np.median(errs):.2f} % RMS z '
          f'{np.sqrt(np.mean(z ** 2)):.2f} max |z| of ok {ok_z:.2f} ok beyond 4 sigma: {far}')


if __name__ == '__main__':
    main()
