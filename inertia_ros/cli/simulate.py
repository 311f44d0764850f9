"""``python -m inertia_ros simulate SCENE.yaml -o OUT.mcap [--seed N] [--force]``.

Simulates a scene (``docs/SCENES.md``) and writes the streams a real robot would record as a
rosbag2-compatible MCAP log: ``/imu`` (sensor_msgs/msg/Imu), ``/torque``
(geometry_msgs/msg/WrenchStamped) and the ground truth ``/truth/inertia``
(geometry_msgs/msg/InertiaStamped).  Refuses to overwrite an existing file without ``--force``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError, bounded, path_text_arg

__all__ = ['add_parser', 'run']

#: Largest stamp [ns]: builtin_interfaces/Time holds int32 seconds (2038-01-19T03:14:07Z).
MAX_STAMP_NS = (2**31 - 1) * 10**9


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register the ``simulate`` sub-command on ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        'simulate', help='simulate a scene and write a rosbag2-compatible MCAP log',
        description='Simulate a scene (YAML, see docs/SCENES.md) and write /imu, /torque and '
                    '/truth/inertia to a rosbag2-compatible MCAP file (-o OUT.mcap), or to a '
                    'rosbag2 bag directory as "ros2 bag record -o OUT" writes it (-o OUT, no '
                    '.mcap suffix: OUT/metadata.yaml and OUT/OUT_0.mcap).')
    p.add_argument('scene', metavar='SCENE.yaml', type=path_text_arg, help='scene file')
    p.add_argument('-o', '--output', required=True, metavar='OUT.mcap|OUT', type=path_text_arg,
                   help='output: an .mcap file, or a new rosbag2 bag directory')
    p.add_argument('--seed', type=bounded(0, math.inf, '', integer=True), default=None,
                   help='seed for every random draw (default: the scene\'s seed)')
    p.add_argument('--force', action='store_true',
                   help='overwrite OUT.mcap if it exists (a bag directory is never replaced)')
    p.add_argument('--start-ns', type=bounded(0, MAX_STAMP_NS, 'ns', integer=True),
                   default=None,
                   metavar='NS',
                   help='epoch of t = 0 in integer nanoseconds (default 2024-01-01T00:00Z)')
    p.add_argument('-q', '--quiet', action='store_true', help='print nothing on success')
    p.set_defaults(func=run)
    return p


def _refuse_input_as_output(scene: Path, out: Path) -> None:
    """Refuse an output that is the scene file itself (``--force`` would replace the input)."""
    try:
        same = out.exists() and scene.exists() and out.samefile(scene)
    except OSError:
        same = False
    if same:
        raise UserError(f'{out}: is the scene file given as input; choose another output')


def run(args: argparse.Namespace) -> int:
    """Run the command; bad input raises :class:`~inertia_ros.cli.UserError`."""
    from inertia_ros.core.scene import SceneError
    from inertia_ros.core.simulation import simulate
    from inertia_ros.io.mcap_writer import DEFAULT_START_NS, McapWriterError, write_simulation
    from inertia_ros.io.scene_file import load_scene

    out = Path(args.output)
    bag_dir = out.suffix != '.mcap'
    if bag_dir and out.suffix:
        raise UserError(f'{out}: give an .mcap file, or a bag directory name without a '
                        f'suffix (not {out.suffix!r})')
    if bag_dir and out.exists():
        raise UserError(f'{out} exists (a bag directory is never replaced: remove it or '
                        'choose another name)')
    if out.exists() and not args.force:
        raise UserError(f'{out} exists (use --force to overwrite it)')
    start_ns = DEFAULT_START_NS if args.start_ns is None else args.start_ns
    _refuse_input_as_output(Path(args.scene), out)
    try:
        scene = load_scene(args.scene)
    except SceneError as exc:
        raise UserError(str(exc)) from None
    last_ns = start_ns + math.ceil((scene.duration + scene.imperfections.torque_delay + 1.0) * 1e9)
    if last_ns > MAX_STAMP_NS:
        raise UserError(f'--start-ns {start_ns}: the run would end after 2038-01-19T03:14:07Z, '
                        'past the 32-bit seconds of a ROS time stamp; give an earlier start')
    t0 = time.perf_counter()
    try:
        result = simulate(scene, seed=args.seed)
    except SceneError as exc:      # the integrator's work budget
        raise UserError(f'{args.scene}: {exc}') from None
    t1 = time.perf_counter()
    if min(len(result.t_gyro), len(result.t_torque)) < 2:
        raise UserError(f'{args.scene}: the run keeps {len(result.t_gyro)} gyro and '
                        f'{len(result.t_torque)} torque samples (imperfections.drop_rate '
                        f'{scene.imperfections.drop_rate:g}, rates, duration); keep at least 2')
    try:
        counts = write_simulation(out, result, start_ns=start_ns, overwrite=args.force,
                                  rosbag2_dir=bag_dir)
    except (McapWriterError, FileExistsError, OSError) as exc:
        raise UserError(f'{out}: {exc}') from None
    t2 = time.perf_counter()
    if not args.quiet:
        topics = ', '.join(f'{k} {v}' for k, v in counts.items())
        print(f'wrote {out}: scene {scene.name!r}, seed {result.seed}, {scene.duration:g} s; '
              f'{topics} messages (simulate {t1 - t0:.2f} s, write {t2 - t1:.2f} s)',
              file=sys.stdout)
    return 0
