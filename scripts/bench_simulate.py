#!/usr/bin/env python3
"""Benchmark: simulate a 60 s, 200 Hz scene and write it as an MCAP log (target < 2 s).

Usage: ``python scripts/bench_simulate.py [SCENE.yaml] [--repeat N]`` (default: the nominal
scene ``config/scenes/default.yaml``, 5 repeats).  Prints the best and median wall-clock
times of simulate, write and their sum, plus the output size.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.io.mcap_writer import write_simulation  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print one line per figure."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('scene', nargs='?', default=str(ROOT / 'config/scenes/default.yaml'))
    ap.add_argument('--repeat', type=int, default=5)
    args = ap.parse_args(argv)
    scene = load_scene(args.scene)
    sim_t, write_t, total_t = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'bench.mcap'
        for _ in range(max(1, args.repeat)):
            t0 = time.perf_counter()
            result = simulate(scene)
            t1 = time.perf_counter()
            write_simulation(out, result, overwrite=True)
            t2 = time.perf_counter()
            sim_t.append(t1 - t0)
            write_t.append(t2 - t1)
            total_t.append(t2 - t0)
        size = out.stat().st_size
    n_msgs = result.t_gyro.size + result.t_torque.size
    print(f'scene {scene.name!r}: {scene.duration:g} s, gyro {scene.gyro.rate:g} Hz, '
          f'torque {scene.torque_sensor.rate:g} Hz, {n_msgs} messages, {size / 1024:.0f} KiB')
    for label, vals in (('simulate', sim_t), ('write', write_t), ('simulate+write', total_t)):
        print(f'{label:15s} best {min(vals):.3f} s   median {statistics.median(vals):.3f} s')
    verdict = 'PASS' if min(total_t) < 2.0 else 'FAIL'
    print(f'target simulate+write < 2 s: {verdict}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
