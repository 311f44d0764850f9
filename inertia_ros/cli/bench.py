"""``python -m inertia_ros bench [--quick] [--out docs/]``: speed, accuracy, bound, stability.

Writes ``speed_vs_accuracy.png``, ``stability_map.png``, ``BENCHMARKS.md`` and
``bench_results.json`` into the output directory (see :mod:`inertia_ros.bench`).  A progress
bar is drawn on stderr when it is a terminal.  The Pinocchio peer baseline needs the optional
``requirements-bench.txt``; without it that point is skipped with a note.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError

__all__ = ['add_parser', 'run']


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register the ``bench`` sub-command on ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        'bench', help='speed/accuracy benchmark, Cramer-Rao efficiency, stability map',
        description='Run every estimator setting on seeded simulations of the standard '
                    'scenes and write the speed-vs-accuracy chart, the stability map and '
                    'BENCHMARKS.md (about 10 minutes; --quick: about one).')
    p.add_argument('--quick', action='store_true',
                   help='few runs and a coarse grid (a smoke test of the pipeline)')
    p.add_argument('--out', default='docs', metavar='DIR',
                   help='output directory (default: docs)')
    p.add_argument('--scenes', default=None, metavar='DIR',
                   help='directory of the standard scene files (default: the repository\'s '
                        'config/scenes)')
    p.add_argument('--no-progress', action='store_true', help='never draw the progress bar')
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Run the command; an unusable output directory raises :class:`UserError`."""
    from inertia_ros.bench.run import FULL, QUICK, SCENE_DIR, run_bench

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f'--out: {out} exists and is not a directory')
    config = QUICK if args.quick else FULL
    scenes = Path(args.scenes) if args.scenes else SCENE_DIR
    missing = [f for _, f in config.scenes if not (scenes / f).is_file()]
    if missing:
        raise UserError(f'--scenes: {scenes} lacks {", ".join(missing)} (give the '
                        f'config/scenes directory of the source tree)')
    head = run_bench(out, config, scene_dir=scenes,
                     show_progress=False if args.no_progress else None)
    ratio = head.get('default_mse_over_crlb_nominal_raw')
    print(f'wrote {out}/speed_vs_accuracy.png, {out}/stability_map.png, {out}/BENCHMARKS.md '
          f'in {head["seconds"]["total"]:.0f} s', file=sys.stderr)
    if ratio is not None:
        print(f'default method on the nominal scene: MSE = {ratio:.2f} x CRLB; silent failures '
              f'on the grid: {head["default_silent_failures_on_grid"]}', file=sys.stderr)
    return 0
