#!/usr/bin/env python3
"""Micro-benchmark of ``RecursiveEstimator`` as the node drives it (issue 6); prints figures.

    .venv/bin/python scripts/bench_recursive.py [--rate HZ] [--duration S] [--profile]

The nominal scene (config/scenes/default.yaml) simulated with gyro and torque both at
``--rate`` Hz (default 1000) for ``--duration`` s (default 60), as scripts/bench_node.py sends
it.  The estimator (default node parameters: model 'full', no bias, no forgetting) is fed in
10 ms blocks (the node's poll period) and ``estimate()`` is called every 100 ms (publish rate
10 Hz).  Reported: median / p95 / max wall time of ``estimate()`` over the second half of the
record [ms], feeding cost per gyro sample [us] (add_gyro + add_torque of the blocks, amortised
processing included) and the final estimate.  ``--profile`` prints the top cProfile entries of
the ``estimate()`` calls.  Timings depend on the machine's load.
"""
from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from inertia_ros.core.estimation import RecursiveEstimator  # noqa: E402
from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402


def streams(rate: float, duration: float, seed: int):
    """Nominal-scene streams with both sensors at ``rate`` Hz."""
    d = yaml.safe_load((ROOT / 'config' / 'scenes' / 'default.yaml').read_text())
    d['duration'] = duration
    d['gyro'] = dict(d.get('gyro', {}), rate=rate)
    d['torque_sensor'] = dict(d.get('torque_sensor', {}), rate=rate)
    return simulate(Scene.from_dict(d), seed=seed)


def main() -> int:
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--rate', type=float, default=1000.0, help='Hz per stream (default 1000)')
    ap.add_argument('--duration', type=float, default=60.0, help='seconds (default 60)')
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--profile', action='store_true', help='cProfile the estimate() calls')
    args = ap.parse_args()
    sim = streams(args.rate, args.duration, args.seed)
    poll, pub = 0.01, 0.1
    tg, tq = sim.t_gyro, sim.t_torque
    rec = RecursiveEstimator(model='full')
    prof = cProfile.Profile() if args.profile else None
    est_times: list[tuple[float, float]] = []
    feed = 0.0
    ig = iq = 0
    next_pub = pub
    res = None
    for k in range(1, int(round(args.duration / poll)) + 1):
        t_now = k * poll
        jg = int(np.searchsorted(tg, t_now, side='right'))
        jq = int(np.searchsorted(tq, t_now, side='right'))
        t0 = time.perf_counter()
        if jg > ig:
            rec.add_gyro(tg[ig:jg], sim.omega[ig:jg])
        if jq > iq:
            rec.add_torque(tq[iq:jq], sim.torque[iq:jq])
        feed += time.perf_counter() - t0
        ig, iq = jg, jq
        if t_now >= next_pub - 1e-9:
            next_pub += pub
            if prof is not None:
                prof.enable()
            t0 = time.perf_counter()
            res = rec.estimate()
            est_times.append((t_now, time.perf_counter() - t0))
            if prof is not None:
                prof.disable()
    late = np.array([dt for t, dt in est_times if t >= 0.5 * args.duration]) * 1e3
    print(f'recursive, {len(tg)} gyro + {len(tq)} torque samples at {args.rate:g} Hz, '
          f'{args.duration:g} s, 10 ms blocks, estimate() at 10 Hz')
    print(f'estimate() second half: median {np.median(late):.3f} ms, '
          f'p95 {np.percentile(late, 95):.3f} ms, max {np.max(late):.3f} ms '
          f'({len(late)} calls)')
    print(f'feeding: {1e6 * feed / len(tg):.2f} us per gyro sample (with its torque sample)')
    if res is not None:
        err = (np.linalg.norm(res.inertia - sim.inertia) / np.linalg.norm(sim.inertia)
               if res.inertia is not None else float('nan'))
        print(f'final: status {res.status}, relative Frobenius error {err:.3e}')
    if prof is not None:
        pstats.Stats(prof).sort_stats('cumulative').print_stats(25)
    return 0


if __name__ == '__main__':
    sys.exit(main())
