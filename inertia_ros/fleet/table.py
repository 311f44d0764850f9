"""Fleet rows <-> a table file: Parquet (``.parquet``, needs pyarrow) or CSV (``.csv``).

Both formats hold the same columns (:data:`COLUMNS`) in the same order; missing values are
nulls in Parquet and empty fields in CSV.  Floats are written at full precision (CSV uses
``repr``), so a round trip is exact (an empty string reads back as null).  Files are
replaced atomically (written to a new temporary file beside the target, created with an
unpredictable name and ``O_EXCL`` so a planted file or link there is never written through,
then renamed over the target), so an interrupted write never leaves half a table.

:func:`read_rows` reads only a table this module wrote (exactly :data:`COLUMNS`, in order):
any other file is refused, so a user's own file at ``--out`` is never taken for earlier
results and rewritten.
"""
from __future__ import annotations

import contextlib
import csv
import os
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

__all__ = ['COLUMNS', 'FORMATS', 'TableError', 'read_rows', 'table_format', 'write_rows']

#: Column name -> type (``str``, ``int`` or ``float``), in file order.  Units: sizes in
#: bytes, times in ns since the Unix epoch (``log_start`` is the same instant as ISO 8601
#: UTC), tensor elements, principal moments and their one-sigma errors in kg m^2, ``wall_s``
#: and ``cpu_s`` (the task's wall and CPU time in the worker) in seconds.  ``report`` is the
#: log's whole ``estimate --format json`` report.
COLUMNS: dict[str, type] = {
    'path': str, 'size': int, 'mtime_ns': int, 'options': str, 'vehicle': str,
    'log_start_ns': int, 'log_start': str, 'status': str, 'reason': str, 'error': str,
    'ixx': float, 'iyy': float, 'izz': float, 'ixy': float, 'ixz': float, 'iyz': float,
    'ixx_std': float, 'iyy_std': float, 'izz_std': float, 'ixy_std': float,
    'ixz_std': float, 'iyz_std': float,
    'I1': float, 'I2': float, 'I3': float, 'I1_std': float, 'I2_std': float, 'I3_std': float,
    'model': str, 'method': str, 'samples_used': int, 'samples_dropped': int,
    'wall_s': float, 'cpu_s': float, 'worker': str, 'report': str,
}
#: Supported file suffixes.
FORMATS = ('.parquet', '.csv')


class TableError(ValueError):
    """A table file that cannot be written or read (format, engine, content)."""


def table_format(path: str | os.PathLike[str]) -> str:
    """``'parquet'`` or ``'csv'`` from the file suffix; :class:`TableError` otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise TableError(f'{path}: unknown table format {suffix or "(no suffix)"!r}; '
                         f'name it .parquet or .csv')
    if suffix == '.parquet':
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise TableError(f'{path}: writing Parquet needs pyarrow (pip install pyarrow); '
                             f'or name the output .csv') from None
    return suffix[1:]


def _clean(row: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for name, kind in COLUMNS.items():
        v = row.get(name)
        if v is not None and v != '':
            v = kind(v)
        else:
            v = None
        out[name] = v
    return out


def _arrow_schema() -> Any:
    import pyarrow as pa

    kinds = {str: pa.string(), int: pa.int64(), float: pa.float64()}
    return pa.schema([(n, kinds[k]) for n, k in COLUMNS.items()])


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _write_to(fh: Any, fmt: str, clean: Sequence[dict[str, Any]]) -> None:
    """Write the cleaned rows to the open binary file ``fh``."""
    if fmt == 'parquet':
        import pyarrow as pa
        import pyarrow.parquet as pq

        cols = {n: [r[n] for r in clean] for n in COLUMNS}
        pq.write_table(pa.table(cols, schema=_arrow_schema()), fh, compression='zstd')
        return
    import io

    text = io.TextIOWrapper(fh, encoding='utf-8', newline='')
    w = csv.writer(text)
    w.writerow(COLUMNS)
    for r in clean:
        w.writerow(['' if r[n] is None else repr(r[n]) if isinstance(r[n], float)
                    else r[n] for n in COLUMNS])
    text.flush()
    text.detach()


def write_rows(path: str | os.PathLike[str], rows: Iterable[dict[str, Any]]) -> None:
    """Write ``rows`` (dicts with the :data:`COLUMNS` keys) to ``path``, replacing it.

    The rows go to a new temporary file in the same directory (``tempfile.mkstemp``:
    unpredictable name, ``O_EXCL``, mode as for a new file under the umask), which then
    replaces ``path`` (``os.replace``; a symbolic link at ``path`` is replaced, its target
    never written).

    Raises
    ------
    TableError
        Unknown suffix, no pyarrow for Parquet, or an OS error (directory missing, ...).
    """
    fmt = table_format(path)
    target = Path(path)
    clean = [_clean(r) for r in rows]
    try:
        fd, tmp = tempfile.mkstemp(prefix=f'.{target.name}.', suffix='.tmp',
                                   dir=target.parent)
    except OSError as exc:
        raise TableError(f'{path}: cannot write ({exc.strerror or exc})') from None
    try:
        with os.fdopen(fd, 'wb') as fh:
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
            _write_to(fh, fmt, clean)
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise TableError(f'{path}: cannot write ({exc.strerror or exc})') from None
        raise


def read_rows(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Rows of a table written by :func:`write_rows` (missing columns read as None).

    Raises
    ------
    TableError
        Unknown suffix, unreadable file, or a file whose columns are not :data:`COLUMNS` (not
        written by :func:`write_rows`).
    """
    fmt = table_format(path)
    try:
        if fmt == 'parquet':
            import pyarrow.parquet as pq

            names = list(pq.read_schema(path).names)
            raw: Sequence[dict[str, Any]] = (pq.read_table(path).to_pylist()
                                             if names == list(COLUMNS) else [])
        else:
            with open(path, newline='', encoding='utf-8') as fh:
                reader = csv.DictReader(fh)
                names = list(reader.fieldnames or [])
                raw = list(reader) if names == list(COLUMNS) else []
    except OSError as exc:
        raise TableError(f'{path}: cannot read ({exc.strerror or exc})') from None
    except Exception as exc:
        raise TableError(f'{path}: not a fleet table ({type(exc).__name__}: {exc}); '
                         f'move it away or choose another --out') from None
    if names != list(COLUMNS):
        raise TableError(f'{path}: exists and is not a table written by inertia_ros fleet '
                         f'(its columns differ); it is left as it is: choose another --out')
    try:
        return [_clean(r) for r in raw]
    except (TypeError, ValueError) as exc:
        raise TableError(f'{path}: not a fleet table ({exc})') from None
