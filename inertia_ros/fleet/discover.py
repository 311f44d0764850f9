"""Find the logs of a fleet: ``.mcap`` files and rosbag2 directories, searched recursively.

A path given on the command line is

- a file: one log, whatever its name (``estimate`` decides whether it is usable);
- a rosbag2 directory (it holds ``metadata.yaml``): one log;
- any other directory: searched recursively for ``*.mcap`` files and rosbag2 directories
  (the files inside a rosbag2 directory belong to it and are not logs of their own; hidden
  entries and the ``*.partial`` directories of unfinished writes are skipped);
- a URL ``PROTOCOL://...`` other than ``file://``: the same rules through fsspec (any
  filesystem fsspec knows and has installed: ``memory://``, ``s3://`` with s3fs, ...). The
  worker copies such a log into a temporary directory before estimating it.

Each log is identified by ``(path, size, mtime_ns)``: the size and the latest modification
time of its files, so a re-run can tell an unchanged log from a new or rewritten one.

A log that cannot be read as a file (a dangling symbolic link, a symbolic-link loop, a FIFO,
a device or a socket named ``*.mcap``) is still found, with its ``problem``: it becomes a row
with that error and is never opened (a FIFO would block the worker for ever).  File names
that are not UTF-8 are kept as the bytes the filesystem gave (to open them) and shown with
backslash escapes (:func:`display_path`) in rows, tables and messages.
"""
from __future__ import annotations

import errno
import os
import posixpath
import stat
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ['DiscoveryError', 'LogRef', 'discover', 'display_path', 'is_url', 'shown',
           'vehicle_from_dir']

#: File-name suffix of an MCAP log.
MCAP_SUFFIX = '.mcap'
#: The file that makes a directory a rosbag2 bag.
BAG_METADATA = 'metadata.yaml'


class DiscoveryError(ValueError):
    """A path on the command line that cannot be searched (missing, unreadable URL)."""


@dataclass(frozen=True)
class LogRef:
    """One log to estimate.

    Attributes
    ----------
    path : str
        Absolute local path, or a URL for fsspec filesystems.
    size : int
        Total size of the log's files [bytes].
    mtime_ns : int
        Latest modification time of the log's files [ns since the Unix epoch]; 0 when the
        filesystem does not report one.
    kind : str
        ``'mcap'`` (a single file) or ``'rosbag2'`` (a bag directory).
    problem : str or None
        Why the log cannot be opened (``'dangling symbolic link'``, ``'not a regular file
        (FIFO)'``, ...); None for a readable log.  Such a log is a row with this error.
    """

    path: str
    size: int
    mtime_ns: int
    kind: str
    problem: str | None = None

    @property
    def key(self) -> tuple[str, int, int]:
        """The identity of this version of the log: ``(path, size, mtime_ns)``."""
        return (self.path, self.size, self.mtime_ns)


def display_path(path: str) -> str:
    """``path`` as valid UTF-8 text: bytes of a non-UTF-8 file name as ``\\xNN`` escapes.

    >>> display_path('/logs/caf\\udce9.mcap')
    '/logs/caf\\\\xe9.mcap'
    """
    return path.encode('utf-8', 'surrogateescape').decode('utf-8', 'backslashreplace')


def shown(text: str, limit: int = 160) -> str:
    """A user's value for a one-line message: :func:`display_path`, control characters
    escaped, the middle of a long one elided (at most ``limit`` characters)."""
    t = display_path(text)
    t = ''.join(c if c.isprintable() else repr(c)[1:-1] for c in t)
    if len(t) <= limit:
        return t
    half = (limit - 5) // 2
    return f'{t[:half]} ... {t[-half:]}'


def is_url(path: str) -> bool:
    """True for ``PROTOCOL://...`` other than ``file://`` (those are read through fsspec)."""
    head, sep, _ = path.partition('://')
    return bool(sep) and head.isidentifier() and head.lower() != 'file'


def vehicle_from_dir(path: str) -> str:
    """The vehicle named by a log's directory: the parent of the file or the bag directory.

    >>> vehicle_from_dir('/data/sat-03/2026-11-02.mcap')
    'sat-03'
    """
    p = path.rstrip('/')
    parent = posixpath.dirname(p) if is_url(p) else os.path.dirname(p)
    name = posixpath.basename(parent.rstrip('/')) if is_url(p) else os.path.basename(parent)
    return name or '/'


# --------------------------------------------------------------------------------------------
# Local filesystem


_KINDS = ((stat.S_ISFIFO, 'a FIFO'), (stat.S_ISCHR, 'a character device'),
          (stat.S_ISBLK, 'a block device'), (stat.S_ISSOCK, 'a socket'),
          (stat.S_ISDIR, 'a directory'))


def _file_problem(p: Path) -> tuple[os.stat_result | None, str | None]:
    """``(stat, None)`` of a regular file (links followed), else ``(None, why)``."""
    try:
        st = p.stat()
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        errnum = getattr(exc, 'errno', None)
        if errnum == errno.ELOOP:
            return None, 'symbolic link loop; not read'
        if errnum == errno.ENOENT and os.path.islink(p):
            return None, 'dangling symbolic link (its target does not exist); not read'
        return None, f'cannot read ({getattr(exc, "strerror", None) or exc})'
    if not stat.S_ISREG(st.st_mode):
        what = next((w for test, w in _KINDS if test(st.st_mode)), 'not a regular file')
        return None, f'not a regular file ({what}); not read'
    return st, None


def _local_stats(paths: Iterable[Path]) -> tuple[int, int, str | None]:
    """Total size [bytes], latest mtime [ns] and the first problem of the files."""
    size = 0
    mtime = 0
    for p in paths:
        st, problem = _file_problem(p)
        if st is None:
            return 0, 0, f'{display_path(str(p))}: {problem}'
        size += st.st_size
        mtime = max(mtime, st.st_mtime_ns)
    return size, mtime, None


def _local_bag(d: Path) -> LogRef:
    files = [d / BAG_METADATA] + sorted(d.glob('*' + MCAP_SUFFIX))
    size, mtime, problem = _local_stats(files)
    return LogRef(str(d), size, mtime, 'rosbag2', problem)


def _local_file(f: Path) -> LogRef:
    size, mtime, problem = _local_stats([f])
    return LogRef(str(f), size, mtime, 'mcap', problem)


def _skip(name: str) -> bool:
    return name.startswith('.') or name.endswith('.partial')


def _walk_local(root: Path) -> list[LogRef]:
    found: list[LogRef] = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        d = Path(dirpath)
        if BAG_METADATA in filenames and d != root:
            found.append(_local_bag(d))
            dirnames[:] = []
            continue
        dirnames[:] = sorted(n for n in dirnames if not _skip(n))
        for name in sorted(filenames):
            if name.endswith(MCAP_SUFFIX) and not _skip(name):
                found.append(_local_file(d / name))
    return found


def _discover_local(arg: str) -> list[LogRef]:
    if not arg.strip():
        raise DiscoveryError(f'PATH {arg!r} is empty; give a file or a directory')
    try:
        return _discover_local_path(arg)
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte, ...
        raise DiscoveryError(f'{shown(arg)}: cannot search '
                             f'({getattr(exc, "strerror", None) or exc})') from None


def _discover_local_path(arg: str) -> list[LogRef]:
    p = Path(arg.removeprefix('file://')).expanduser()
    p = Path(os.path.abspath(p))
    if not p.is_dir():
        if not p.exists() and not p.is_symlink():
            raise DiscoveryError(f'{shown(arg)}: no such file or directory')
        return [_local_file(p)]  # a file, or a path that is not one (a row with its problem)
    if (p / BAG_METADATA).exists():
        return [_local_bag(p)]
    return _walk_local(p)


# --------------------------------------------------------------------------------------------
# fsspec URLs


def _mtime_ns(info: dict[str, Any]) -> int:
    """Modification time of an fsspec ``info`` record [ns], whatever the backend calls it."""
    for key in ('mtime', 'LastModified', 'last_modified', 'updated', 'modified', 'created'):
        v = info.get(key)
        if v is None:
            continue
        if hasattr(v, 'timestamp'):
            return int(round(v.timestamp() * 1e9))
        try:
            return int(round(float(v) * 1e9))
        except (TypeError, ValueError):
            continue
    return 0


def _discover_url(arg: str) -> list[LogRef]:
    try:
        import fsspec
    except ImportError:  # pragma: no cover - fsspec comes with dask
        raise DiscoveryError(f'{shown(arg)}: URLs need fsspec (pip install fsspec)') from None
    try:
        fs, root = fsspec.core.url_to_fs(arg)
        if not fs.exists(root):
            raise DiscoveryError(f'{shown(arg)}: no such file or directory')
        if fs.isfile(root):
            info = fs.info(root)
            return [LogRef(fs.unstrip_protocol(root), int(info.get('size') or 0),
                           _mtime_ns(info), 'mcap')]
        entries = fs.find(root, withdirs=False, detail=True)
    except DiscoveryError:
        raise
    except Exception as exc:  # whatever a filesystem backend raises
        raise DiscoveryError(f'{shown(arg)}: cannot list this URL '
                             f'({shown(str(exc), 200)})') from None
    root = root.rstrip('/')
    by_dir: dict[str, list[tuple[str, dict[str, Any]]]] = {}
    for name, info in entries.items():
        rel = name[len(root):].strip('/').split('/')
        if any(_skip(part) for part in rel):
            continue
        by_dir.setdefault(posixpath.dirname(name), []).append((name, info))
    bags = sorted(d for d, items in by_dir.items() if d != root
                  and any(posixpath.basename(n) == BAG_METADATA for n, _ in items))
    found: list[LogRef] = []
    for d in bags:
        items = [i for n, i in by_dir[d]
                 if n.endswith(MCAP_SUFFIX) or posixpath.basename(n) == BAG_METADATA]
        found.append(LogRef(fs.unstrip_protocol(d), sum(int(i.get('size') or 0) for i in items),
                            max(_mtime_ns(i) for i in items), 'rosbag2'))
    for d, items in by_dir.items():
        if any(d == b or d.startswith(b + '/') for b in bags):
            continue
        for name, info in items:
            if name.endswith(MCAP_SUFFIX):
                found.append(LogRef(fs.unstrip_protocol(name), int(info.get('size') or 0),
                                    _mtime_ns(info), 'mcap'))
    return found


# --------------------------------------------------------------------------------------------


def discover(paths: Sequence[str]) -> list[LogRef]:
    """Every log under ``paths``, each once, in a stable order (sorted by path).

    Parameters
    ----------
    paths : sequence of str
        Files, rosbag2 directories, directories to search, or fsspec URLs.

    Returns
    -------
    list of LogRef

    Raises
    ------
    DiscoveryError
        A path that does not exist or a URL that cannot be listed.
    """
    seen: dict[str, LogRef] = {}
    for arg in paths:
        refs = _discover_url(arg) if is_url(arg) else _discover_local(arg)
        for ref in refs:
            seen.setdefault(ref.path, ref)
    return [seen[k] for k in sorted(seen)]
