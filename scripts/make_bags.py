#!/usr/bin/env python3
"""Regenerate the sample logs in ``bags/`` (``make bags``).

For each sample scene, copy ``config/scenes/NAME.yaml`` to ``bags/NAME.yaml`` and write
``bags/NAME.mcap`` from it with its own seed (the same as
``python -m inertia_ros simulate bags/NAME.yaml -o bags/NAME.mcap --force``).  Every log must
stay under 2 MB.

Usage: ``python scripts/make_bags.py [NAME ...]`` (default: all sample scenes).
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.io.mcap_writer import write_simulation  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402

#: The sample logs and what each one shows.
BAGS = {
    'default': 'nominal body and three-axis multisine: the full tensor is identifiable',
    'torque_free': 'torque-free tumble: only ratios and principal axes are observable',
    'single_axis': 'slews about z only: ixx, iyy, ixy are not identifiable',
    'disturbance': 'constant unmeasured disturbance torque: needs the torque-bias model',
    'wheels': 'three reaction wheels, JointState speeds on /joint_states, no other torque '
              '(estimate with --wheels bags/wheels_wheels.yaml)',
    'quadrotor': 'quadrotor (X) with rotor speeds as JointState on /joint_states, no torque '
                 'topic of its own (zeros) (estimate with --rotors bags/quadrotor_rotors.yaml)',
    'gyro_bias': 'constant gyro bias, wide rate swings (estimate with --nuisance auto)',
    'torque_delay': 'torque stamps 15 ms late (estimate with --nuisance auto)',
    'damping': 'aerodynamic damping -D w, unmeasured (estimate with --nuisance auto)',
    'gyro_lowpass': 'gyro behind a 15 ms first-order filter, quantised (--nuisance auto)',
}
MAX_BYTES = 2 * 1024 * 1024


def make(name: str, out_dir: Path = ROOT / 'bags') -> Path:
    """Copy the scene beside the log and (re)write ``out_dir/NAME.mcap``; return its path."""
    src = ROOT / 'config' / 'scenes' / f'{name}.yaml'
    out_dir.mkdir(parents=True, exist_ok=True)
    scene_copy = out_dir / f'{name}.yaml'
    shutil.copyfile(src, scene_copy)
    wheels_file = ROOT / 'config' / 'wheels' / f'{name}.yaml'
    if wheels_file.is_file():
        shutil.copyfile(wheels_file, out_dir / f'{name}_wheels.yaml')
    rotors_file = ROOT / 'config' / 'rotors' / f'{name}.yaml'
    if rotors_file.is_file():
        shutil.copyfile(rotors_file, out_dir / f'{name}_rotors.yaml')
    result = simulate(load_scene(scene_copy))
    path = out_dir / f'{name}.mcap'
    counts = write_simulation(path, result, overwrite=True)
    size = path.stat().st_size
    if size >= MAX_BYTES:
        raise SystemExit(f'{path}: {size} bytes, over the 2 MB limit for sample logs')
    print(f'{path.relative_to(ROOT)}: {size / 1024:.0f} KiB, '
          + ', '.join(f'{k} {v}' for k, v in counts.items()))
    return path


def main(argv: list[str]) -> int:
    """Regenerate the named sample logs (all by default)."""
    names = argv or list(BAGS)
    unknown = [n for n in names if n not in BAGS]
    if unknown:
        print(f'make_bags: unknown sample {unknown[0]!r} (known: {", ".join(BAGS)})',
              file=sys.stderr)
        return 2
    for name in names:
        make(name)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
