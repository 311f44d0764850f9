"""``bench simulate``: simulate a scene and write it as an MCAP log (target < 2 s for 60 s at
200 Hz).

Prints the best and median wall-clock times of the simulation, the write and their sum over
``repeat`` runs, the output size, and whether the best sum meets the target.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from inertia_ros.core.simulation import simulate
from inertia_ros.io.mcap_writer import write_simulation
from inertia_ros.io.scene_file import load_scene

from .common import SCENE_DIR

__all__ = ['TARGET_SECONDS', 'run']

#: Target for simulate + write of the nominal 60 s scene [s].
TARGET_SECONDS = 2.0


def run(scene_path: Path | None = None, repeat: int = 5) -> int:
    """Run the benchmark and print one line per figure; return the exit status (0).

    Parameters
    ----------
    scene_path : Path, optional
        Scene file (default: ``config/scenes/default.yaml``).
    repeat : int
        Runs; best and median are reported.
    """
    scene = load_scene(scene_path or SCENE_DIR / 'default.yaml')
    sim_t, write_t, total_t = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / 'bench.mcap'
        for _ in range(max(1, repeat)):
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
    verdict = 'PASS' if min(total_t) < TARGET_SECONDS else 'FAIL'
    print(f'target simulate+write < {TARGET_SECONDS:g} s: {verdict}')
    return 0
