"""Estimate many logs on Dask: the per-log task, the client, the submission loop.

Each Dask task runs the ``estimate`` command in-process on one log through its public
contract (``inertia_ros.cli.main(['estimate', PATH, '--format', 'json', ...])``: exit 0 and a
JSON report, or exit 2 and one error line on stderr) and turns the outcome into one table row
(:func:`row_from_report`).  The worker reads the log itself; only the path goes to it and
only the row (a few kB) comes back.

A worker runs one log at a time: ``estimate`` is called with ``sys.stdout``/``sys.stderr``
redirected, which is process-wide, so calls inside one process are serialised by a lock.
Run workers with one thread each and as many processes as cores (``dask worker ADDR
--nworkers N --nthreads 1``; the local cluster does this by itself).

Statuses of a row: the estimate's own (``ok``, ``model_mismatch``, ...; the log gave a
report), ``error`` (the log is unusable: ``estimate`` refused it, the row carries its error
line), ``failed`` (the infrastructure failed: a worker died or was lost; such rows are run
again by the next invocation).
"""
from __future__ import annotations

import contextlib
import functools
import io
import json
import math
import os
import shlex
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from inertia_ros.core.tensor import THETA_COLS, THETA_NAMES, THETA_ROWS
from inertia_ros.fleet.cluster import ClusterError, n_workers, open_client
from inertia_ros.fleet.discover import (
    BAG_METADATA,
    MCAP_SUFFIX,
    LogRef,
    display_path,
    is_url,
    shown,
    vehicle_from_dir,
)

__all__ = ['ERROR', 'FAILED', 'ClusterError', 'estimate_log', 'log_info', 'n_workers',
           'open_client', 'options_signature', 'row_from_report', 'run_logs']

#: Status of a row whose log ``estimate`` could not use (exit 2) or crashed on.
ERROR = 'error'
#: Status of a row whose task was lost by the infrastructure; re-run next time.
FAILED = 'failed'
#: (row, column) of each tensor element of THETA_NAMES (DESIGN.md's parameter order).
_THETA_IDX = tuple(zip(THETA_ROWS.tolist(), THETA_COLS.tolist(), strict=True))
#: Serialises in-process ``estimate`` calls (they redirect the process-wide stdout/stderr).
_LOCK = threading.Lock()
_ERROR_PREFIX = 'inertia_ros estimate: error: '
#: The local cluster's workers are processes (True: the logs run in parallel).  False puts
#: them in threads of this process, where the lock above runs one log at a time: only for
#: tests, where it saves the workers' start-up (about 5 s on a loaded 2-core machine).
LOCAL_PROCESSES = True


def options_signature(flags: Sequence[str], vehicle_from: str) -> str:
    """The options a row was made with, as one string stored in the row.

    A row is reused by a re-run only when this string is unchanged.
    """
    return shlex.join([*flags, '--vehicle-from', vehicle_from])


# --------------------------------------------------------------------------------------------
# Facts the report does not carry: metadata (for the vehicle) and the start of a failed log


def _mcap_files(path: Path) -> list[Path]:
    if path.is_dir():
        return sorted(path.glob('*' + MCAP_SUFFIX))
    return [path]


def log_info(path: str | os.PathLike[str]) -> tuple[int | None, dict[str, str]]:
    """Start time and metadata of a local log, best effort (never raises).

    Parameters
    ----------
    path : str or PathLike
        A ``.mcap`` file or a rosbag2 directory.

    Returns
    -------
    start_ns : int or None
        Earliest message log time of the files' summaries [ns], None if unknown.
    metadata : dict of str to str
        The key/value pairs of every MCAP metadata record (first value wins) and of a rosbag2
        ``metadata.yaml``'s ``custom_data``.
    """
    p = Path(path)
    start: int | None = None
    meta: dict[str, str] = {}
    try:
        from mcap.reader import make_reader
    except ImportError:  # pragma: no cover - mcap is a runtime requirement
        return None, meta
    for f in _mcap_files(p):
        try:
            with open(f, 'rb') as fh:
                reader = make_reader(fh)
                summary = reader.get_summary()
                if summary is not None and summary.statistics is not None \
                        and summary.statistics.message_count:
                    t = int(summary.statistics.message_start_time)
                    start = t if start is None else min(start, t)
                for rec in reader.iter_metadata():
                    for k, v in rec.metadata.items():
                        meta.setdefault(str(k), str(v))
        except Exception:
            continue
    if p.is_dir() and (p / BAG_METADATA).is_file():
        try:
            import yaml

            info = yaml.safe_load((p / BAG_METADATA).read_text()) or {}
            info = info.get('rosbag2_bagfile_information', info)
            for k, v in (info.get('custom_data') or {}).items():
                meta.setdefault(str(k), str(v))
        except Exception:
            pass
    return start, meta


# --------------------------------------------------------------------------------------------
# One row


def _finite(x: Any) -> float | None:
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _iso(ns: int | None) -> str | None:
    if ns is None:
        return None
    return datetime.fromtimestamp(ns / 1e9, tz=UTC).strftime('%Y-%m-%dT%H:%M:%S.%fZ')


def _empty_row(ref: LogRef, signature: str) -> dict[str, Any]:
    row: dict[str, Any] = {
        'path': display_path(ref.path), 'size': ref.size, 'mtime_ns': ref.mtime_ns,
        'options': signature,
        'vehicle': None, 'log_start_ns': None, 'log_start': None, 'status': None,
        'reason': None, 'error': None}
    for n in THETA_NAMES:
        row[n] = None
    for n in THETA_NAMES:
        row[n + '_std'] = None
    for n in ('I1', 'I2', 'I3', 'I1_std', 'I2_std', 'I3_std'):
        row[n] = None
    row.update({'model': None, 'method': None, 'samples_used': None, 'samples_dropped': None,
                'wall_s': None, 'cpu_s': None, 'worker': None, 'report': None})
    return row


def row_from_report(ref: LogRef, report: dict[str, Any] | None, *, signature: str,
                    vehicle: str | None, error: str | None = None,
                    start_ns: int | None = None, wall_s: float | None = None,
                    cpu_s: float | None = None, worker: str | None = None
                    ) -> dict[str, Any]:
    """One table row from an ``estimate`` JSON report (or from the error of a failed log).

    Parameters
    ----------
    ref : LogRef
        The log.
    report : dict or None
        The JSON report (DESIGN.md contract); None when the log failed.
    signature : str
        :func:`options_signature` of the run.
    vehicle : str or None
        The vehicle the log belongs to.
    error : str, optional
        The one-line error of a failed log (then ``status`` is ``'error'``).
    start_ns : int, optional
        Log start [ns since the epoch] when the report does not say (failed logs).
    wall_s, cpu_s : float, optional
        Wall and CPU time of the task [s].
    worker : str, optional
        The worker that ran the task.

    Returns
    -------
    dict
        The columns of :data:`inertia_ros.fleet.table.COLUMNS`; tensor elements and their
        one-sigma errors in kg m^2, None where not identified.  Text is valid UTF-8 (the
        bytes of a non-UTF-8 file name in a path, vehicle or error as ``\\xNN``).
    """
    row = _empty_row(ref, signature)
    row.update({'vehicle': vehicle, 'wall_s': wall_s, 'cpu_s': cpu_s, 'worker': worker})
    if report is None:
        row.update({'status': ERROR, 'error': shown(error or 'no report', 2000),
                    'log_start_ns': start_ns,
                    'log_start': _iso(start_ns)})
    else:
        _fill_from_report(row, report, start_ns)
    return {k: display_path(v) if isinstance(v, str) else v for k, v in row.items()}


def _fill_from_report(row: dict[str, Any], report: dict[str, Any], start_ns: int | None
                      ) -> None:
    """Set the columns of ``row`` that come from an ``estimate`` JSON report."""
    diag = report.get('diagnostics') or {}
    log = diag.get('log') or {}
    epoch = log.get('epoch_ns', start_ns)
    epoch = int(epoch) if epoch is not None else None
    status = str(report.get('status'))
    reason = report.get('reason') or diag.get('reason')
    if reason is None and status != 'ok':
        reason = (diag.get('adequacy') or {}).get('reason') if isinstance(
            diag.get('adequacy'), dict) else None
    row.update({'status': status, 'reason': reason, 'log_start_ns': epoch,
                'log_start': _iso(epoch), 'model': report.get('model'),
                'method': report.get('method')})
    inertia, std = report.get('inertia'), report.get('inertia_std')
    for n, (i, j) in zip(THETA_NAMES, _THETA_IDX, strict=True):
        row[n] = _finite(inertia[i][j]) if inertia is not None else None
        row[n + '_std'] = _finite(std[i][j]) if std is not None else None
    pm = report.get('principal_moments')
    pm_std = diag.get('principal_moments_std')
    for k in range(3):
        row[f'I{k + 1}'] = _finite(pm[k]) if pm is not None else None
        row[f'I{k + 1}_std'] = _finite(pm_std[k]) if pm_std is not None else None
    samples = report.get('samples') or {}
    row['samples_used'] = samples.get('used')
    row['samples_dropped'] = samples.get('dropped')
    row['report'] = json.dumps(report, separators=(',', ':'), allow_nan=False)


def _worker_name() -> str | None:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return None


def _fetch(url: str, kind: str, tmp: Path) -> Path:
    """Copy a log at an fsspec URL into ``tmp``; return the local path."""
    import fsspec

    fs, root = fsspec.core.url_to_fs(url)
    name = Path(root.rstrip('/')).name or 'log'
    local = tmp / name
    if kind == 'rosbag2':
        local.mkdir()
        for f in fs.ls(root, detail=False):
            base = Path(f.rstrip('/')).name
            if base == BAG_METADATA or base.endswith(MCAP_SUFFIX):
                fs.get(f, str(local / base))
    else:
        fs.get(root, str(local))
    return local


@contextlib.contextmanager
def _reader_threads(on: bool) -> Iterator[None]:
    """The MCAP reader's chunk-loading thread on or off for one log (restored after).

    Off inside a Dask worker: a worker thread stands for one core (``threads_per_worker=1``,
    ``dask worker --nthreads 1``), as Dask's own one-thread BLAS setting in its workers says,
    and a thread the scheduler does not know of competes with the neighbouring workers. With
    every core busy it gained nothing (2 workers on 2 cores: 41.6-42.0 s with it, 41.6-42.3 s
    without); it only helps a lone worker with a free core.  Runs under ``_LOCK`` (one log at
    a time per process), so the class attribute is not shared with a concurrent log.
    """
    from inertia_ros.io.mcap_reader import McapReader

    before = McapReader.THREADS
    McapReader.THREADS = before and on
    try:
        yield
    finally:
        McapReader.THREADS = before


def _vehicle(ref: LogRef, vehicle_from: str, meta: dict[str, str] | None) -> str | None:
    if vehicle_from == 'dir':
        return vehicle_from_dir(ref.path)
    key = vehicle_from.removeprefix('metadata:')
    return (meta or {}).get(key)


def estimate_log(ref: LogRef, flags: Sequence[str] = (), vehicle_from: str = 'dir'
                 ) -> dict[str, Any]:
    """Estimate one log: the Dask task.  Never raises for a bad log; returns its row.

    Parameters
    ----------
    ref : LogRef
        The log (a local path the worker can read, or an fsspec URL).
    flags : sequence of str
        ``estimate`` options (``--model full``, ...), the same for every log.
    vehicle_from : str
        ``'dir'`` (the log's parent directory) or ``'metadata:KEY'`` (a key of the log's MCAP
        metadata records or of a rosbag2 ``custom_data``; None when absent).

    Returns
    -------
    dict
        The row (:func:`row_from_report`).
    """
    from inertia_ros.cli import main

    t0, c0 = time.perf_counter(), time.process_time()
    signature = options_signature(flags, vehicle_from)
    worker = _worker_name()
    if ref.problem is not None:  # never opened (a FIFO would block this worker for ever)
        return row_from_report(ref, None, signature=signature,
                               vehicle=_vehicle(ref, vehicle_from, None), error=ref.problem,
                               wall_s=time.perf_counter() - t0, worker=worker)
    with tempfile.TemporaryDirectory(prefix='inertia_fleet_') as tmpdir:
        tmp = Path(tmpdir)
        local = ref.path
        if is_url(ref.path):
            try:
                local = str(_fetch(ref.path, ref.kind, tmp))
            except Exception as exc:
                return row_from_report(
                    ref, None, signature=signature, vehicle=_vehicle(ref, vehicle_from, None),
                    error=f'{ref.path}: cannot fetch: {exc}', wall_s=time.perf_counter() - t0,
                    worker=worker)
        out = tmp / 'report.json'
        err = io.StringIO()
        argv = ['estimate', local, '--format', 'json', '--no-progress', '-o', str(out),
                *flags]
        with _LOCK, contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), \
                _reader_threads(worker is None):
            try:
                rc = main(argv)
            except SystemExit as exc:  # argparse refusing a pass-through flag
                rc = exc.code if isinstance(exc.code, int) else 2
            except Exception as exc:
                rc = -1
                err.write(f'{_ERROR_PREFIX}internal error: {type(exc).__name__}: {exc}\n')
        report = None
        if rc == 0 and out.is_file():
            try:
                report = json.loads(out.read_text())
            except ValueError as exc:
                err.write(f'{_ERROR_PREFIX}unreadable report: {exc}\n')
        need_info = report is None or vehicle_from != 'dir'
        start, meta = log_info(local) if need_info else (None, {})
    message = None
    if report is None:
        lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
        ours = [ln for ln in lines if ln.startswith('inertia_ros estimate')]  # not warnings
        message = (ours or lines or [f'estimate exited with status {rc}'])[-1]
        message = message.removeprefix(_ERROR_PREFIX)
        if local != ref.path:
            message = message.replace(local, ref.path)
    row = row_from_report(ref, report, signature=signature,
                          vehicle=_vehicle(ref, vehicle_from, meta), error=message,
                          start_ns=start, wall_s=time.perf_counter() - t0,
                          cpu_s=time.process_time() - c0, worker=worker)
    if rc == 130:  # Ctrl-C reached the worker: not the log's fault, run it again next time
        row['status'] = FAILED
    return row


def failed_row(ref: LogRef, flags: Sequence[str], vehicle_from: str, exc: BaseException
               ) -> dict[str, Any]:
    """The row of a task the infrastructure lost (status ``failed``: re-run next time)."""
    row = row_from_report(ref, None, signature=options_signature(flags, vehicle_from),
                          vehicle=_vehicle(ref, vehicle_from, {}) if vehicle_from == 'dir'
                          else None,
                          error=f'task failed: {type(exc).__name__}: {exc}'.strip())
    row['status'] = FAILED
    return row


# --------------------------------------------------------------------------------------------
# The submission loop (the client: inertia_ros.fleet.cluster)


def run_logs(client: Any, refs: Sequence[LogRef], flags: Sequence[str] = (),
             vehicle_from: str = 'dir',
             on_row: Callable[[dict[str, Any]], None] | None = None
             ) -> tuple[list[dict[str, Any]], bool]:
    """Estimate every log on the cluster; return the rows as they finished.

    Parameters
    ----------
    client : distributed.Client
    refs : sequence of LogRef
    flags : sequence of str
        ``estimate`` options.
    vehicle_from : str
        See :func:`estimate_log`.
    on_row : callable, optional
        Called with each row as it arrives (progress, checkpoints).  A ``KeyboardInterrupt``
        raised there, or by Ctrl-C, stops the run like Ctrl-C does.

    Returns
    -------
    rows : list of dict
        One per finished log, in completion order.
    interrupted : bool
        True when Ctrl-C stopped the run: unfinished tasks were cancelled, their logs have
        no row.
    """
    from distributed import as_completed

    flags = list(flags)
    # the options travel inside each task (a partial), not as map keyword arguments: Dask
    # makes a large keyword argument (a 130 kB option) a shared task of its own, which its
    # scheduler then failed on (AssertionError, every row 'failed')
    task = functools.partial(estimate_log, flags=flags, vehicle_from=vehicle_from)
    futures = client.map(task, list(refs), pure=False)
    by_key = {f.key: ref for f, ref in zip(futures, refs, strict=True)}
    rows: list[dict[str, Any]] = []
    interrupted = False
    try:
        for fut in as_completed(futures):
            ref = by_key[fut.key]
            try:
                row = fut.result()
            except KeyboardInterrupt:
                raise
            except BaseException as exc:
                row = failed_row(ref, flags, vehicle_from, exc)
            rows.append(row)
            if on_row is not None:
                on_row(row)
    except KeyboardInterrupt:
        interrupted = True
        with contextlib.suppress(Exception):
            client.cancel([f for f in futures if not f.done()])
    return rows, interrupted
