"""Measure ``estimate(..., inertial_torque=...)`` on the reference simulator (issue 27).

    python scripts/measure/inertial_torque.py SCENE DURATION SEEDS [--option auto|on|off]
        [--method integral] [--hold auto] [--show] [--screen]

SCENE: ``inertial`` (``bench.honesty.CASES['disturbance']``: 0.01 N m per axis fixed in
inertial axes), ``zero`` (the same scene without disturbance) or ``body`` (the same
disturbance constant in body axes); SEEDS a count (``40``: seeds 0-39) or a list (``3,31``).
Prints per scene: the statuses, the disturbance chosen (``diagnostics.disturbance.chosen``),
the methods reported (``--method auto`` and ``ml`` report ``integral`` when the inertial
torque is kept), the median relative Frobenius error of the tensor, the RMS z of its six
elements, the largest |z| of the ``ok`` records and how many of them have some |z| > 4;
``--show`` one line per record.

``--screen`` (with ``--option auto``): each record also through the full joint rule
(``selection.SCREEN_ALPHA = 1``: always wide, as before the screen), and the screen against
it: records the screen sent wide, misses (the full rule keeps ``d``, the screened estimate
does not), choices that differ where the screen went wide (none expected: the wide path is the
full rule's), and the estimate's median time screened / full / ``'off'``.

Measured (hspace2 15dce70, 2026-11-28, method integral, hold auto, 5 s, seeds 0-39):

    inertial  off   model_mismatch 35, ok 5   3.28 %  RMS z 1.27  ok beyond 4 sigma: 4
    inertial  auto  ok 40 (inertial 38, both 2)  0.40 %  RMS z 0.98  ok beyond 4 sigma: 0
    zero      off   ok 40                        0.41 %  RMS z 1.07
    zero      auto  ok 40 (none 38, both 2)      0.41 %  RMS z 0.99
    body      auto  ok 40 (body 38, both 2)      0.43 %  RMS z 1.00

With the screen (h9speed, 2026-11-28, 5 s, seeds 0-199, ``--screen``): inertial 0 misses,
the full rule's choice on 200/200 (inertial 187, both 13); zero 7/200 went wide, 0 misses,
200/200 the same (none 198); body 21/200 wide, 0 misses, 200/200 the same (body 190, both
10).  ``--option auto`` against main 3321eac: the same statuses, choices, errors (0.39,
0.37, 0.41 %) and RMS z (1.03, 1.00 -> 0.99, 1.02).
"""
from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np

import inertia_ros.core.estimation.selection as selection
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
    ap.add_argument('--screen', action='store_true')
    a = ap.parse_args()
    if a.screen:
        _screen(a)
        return
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


def _timed(rec, a, option: str, screen_alpha: float):
    """The estimate of ``rec`` with ``inertial_torque=option`` and the screen's level, and
    its time [s]."""
    selection.SCREEN_ALPHA = screen_alpha
    t0 = time.perf_counter()
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method=a.method,
                 hold=a.hold, inertial_torque=option)
    return e, time.perf_counter() - t0


def _screen(a) -> None:
    """``--screen``: the screen against the full rule on every record."""
    case = CASES['disturbance'].truth.with_(duration=a.duration)
    if a.scene == 'zero':
        case = case.with_(disturbance=(0.0, 0.0, 0.0))
    elif a.scene == 'body':
        case = case.with_(disturbance_kind='body')
    level = selection.SCREEN_ALPHA
    wide = misses = differ = 0
    times: dict[str, list[float]] = {'screened': [], 'full': [], 'off': []}
    chosen: Counter = Counter()
    for rec in simulate_truth(case, a.seeds):
        es, ts = _timed(rec, a, 'auto', level)
        ef, tf = _timed(rec, a, 'auto', 1.0)              # always wide: the full rule
        _, to = _timed(rec, a, 'off', level)
        for k, v in zip(times, (ts, tf, to), strict=True):
            times[k].append(v)
        ds, df = es.diagnostics.get('disturbance', {}), ef.diagnostics.get('disturbance', {})
        # (a linear-hold result keeps the held run's choice: its screen went wide when on)
        went = bool(ds.get('screen', {}).get('went_wide')) or ds.get(
            'inertial_torque_of_the_held_run') == 'on'
        full_d = df.get('chosen') in ('inertial', 'both')
        wide += went
        misses += full_d and ds.get('chosen') not in ('inertial', 'both')
        differ += went and ds.get('chosen') != df.get('chosen')
        chosen[(str(ds.get('chosen')), str(df.get('chosen')))] += 1
        if a.show:
            sc = ds.get('screen', {})
            print(f'  seed {rec.seed}: screen {sc.get("test")} p {sc.get("p_value") or np.nan:.2e} '
                  f'wide {went}; chosen {ds.get("chosen")} (full rule {df.get("chosen")})')
    n = len(a.seeds)
    med = {k: 1e3 * float(np.median(v)) for k, v in times.items()}
    print(f'{a.scene} {a.duration:g} s, screen at {level:g}: wide {wide}/{n}, misses {misses} '
          f'(full rule keeps d, screened not), choices differing where wide {differ}; '
          f'(screened, full) choices {dict(chosen)}; median ms screened {med["screened"]:.0f} '
          f'full {med["full"]:.0f} off {med["off"]:.0f}')


if __name__ == '__main__':
    main()
