"""``python -m inertia_ros fleet PATH... --out FILE``: estimate every log of a fleet on Dask.

Every log under the PATHs (``.mcap`` files, rosbag2 directories, directories searched
recursively, fsspec URLs; :mod:`inertia_ros.fleet.discover`) is estimated with the same
``estimate`` options, one Dask task per log, and becomes one row of FILE (``.parquet`` or
``.csv``; :mod:`inertia_ros.fleet.table`).  A log that cannot be used is a row with its error,
never the end of the run (a dangling link, a link loop or a FIFO named ``*.mcap`` too: never
opened).  Re-runs are incremental: a row whose log is unchanged (same path, size and
modification time) and that was made with the same options is kept; only a table this
command wrote is read back, any other file at FILE is refused and left as it is.  Ctrl-C
stops the run, stops the workers and writes the rows finished so far (exit 130, also for a
second Ctrl-C during that clean-up, and for one during the cluster's start-up).  Exit 0
otherwise, with a summary line on stdout, whatever the logs' statuses.

The ``estimate`` options (``--model``, ``--method``, ``--com X Y Z``, ...) are copies of the
``estimate`` command's own argparse actions (nargs, types, choices, metavars, defaults), so the
two always accept the same ones, and they are passed on to each log as typed.  The options
that write a file per log (``--urdf`` and its ``--mass``, ``--com``, ``--link``) are refused
with one line: a fleet has no per-log file names, and its table holds every log's tensor.
"""
from __future__ import annotations

import argparse
import copy
import os
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

from inertia_ros.cli import UserError

__all__ = ['add_parser', 'estimate_flags', 'run']

#: ``estimate`` options that the fleet sets itself (per-log output), not passed through
#: (``force``: estimate's overwrite permission, for outputs a fleet does not write).
_OWN = {'path', 'format', 'output', 'plot', 'no_progress', 'help', 'force'}
#: ``estimate`` options that write one file per log: refused in a fleet (one line).
_PER_LOG_OUTPUTS = ('urdf', 'mass', 'com', 'link')
#: Seconds between checkpoints of the table during a long run.
CHECKPOINT_S = 60.0


def _estimate_parser() -> argparse.ArgumentParser:
    """A throw-away ``estimate`` sub-parser: the source of the pass-through options."""
    from inertia_ros.cli import Parser, estimate

    sub = Parser(add_help=False).add_subparsers()
    estimate.add_parser(sub)
    return sub.choices['estimate']


def _estimate_actions() -> list[argparse.Action]:
    """The pass-through options of the ``estimate`` sub-parser (its own actions)."""
    return [a for a in _estimate_parser()._actions if a.dest not in _OWN and a.option_strings]


def _recording(action: argparse.Action, raw: dict[str, list[str]]) -> Any:
    """``action.type`` that also keeps the words given for the option, as typed.

    The words are passed on to ``estimate`` unchanged (a parsed value, e.g. the tuple of
    ``--nuisance a,b``, need not print back as the option).  A repeated option keeps its
    last occurrence (argparse's rule): with ``nargs=N`` the last N words.
    """
    convert = action.type if callable(action.type) else str
    n = action.nargs if isinstance(action.nargs, int) else 1

    def parse(text: str) -> Any:
        value = convert(text)
        raw[action.dest] = [*raw.get(action.dest, []), text][-n:]
        return value

    parse.__name__ = getattr(convert, '__name__', 'value')  # argparse names it in errors
    return parse


def _add_estimate_options(p: argparse.ArgumentParser) -> None:
    """Copy the ``estimate`` options onto the fleet parser (copies of its actions)."""
    est = _estimate_parser()
    raw: dict[str, list[str]] = {}
    group = p.add_argument_group('estimate options (the same for every log)')
    copies: dict[int, argparse.Action] = {}
    for a in est._actions:
        if a.dest in _OWN or not a.option_strings:
            continue
        c = copy.copy(a)
        if c.nargs != 0:  # takes words (not a flag)
            c.type = _recording(c, raw)
        if c.dest in _PER_LOG_OUTPUTS:
            c.help = argparse.SUPPRESS  # refused in a fleet (_check_options)
        copies[id(a)] = c
        group._add_action(c)
    for mutex in est._mutually_exclusive_groups:  # keep estimate's either/or rules
        m = p.add_mutually_exclusive_group(required=mutex.required)
        m._group_actions += [copies[id(a)] for a in mutex._group_actions if id(a) in copies]
    p.set_defaults(estimate_words=raw)


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
                        'in it are kept; a file this command did not write is refused)')
    where = p.add_mutually_exclusive_group()
    where.add_argument('--workers', type=int, metavar='N',
                       help='local cluster of N single-threaded worker processes (default and '
                            'at most: the number of CPU cores this process may use)')
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
    _add_estimate_options(p)
    p.set_defaults(func=run)


def estimate_flags(args: argparse.Namespace) -> list[str]:
    """The ``estimate`` options of ``args`` that differ from their defaults, as argv.

    Each option's words are those typed (``--com 0 0 0.1``, ``--nuisance a,b``); file names
    (options parsed to a Path) are made absolute, so a worker in another directory finds
    them.
    """
    words: dict[str, list[str]] = getattr(args, 'estimate_words', None) or {}
    flags: list[str] = []
    for a in _estimate_actions():
        v = getattr(args, a.dest, a.default)
        if v == a.default or (isinstance(v, list) and tuple(v) == a.default):
            continue
        opt = max(a.option_strings, key=len)
        if a.nargs == 0:
            flags.append(opt)
            continue
        given = words.get(a.dest) or [str(x) for x in (v if isinstance(v, list) else [v])]
        if isinstance(v, Path):  # a file the workers read
            given = [os.path.abspath(w) for w in given]
        flags += [opt, *given]
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


def _cores() -> int:
    """CPU cores this process may run on (its affinity; the machine's count elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _check_workers(args: argparse.Namespace) -> None:
    """``--workers``: >= 1, and at most one per core (said on stderr when capped)."""
    if args.workers is None:
        return
    if args.workers < 1:
        raise UserError(f'--workers: must be >= 1, got {args.workers}')
    cores = _cores()
    if args.workers > cores:
        print(f'inertia_ros fleet: --workers {args.workers}: {cores} CPU core'
              f'{"s" if cores != 1 else ""} here; starting {cores} single-threaded worker'
              f'{"s" if cores != 1 else ""} (more would only compete for them)',
              file=sys.stderr)
        args.workers = cores


def _check_out(out: Path) -> None:
    """``--out``: a .parquet/.csv name in a writable directory, a regular file if present
    (the directory is tried with a temporary file, removed at once)."""
    import tempfile

    from inertia_ros.fleet.discover import shown
    from inertia_ros.fleet.table import TableError, table_format

    name = shown(str(out))
    try:
        table_format(out)
    except TableError:
        raise UserError(f'--out {name}: unknown table format; name it .parquet or .csv'
                        ) from None
    try:
        if out.is_symlink():
            raise UserError(f'--out {name}: is a symbolic link; give the path of the table '
                            f'itself (a link is never written through)')
        if out.is_dir():
            raise UserError(f'--out {name}: is a directory; give a .parquet or .csv file '
                            f'name')
        if out.exists() and not out.is_file():
            raise UserError(f'--out {name}: exists and is not a regular file; choose '
                            f'another --out')
        if not out.parent.is_dir():
            raise UserError(f'--out {name}: directory {shown(str(out.parent))} does not '
                            f'exist')
        fd, probe = tempfile.mkstemp(prefix=f'.{out.name}.', suffix='.tmp', dir=out.parent)
        os.close(fd)
        os.unlink(probe)
    except (OSError, ValueError) as exc:  # too long a name, permissions, a NUL byte, ...
        raise UserError(f'--out {name}: cannot write there '
                        f'({getattr(exc, "strerror", None) or exc}); choose another --out'
                        ) from None


def _check_report(report: Path | None) -> None:
    """``--report``: the directory is made now (before any log runs), or refused."""
    from inertia_ros.fleet.discover import shown

    if report is None:
        return
    try:
        if report.exists() and not report.is_dir():
            raise UserError(f'--report {shown(str(report))}: exists and is not a directory; '
                            f'give a directory')
        report.mkdir(parents=True, exist_ok=True)
    except (OSError, ValueError) as exc:
        raise UserError(f'--report {shown(str(report))}: cannot make this directory '
                        f'({getattr(exc, "strerror", None) or exc})') from None


def _check_estimate_options(args: argparse.Namespace) -> None:
    """The per-log file outputs are refused; input files must be readable regular files."""
    from inertia_ros.fleet.discover import _file_problem, shown

    for a in _estimate_actions():
        v = getattr(args, a.dest, a.default)
        if v is None or v == a.default or (isinstance(v, list) and tuple(v) == a.default):
            continue
        opt = max(a.option_strings, key=len)
        if a.dest in _PER_LOG_OUTPUTS:
            raise UserError(
                f'{opt}: a fleet writes no file per log (they would all need their own name); '
                f'its table holds every log\'s tensor: for one log\'s URDF run `python -m '
                f'inertia_ros estimate LOG --urdf FILE --mass M`')
        if isinstance(v, Path):  # an input file (--wheels, --rotors)
            _, problem = _file_problem(v)
            if problem is not None:
                raise UserError(f'{opt} {shown(str(v))}: {problem}')


def _check_options(args: argparse.Namespace) -> None:
    """Refuse unusable options before any log is touched (UserError, one line)."""
    from inertia_ros.fleet.cluster import ClusterError, check_scheduler

    _check_workers(args)
    rule = args.vehicle_from
    if rule != 'dir' and not (rule.startswith('metadata:') and len(rule) > len('metadata:')):
        from inertia_ros.fleet.discover import shown

        raise UserError(f'--vehicle-from: expected dir or metadata:KEY, got '
                        f'{shown(repr(rule))}')
    if getattr(args, 'model', None) == 'axisymmetric' \
            and getattr(args, 'symmetry_axis', None) is None:
        raise UserError('--model axisymmetric needs --symmetry-axis x|y|z')
    _check_estimate_options(args)
    from inertia_ros.cli.estimate import check_companions

    check_companions(args)          # --wheel-topic without --wheels, ...
    _check_out(args.out)
    _check_report(args.report)
    if args.scheduler is not None:
        try:
            check_scheduler(args.scheduler)
        except ClusterError as exc:
            raise UserError(str(exc)) from None


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
    from inertia_ros.fleet.discover import shown
    from inertia_ros.fleet.report import write_report

    try:
        md = write_report(rows, report)
    except OSError as exc:
        raise UserError(f'--report {shown(str(report))}: {exc.strerror or exc}') from None
    print(f'report: {shown(str(md), 1000)}', file=sys.stderr)


def _summary(rows: list[dict[str, Any]], refs: list[Any], found: dict[str, Any],
             todo: list[Any], new_rows: list[dict[str, Any]], workers: int, out: str,
             t0: float) -> str:
    """The one-line summary printed at the end."""
    counts = Counter(r['status'] for r in rows if r['path'] in found)
    ran = f'{len(new_rows)} estimated' + (
        f' on {workers} worker{"s" if workers != 1 else ""}' if todo and workers else '')
    return (f'fleet: {len(refs)} logs ({ran}, {len(refs) - len(todo)} unchanged) in '
               f'{time.perf_counter() - t0:.1f} s: '
               + ', '.join(f'{n} {s}' for s, n in sorted(counts.items(),
                                                         key=lambda x: (-x[1], x[0])))
               + f' -> {out}')


def _in_own_process() -> bool:
    """True when this process is the command line (``python -m inertia_ros``,
    ``inertia-ros``), not a program that called :func:`inertia_ros.cli.main`."""
    argv0 = Path(sys.argv[0]) if sys.argv and sys.argv[0] else Path()
    return argv0.name == 'inertia-ros' or argv0.parts[-2:] == ('inertia_ros', '__main__.py')


def _ignore_ctrl_c() -> Any:
    """After a Ctrl-C: further ones are ignored while the rows are written and the process
    exits, so it exits 130 (a second Ctrl-C then ended it by SIGINT, status -2).  Returns
    the previous handler (None off the main thread, where nothing is changed)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, signal.SIG_IGN)


def _estimate_todo(args: argparse.Namespace, todo: list[Any], flags: list[str],
                   new_rows: list[dict[str, Any]], checkpoint: Any) -> tuple[int, bool]:
    """Run the logs of ``todo`` on the cluster, appending their rows to ``new_rows``.

    Returns the number of workers and whether Ctrl-C stopped the run (also during the
    cluster's start-up or shut-down: the workers are stopped either way).
    """
    from inertia_ros.fleet.run import ClusterError, n_workers, open_client, run_logs
    from inertia_ros.fleet.table import TableError

    bar = _Bar(len(todo), sys.stderr.isatty() and not args.no_progress)
    last = [time.monotonic()]
    if _in_own_process():
        # Dask's own log stays quiet to the end of the process (its event loop can report a
        # closed connection with a traceback at INFO while the interpreter exits); a log
        # that cannot be finished is a 'failed' row anyway
        import logging

        logging.getLogger('distributed').setLevel(logging.CRITICAL)
    workers = 0
    interrupted = False

    def on_row(row: dict[str, Any]) -> None:
        new_rows.append(row)
        bar(row)
        if time.monotonic() - last[0] > CHECKPOINT_S:
            last[0] = time.monotonic()
            checkpoint()

    try:
        with open_client(args.workers, args.scheduler) as client:
            workers = n_workers(client)
            _, interrupted = run_logs(client, todo, flags, args.vehicle_from, on_row=on_row)
    except ClusterError as exc:
        raise UserError(str(exc)) from None
    except TableError as exc:
        raise UserError(f'--out {exc}') from None
    except KeyboardInterrupt:  # while starting or stopping the cluster
        interrupted = True
    finally:
        bar.close()
    return workers, interrupted


def run(args: argparse.Namespace) -> int:
    """Run the command; return the exit status."""
    from inertia_ros.fleet.discover import DiscoveryError, discover, display_path, shown
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
                        f'{shown(", ".join(args.paths))}')
    flags = estimate_flags(args)
    signature = options_signature(flags, rule)
    try:
        old = read_rows(out) if out.exists() else []
    except TableError as exc:
        raise UserError(f'--out {shown(str(exc), 400)}') from None
    found = {display_path(r.path): r for r in refs}  # the rows' paths are display paths
    kept = _unchanged(old, found, display_path(signature))
    todo = [r for p, r in found.items() if p not in kept]
    new_rows: list[dict[str, Any]] = []
    interrupted = False
    workers = 0

    def table() -> list[dict[str, Any]]:
        return sorted([*kept.values(), *new_rows], key=_order)

    if todo:
        workers, interrupted = _estimate_todo(args, todo, flags, new_rows,
                                              lambda: write_rows(out, table()))
    previous = _ignore_ctrl_c() if interrupted else None
    try:
        return _finish(args, rows=table(), old=old, refs=refs, found=found, todo=todo,
                       new_rows=new_rows, workers=workers, t0=t0,
                       interrupted=interrupted and len(new_rows) < len(todo))
    finally:
        if previous is not None and not _in_own_process():  # a caller's handler is its own
            import signal

            signal.signal(signal.SIGINT, previous)


def _finish(args: argparse.Namespace, *, rows: list[dict[str, Any]],
            old: list[dict[str, Any]], refs: list[Any], found: dict[str, Any],
            todo: list[Any], new_rows: list[dict[str, Any]], workers: int, t0: float,
            interrupted: bool) -> int:
    """Write the table (and the report), print the summary; return the exit status.

    ``interrupted``: Ctrl-C stopped the run before every log of ``todo`` had a row (not if
    only the cluster's shut-down was cut short).
    """
    from inertia_ros.fleet.discover import display_path, shown
    from inertia_ros.fleet.table import TableError, write_rows

    out: Path = args.out
    if todo or len(rows) != len(old):
        try:
            write_rows(out, rows)
        except TableError as exc:
            raise UserError(f'--out {shown(str(exc), 400)}') from None
    if args.report is not None and not interrupted:
        _write_report(rows, args.report)
    summary = _summary(rows, refs, found, todo, new_rows, workers, display_path(str(out)), t0)
    if interrupted:
        print(f'inertia_ros fleet: interrupted: {len(new_rows)} of {len(todo)} logs done, '
              f'their rows written to {display_path(str(out))}; run the same command again '
              f'to continue', file=sys.stderr)
        print(summary)
        return 130
    print(summary)
    return 0
