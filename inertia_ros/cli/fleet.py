"""``python -m inertia_ros fleet PATH... --out FILE``: estimate every log of a fleet on Dask.

Every log under the PATHs (``.mcap`` files, rosbag2 directories, directories searched
recursively, fsspec URLs; :mod:`inertia_ros.fleet.discover`) is estimated with the same
``estimate`` options, one Dask task per log, and becomes one row of FILE (``.parquet`` or
``.csv``; :mod:`inertia_ros.fleet.table`).  A log that cannot be used is a row with its error,
never the end of the run.  Re-runs are incremental: a row whose log is unchanged (same path,
size and modification time) and that was made with the same options is kept.  Ctrl-C stops
the run and writes the rows finished so far (exit 130).  Exit 0 otherwise, with a summary
line on stdout, whatever the logs' statuses.

The ``estimate`` options (``--model``, ``--method``, ...) are copied from the ``estimate``
command itself, so the two always accept the same ones.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError

__all__ = ['add_parser', 'estimate_flags', 'run']

#: ``estimate`` options that the fleet sets itself (per-log output), not passed through.
_OWN = {'path', 'format', 'output', 'plot', 'no_progress', 'help'}
#: Seconds between checkpoints of the table during a long run.
CHECKPOINT_S = 60.0


def _estimate_actions() -> list[argparse.Action]:
    """The pass-through options of the ``estimate`` sub-parser."""
    from inertia_ros.cli import estimate

    parser = argparse.ArgumentParser(add_help=False)
    sub = parser.add_subparsers()
    estimate.add_parser(sub)
    est = sub.choices['estimate']
    return [a for a in est._actions if a.dest not in _OWN and a.option_strings]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``fleet`` sub-command."""
    p = sub.add_parser(
        'fleet', help='estimate every log of a fleet (many files/directories) on Dask',
        description='Estimate every log under PATH... (.mcap files, rosbag2 directories, '
                    'directories searched recursively) with the same options, on a local '
                    'Dask cluster or an existing one, into one table (one row per log). '
                    'Re-runs only estimate new or changed logs.')
    p.add_argument('paths', nargs='+', metavar='PATH',
                   help='.mcap file, rosbag2 directory, directory to search, or fsspec URL')
    p.add_argument('--out', required=True, type=Path, metavar='FILE',
                   help='table of results, .parquet or .csv (rows of unchanged logs already '
                        'in it are kept)')
    where = p.add_mutually_exclusive_group()
    where.add_argument('--workers', type=int, metavar='N',
                       help='local cluster of N single-threaded worker processes (default: '
                            'the number of CPU cores)')
    where.add_argument('--scheduler', metavar='ADDR',
                       help='run on an existing Dask cluster, e.g. tcp://HOST:8786 (start it '
                            'with `dask scheduler` and `dask worker ADDR --nthreads 1`)')
    p.add_argument('--vehicle-from', default='dir', metavar='dir|metadata:KEY',
                   help='the vehicle of a log: its parent directory\'s name (dir, default) or '
                        'the value of KEY in its MCAP metadata records or rosbag2 '
                        'custom_data')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='also write a trend plot per vehicle, the outliers and the status '
                        'counts to DIR (PNG + fleet_report.md)')
    p.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')
    group = p.add_argument_group('estimate options (the same for every log)')
    for a in _estimate_actions():
        kwargs: dict[str, Any] = {'dest': a.dest, 'default': a.default, 'help': a.help}
        if isinstance(a, argparse._StoreTrueAction):
            kwargs['action'] = 'store_true'
        else:
            kwargs.update({'type': a.type, 'choices': a.choices, 'metavar': a.metavar})
        group.add_argument(*a.option_strings, **kwargs)
    p.set_defaults(func=run)


def estimate_flags(args: argparse.Namespace) -> list[str]:
    """The ``estimate`` options of ``args`` that differ from their defaults, as argv."""
    flags: list[str] = []
    for a in _estimate_actions():
        v = getattr(args, a.dest, a.default)
        if v == a.default:
            continue
        opt = max(a.option_strings, key=len)
        flags += [opt] if isinstance(a, argparse._StoreTrueAction) else [opt, str(v)]
    return flags


class _Bar:
    """A one-line progress bar over logs on stderr (only when stderr is a terminal)."""

    def __init__(self, total: int, enabled: bool) -> None:
        from inertia_ros.progress import progress_bar

        self.total, self.enabled = total, enabled and total > 0
        self.done, self.errors = 0, 0
        self._bar = progress_bar(max(total, 1), 'logs', enabled=self.enabled, unit='log')

    def __call__(self, row: dict[str, Any]) -> None:
        self.done += 1
        self.errors += row.get('status') in ('error', 'failed')
        self._bar.set_postfix_str(f'{self.errors} errors', refresh=False)
        self._bar.update(1)

    def close(self) -> None:
        self._bar.close()


def _order(row: dict[str, Any]) -> tuple[str, int, str]:
    t = row.get('log_start_ns')
    return (row.get('vehicle') or '', t if t is not None else 2 ** 63 - 1, row['path'])


def _check_options(args: argparse.Namespace) -> None:
    """Refuse unusable options before any log is touched (UserError, one line)."""
    from inertia_ros.fleet.table import TableError, table_format

    if args.workers is not None and args.workers < 1:
        raise UserError(f'--workers: must be >= 1, got {args.workers}')
    rule = args.vehicle_from
    if rule != 'dir' and not (rule.startswith('metadata:') and len(rule) > len('metadata:')):
        raise UserError(f'--vehicle-from: expected dir or metadata:KEY, got {rule!r}')
    if getattr(args, 'model', None) == 'axisymmetric' \
            and getattr(args, 'symmetry_axis', None) is None:
        raise UserError('--model axisymmetric needs --symmetry-axis x|y|z')
    out: Path = args.out
    try:
        table_format(out)
    except TableError as exc:
        raise UserError(f'--out {exc}') from None
    if out.is_dir():
        raise UserError(f'--out {out}: is a directory; give a .parquet or .csv file name')
    if not out.parent.is_dir():
        raise UserError(f'--out {out}: directory {out.parent} does not exist')


def _unchanged(old: list[dict[str, Any]], found: dict[str, Any],
               signature: str) -> dict[str, dict[str, Any]]:
    """Rows of the existing table that need no new run, by path."""
    from inertia_ros.fleet.run import FAILED

    kept: dict[str, dict[str, Any]] = {}
    for row in old:
        ref = found.get(row['path'])
        # another PATH's log is left as it is; a changed log, other options or a lost task
        # runs again
        if ref is None or ((row['size'], row['mtime_ns'], row['options'])
                           == (ref.size, ref.mtime_ns, signature)
                           and row['status'] != FAILED):
            kept[row['path']] = row
    return kept


def _write_report(rows: list[dict[str, Any]], report: Path) -> None:
    """Write the fleet report next to ``report`` and name it on stderr."""
    from inertia_ros.fleet.report import write_report

    try:
        md = write_report(rows, report)
    except OSError as exc:
        raise UserError(f'--report {report}: {exc.strerror or exc}') from None
    print(f'report: {md}', file=sys.stderr)


def _summary(rows: list[dict[str, Any]], refs: list[Any], found: dict[str, Any],
             todo: list[Any], new_rows: list[dict[str, Any]], workers: int, out: Path,
             t0: float) -> str:
    """The one-line summary printed at the end."""
    counts = Counter(r['status'] for r in rows if r['path'] in found)
    ran = f'{len(new_rows)} estimated' + (
        f' on {workers} worker{"s" if workers != 1 else ""}' if todo else '')
    return (f'fleet: {len(refs)} logs ({ran}, {len(refs) - len(todo)} unchanged) in '
               f'{time.perf_counter() - t0:.1f} s: '
               + ', '.join(f'{n} {s}' for s, n in sorted(counts.items(),
                                                         key=lambda x: (-x[1], x[0])))
               + f' -> {out}')


def run(args: argparse.Namespace) -> int:
    """Run the command; return the exit status."""
    from inertia_ros.fleet.discover import DiscoveryError, discover
    from inertia_ros.fleet.run import options_signature
    from inertia_ros.fleet.table import TableError, read_rows, write_rows

    t0 = time.perf_counter()
    _check_options(args)
    rule = args.vehicle_from
    out: Path = args.out
    try:
        refs = discover(args.paths)
    except DiscoveryError as exc:
        raise UserError(str(exc)) from None
    if not refs:
        raise UserError(f'no logs (.mcap files or rosbag2 directories) under '
                        f'{", ".join(args.paths)}')
    flags = estimate_flags(args)
    signature = options_signature(flags, rule)
    try:
        old = read_rows(out) if out.exists() else []
    except TableError as exc:
        raise UserError(f'--out {exc}') from None
    found = {r.path: r for r in refs}
    kept = _unchanged(old, found, signature)
    todo = [r for r in refs if r.path not in kept]
    new_rows: list[dict[str, Any]] = []
    interrupted = False
    workers = 0

    def table() -> list[dict[str, Any]]:
        return sorted([*kept.values(), *new_rows], key=_order)

    if todo:
        from inertia_ros.fleet.run import ClusterError, n_workers, open_client, run_logs

        bar = _Bar(len(todo), sys.stderr.isatty() and not args.no_progress)
        last = [time.monotonic()]

        def on_row(row: dict[str, Any]) -> None:
            new_rows.append(row)
            bar(row)
            if time.monotonic() - last[0] > CHECKPOINT_S:
                last[0] = time.monotonic()
                write_rows(out, table())

        try:
            with open_client(args.workers, args.scheduler) as client:
                workers = n_workers(client)
                _, interrupted = run_logs(client, todo, flags, rule, on_row=on_row)
        except ClusterError as exc:
            raise UserError(str(exc)) from None
        except TableError as exc:
            raise UserError(f'--out {exc}') from None
        except KeyboardInterrupt:  # while starting or stopping the cluster
            interrupted = True
        finally:
            bar.close()
    interrupted = interrupted and len(new_rows) < len(todo)  # not if only closing was cut
    rows = table()
    if todo or len(rows) != len(old):
        try:
            write_rows(out, rows)
        except TableError as exc:
            raise UserError(f'--out {exc}') from None
    if args.report is not None and not interrupted:
        _write_report(rows, args.report)
    summary = _summary(rows, refs, found, todo, new_rows, workers, out, t0)
    if interrupted:
        print(f'inertia_ros fleet: interrupted: {len(new_rows)} of {len(todo)} logs done, '
              f'their rows written to {out}; run the same command again to continue',
              file=sys.stderr)
        print(summary)
        return 130
    print(summary)
    return 0
