"""Time ``attitude.attitude_integral`` on an hour of 200 Hz gyro (issue 27, design step 1).

    python scripts/measure/attitude_speed.py [--samples 720000] [--repeat 7]

A wandering rate (0.6 rad/s mean, random walk), written with ``out=`` into the nine columns
of a 22-wide array as the integral equations do (the array touched once before timing);
prints the best and median of ``--repeat`` calls [s] and ``|C|`` max.

Measured (2026-11-28, the loaded 2-core machine, best of 7): the stacked (N, 3, 3)
implementation of fc1dd39 0.29-0.44 s; the flat-plane scan 0.086-0.099 s (same values to
9.4e-14 relative, rotations to 1.3e-13).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from inertia_ros.core.estimation.attitude import attitude_integral


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--samples', type=int, default=720_000)
    ap.add_argument('--repeat', type=int, default=7)
    a = ap.parse_args()
    n = a.samples
    t = np.arange(n) * 0.005
    rng = np.random.default_rng(0)
    w = np.cumsum(rng.normal(size=(n, 3)) * 0.01, axis=0) + np.array([0.5, -0.3, 0.2])
    V = np.ones((n, 22))
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        attitude_integral(t, w, out=V[:, 13:])
        times.append(time.perf_counter() - t0)
    print(f'{n} samples: best {min(times):.3f} s, median {float(np.median(times)):.3f} s '
          f'(|C| max {np.abs(V[:, 13:]).max():.1f} s)')


if __name__ == '__main__':
    main()
