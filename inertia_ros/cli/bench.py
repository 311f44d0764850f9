"""``python -m inertia_ros bench [KIND ...]``: every benchmark of the package, one home.

Without a KIND, the accuracy suite: every estimator setting on seeded simulations of the
standard scenes, the Cramer-Rao bound, the stability map and the start-up times; it writes
``speed_vs_accuracy.png``, ``stability_map.png``, ``BENCHMARKS.md`` and ``bench_results.json``
into ``--out`` (:mod:`inertia_ros.bench.run`).  Its wall time is measured and written into
BENCHMARKS.md ("Wall time of this bench").  The Pinocchio peer baseline needs the optional
``requirements-bench.txt``; without it that point is skipped with a note.

KIND runs one focused benchmark and prints its figures:

``startup``      the command line's start-up as whole processes (:mod:`~inertia_ros.bench.startup`)
``estimators``   batch speed on a 1M-sample record, recursive cost, accuracy per method
``recursive``    the recursive estimator as the node drives it (10 ms blocks, 10 Hz estimates)
``offline``      read/decode/estimate of a long MCAP log against mcap, mcap_ros2, rosbags
``node``         the estimator node as a process fed at 1 kHz + 1 kHz (needs ROS 2)
``simulate``     simulate + write a 60 s, 200 Hz scene (target < 2 s)
``honesty``      calibration of sigma and status on an independent simulator, every path
``tracking``     the Kalman tracker against a forgetting RLS on a payload step and a drift

This module imports nothing heavy: the benchmark modules are imported when they run.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import math
import sys
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError, bounded

__all__ = ['add_parser', 'run']

_SEED = bounded(0, math.inf, '', integer=True)
_RATE = bounded(1.0, 20_000.0, 'Hz')
_REPEAT = bounded(1, 100, 'runs', integer=True)


def _add_suite_options(p: argparse.ArgumentParser) -> None:
    """The options of the accuracy suite (``bench`` without a KIND)."""
    p.add_argument('--quick', action='store_true',
                   help='few runs and a coarse grid (a smoke test of the pipeline)')
    p.add_argument('--out', default='docs', metavar='DIR',
                   help='output directory (default: docs)')
    p.add_argument('--scenes', default=None, metavar='DIR',
                   help='directory of the standard scene files (default: the repository\'s '
                        'config/scenes)')
    p.add_argument('--no-progress', action='store_true', help='never draw the progress bar')


def _add_kinds(kinds: Any) -> None:
    """The focused benchmarks, one sub-parser each."""
    k = kinds.add_parser('startup', help='start-up time of the command line and the node')
    k.add_argument('--repeat', type=_REPEAT, default=5, help='runs per case, 1-100 (5)')
    k = kinds.add_parser('estimators', help='batch speed, recursive cost, accuracy per method')
    k.add_argument('--quick', action='store_true', help='a 500 s record instead of 5000 s')
    k.add_argument('--seeds', type=bounded(1, 1000, 'records', integer=True), default=10,
                   help='records per method in the accuracy table, 1-1000 (10)')
    k = kinds.add_parser('recursive', help='the recursive estimator as the node drives it')
    k.add_argument('--rate', type=_RATE, default=1000.0, help='Hz per stream, 1-20000 (1000)')
    k.add_argument('--duration', type=bounded(1.0, 3600.0, 's'), default=60.0,
                   help='record length, 1-3600 s (60)')
    k.add_argument('--seed', type=_SEED, default=1, help='simulation seed (1)')
    k.add_argument('--profile', action='store_true', help='cProfile the estimate() calls')
    k = kinds.add_parser('offline', help='read/decode/estimate a long log vs mcap, mcap_ros2')
    k.add_argument('--minutes', type=bounded(0.5, 600.0, 'min'), default=60.0,
                   help='log length, 0.5-600 min (60)')
    k.add_argument('--compression', choices=('zstd', 'lz4', 'none'), default='zstd')
    k.add_argument('--skip-slow', action='store_true', help='skip the mcap_ros2 decode')
    k.add_argument('--repeat', type=_REPEAT, default=1,
                   help='runs per stage, the fastest reported, 1-100 (1)')
    k.add_argument('--json', type=Path, metavar='FILE', help='also write the results here')
    k.add_argument('--blas-threads', type=bounded(1, 256, 'threads', integer=True),
                   default=None, help='OPENBLAS/OMP_NUM_THREADS of the stages (inherited)')
    k.add_argument('--whole', action='store_true',
                   help='time "estimate LOG --format json" as whole processes on the log '
                        'uncompressed and zstd-chunked (768 KiB), with its phases and the '
                        'mcap_ros2 and rosbags readers (median of --repeat runs)')
    k.add_argument('--peer-repeat', type=_REPEAT, default=5,
                   help='--whole: runs per peer reader, 1-100 (5)')
    k.add_argument('--md', type=Path, metavar='FILE.md',
                   help='--whole: also write the BENCHMARKS.md section here')
    k = kinds.add_parser('node', help='the estimator node fed at 1 kHz + 1 kHz (ROS 2)')
    k.add_argument('--rate', type=_RATE, default=1000.0, help='gyro Hz, 1-20000 (1000)')
    k.add_argument('--torque-rate', type=_RATE, default=None,
                   help='torque Hz, 1-20000 (default: --rate)')
    k.add_argument('--duration', type=bounded(1.0, 3600.0, 's'), default=60.0,
                   help='streamed time, 1-3600 s (60)')
    k.add_argument('--publish-rate', type=bounded(0.1, 1000.0, 'Hz'), default=10.0,
                   help='the estimator\'s publish_rate, 0.1-1000 Hz (10)')
    k.add_argument('--method', default='recursive', help='the estimator\'s method parameter')
    k.add_argument('--seed', type=_SEED, default=1, help='simulation seed (1)')
    k = kinds.add_parser('simulate', help='simulate + write a scene (target < 2 s)')
    k.add_argument('scene', nargs='?', type=Path, default=None, metavar='SCENE.yaml',
                   help='scene file (default: config/scenes/default.yaml)')
    k.add_argument('--repeat', type=_REPEAT, default=5, help='runs, 1-100 (5)')
    k = kinds.add_parser('honesty', help='calibration of sigma and status on an independent '
                                         'simulator, over the API, CLI and node paths')
    k.add_argument('--seeds', type=bounded(1, 1000, 'records', integer=True), default=20,
                   help='records per case, 1-1000 (20)')
    k.add_argument('--cases', default=None, help='comma-separated case names (default all)')
    k.add_argument('--paths', default='api,cli,node', help='comma-separated: api, cli, node')
    k.add_argument('--json', type=Path, metavar='FILE', help='also write the outcomes here')
    k = kinds.add_parser('tracking', help='the Kalman tracker against a forgetting RLS of the '
                                          'same memory on a payload step and a drift')
    k.add_argument('--seeds', type=bounded(1, 1000, 'records', integer=True), default=10,
                   help='records per scene, 1-1000 (10)')
    k.add_argument('--memory', type=bounded(0.5, 3600.0, 's'), default=10.0,
                   help='memory time constant of both estimators, 0.5-3600 s (10)')


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register the ``bench`` sub-command on ``sub`` (an argparse subparsers object)."""
    p = sub.add_parser(
        'bench', help='benchmarks: accuracy suite (default), start-up, speed, node, I/O',
        description='Without KIND: run every estimator setting on seeded simulations of the '
                    'standard scenes and write the speed-vs-accuracy chart, the stability '
                    'map and BENCHMARKS.md (its measured wall time is stated there). With '
                    'KIND: run one focused benchmark and print its figures.')
    _add_suite_options(p)
    _add_kinds(p.add_subparsers(dest='kind', metavar='KIND', title='focused benchmarks'))
    p.set_defaults(func=run)
    return p


def _suite(args: argparse.Namespace) -> int:
    """The accuracy suite; an unusable output or scene directory raises UserError."""
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


#: KIND -> (module under inertia_ros.bench, the namespace attributes its run() takes).
_KINDS: dict[str, tuple[str, dict[str, str]]] = {
    'startup': ('startup', {'repeat': 'repeat'}),
    'estimators': ('estimators', {'quick': 'quick', 'seeds': 'seeds'}),
    'recursive': ('recursive', {'rate': 'rate', 'duration': 'duration', 'seed': 'seed',
                                'profile': 'profile'}),
    'offline': ('offline', {'minutes': 'minutes', 'compression': 'compression',
                            'skip_slow': 'skip_slow', 'repeat': 'repeat', 'json': 'json_path',
                            'blas_threads': 'blas_threads', 'whole': 'whole',
                            'peer_repeat': 'peer_repeat', 'md': 'md_path'}),
    'node': ('node', {'rate': 'rate', 'duration': 'duration', 'publish_rate': 'publish_rate',
                      'method': 'method', 'seed': 'seed', 'torque_rate': 'torque_rate'}),
    'simulate': ('simulate', {'scene': 'scene_path', 'repeat': 'repeat'}),
    'tracking': ('tracking', {'seeds': 'seeds', 'memory': 'memory'}),
}


def _honesty(args: argparse.Namespace) -> int:
    """``bench honesty``: unknown case or path names are one line, not a KeyError."""
    from inertia_ros.bench import honesty

    cases = args.cases.split(',') if args.cases else list(honesty.CASES)
    bad = [c for c in cases if c not in honesty.CASES]
    if bad:
        raise UserError(f'--cases: unknown {", ".join(bad)}; known: '
                        f'{", ".join(honesty.CASES)}')
    bad = [p for p in args.paths.split(',') if p not in ('api', 'cli', 'node')]
    if bad:
        raise UserError(f'--paths: unknown {", ".join(bad)}; known: api, cli, node')
    argv = ['--seeds', str(args.seeds), '--cases', ','.join(cases), '--paths', args.paths]
    return honesty.main(argv + (['--json', str(args.json)] if args.json else []))


def run(args: argparse.Namespace) -> int:
    """Run the suite, or the focused benchmark named by KIND; return the exit status."""
    if args.kind is None:
        return _suite(args)
    if args.kind == 'honesty':
        return _honesty(args)
    module, params = _KINDS[args.kind]
    if args.kind == 'node' and importlib.util.find_spec('rclpy') is None:
        raise UserError('bench node needs ROS 2: rclpy is not importable (source a ROS 2 '
                        'Jazzy environment or install the rclpy wheels)')
    if args.kind == 'simulate' and args.scene is not None and not args.scene.is_file():
        raise UserError(f'{args.scene}: no such scene file')
    bench = importlib.import_module(f'inertia_ros.bench.{module}')
    return int(bench.run(**{kw: getattr(args, attr) for attr, kw in params.items()}) or 0)
