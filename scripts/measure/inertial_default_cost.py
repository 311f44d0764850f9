"""The default call's cost with ``inertial_torque='auto'`` against ``'off'`` (issue 27).

    python scripts/measure/inertial_default_cost.py [--records 6] [--calls 3] [DURATION ...]

The conforming scene of ``honest_status.py`` (5 s and 60 s by default): ``estimate()`` with
its defaults but the option, on each record ``--calls`` times per setting in turn; prints
the per-record ratio of the fastest calls and its median.  Session 9: 1.36x at 5 s, 1.29x
at 60 s (13 -> 19 ms, 58 -> 75 ms).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from honest_status import case_named

from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.core.estimation import estimate


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('durations', type=float, nargs='*', default=[5.0, 60.0], help='[s]')
    ap.add_argument('--records', type=int, default=6, help='records (seeds 0..N-1)')
    ap.add_argument('--calls', type=int, default=3, help='calls per record and setting')
    args = ap.parse_args()
    if args.records < 1 or args.calls < 1 or not all(d > 0 for d in args.durations):
        ap.error('records and calls must be >= 1 and durations > 0')
    for dur in args.durations:
        ratios, best = [], {'off': [], 'auto': []}
        for r in simulate_truth(case_named('conforming', dur), range(args.records)):
            t: dict[str, list[float]] = {'off': [], 'auto': []}
            for _ in range(args.calls):
                for opt in t:
                    t0 = time.perf_counter()
                    estimate(r.t_gyro, r.omega, r.t_torque, r.torque, inertial_torque=opt)
                    t[opt].append(time.perf_counter() - t0)
            ratios.append(min(t['auto']) / min(t['off']))
            for opt in t:
                best[opt].append(min(t[opt]))
        print(f'{dur:g} s: off {1e3 * np.median(best["off"]):.1f} ms, auto '
              f'{1e3 * np.median(best["auto"]):.1f} ms; auto/off per record '
              f'{np.round(ratios, 2).tolist()}, median {np.median(ratios):.2f}')


if __name__ == '__main__':
    main()
