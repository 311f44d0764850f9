"""Output files of the command line: checked before any work, written without surprises.

One rule for every file a command writes (``estimate -o``, ``--plot``, ``--urdf``): an
existing file is refused unless ``force``; a directory, a missing or unwritable directory, a
dangling symbolic link, a name the file system cannot hold and one of the command's own inputs
are always refused.  :func:`check_output` says so before the work starts (one line, naming the
option and the path); :func:`write_output` then writes

- a new file with ``O_CREAT | O_EXCL``: it never follows a symbolic link nor replaces a file
  that appeared meanwhile, and a failed write leaves nothing behind;
- a replaced file (``force``) through a temporary file with an unpredictable name in the same
  directory, renamed over the old one: the old file (or the link, never its target) is
  replaced whole, or not at all;
- an existing special file (``/dev/stdout``, ``/dev/null``, a pipe) as a stream.

Functions
---------
:func:`check_output`  refuse, before any work, an output that cannot or must not be written
:func:`write_output`  write bytes or text to a checked output
"""
from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = ['OutputError', 'check_output', 'write_output']


class OutputError(ValueError):
    """An output the user named cannot or must not be written (one line)."""


def _lstat(path: Path) -> os.stat_result | None:
    """``os.lstat`` or None when nothing is there."""
    try:
        return path.lstat()
    except FileNotFoundError:
        return None


def check_output(opt: str, path: Path, *, force: bool = False,
                 inputs: Mapping[Path, str] | Iterable[Path] = ()) -> None:
    """Refuse an output file that cannot or must not be written.

    Parameters
    ----------
    opt : str
        The option that named it (``'-o'``, ``'--plot'``, ``'--urdf'``), for the message.
    path : Path
        The output file.
    force : bool
        Replace an existing regular file (default: refuse it).
    inputs : mapping of Path to str, or iterable of Path
        Resolved paths of the command's inputs, never written even with ``force`` (with what
        each is for the message, default ``'the input log'``).

    Raises
    ------
    OutputError
        One line ``'OPT PATH: what is wrong; what to do'``.
    """
    text = str(path)
    where = f'{opt} {text if len(text) <= 200 else text[:100] + "..." + text[-40:]}'
    try:
        st = _lstat(path)
        if st is not None and stat.S_ISLNK(st.st_mode) and not path.exists():
            raise OutputError(f'{where}: is a dangling symbolic link (to {os.readlink(path)}); '
                              'remove the link or choose another name')
        named = inputs if isinstance(inputs, Mapping) else dict.fromkeys(inputs, 'the input log')
        if path.resolve() in named:
            raise OutputError(f'{where}: refusing to overwrite {named[path.resolve()]}')
        if path.is_dir():
            raise OutputError(f'{where}: is a directory; give a file name')
        if st is not None and not path.is_file():
            return                   # a device or a pipe (/dev/stdout): written as a stream
        if st is not None and not force:
            raise OutputError(f'{where}: exists; pass --force to replace it, or choose another '
                              'name')
        parent = path.parent
        if not parent.is_dir():
            raise OutputError(f'{where}: directory {parent} does not exist')
        fd, probe = tempfile.mkstemp(prefix='.inertia_ros-probe-', dir=parent)
        os.close(fd)
        os.unlink(probe)
    except OutputError:
        raise
    except (OSError, ValueError) as exc:      # read-only, permission, name too long, NUL
        what = getattr(exc, 'strerror', None) or str(exc).splitlines()[0]
        raise OutputError(f'{where}: cannot be written ({what}); choose another place') from None


def _umask() -> int:
    """The process umask (read by setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_output(path: Path, data: bytes | str, *, force: bool = False) -> None:
    """Write ``data`` to ``path`` (checked by :func:`check_output`).

    Parameters
    ----------
    path : Path
        The output file.
    data : bytes or str
        The content (text is written as UTF-8).
    force : bool
        Replace an existing regular file (or symbolic link) whole.

    Raises
    ------
    OSError
        The write failed; nothing is left at ``path`` that was not there before.
    FileExistsError
        ``path`` exists (a file or a link) and ``force`` is false.
    """
    raw = data.encode('utf-8') if isinstance(data, str) else bytes(data)
    st = _lstat(path)
    target = path.stat() if st is not None and path.exists() else None
    if target is not None and not stat.S_ISREG(target.st_mode):
        with open(path, 'wb') as f:                    # a device or a pipe
            f.write(raw)
        return
    if st is None or not force:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            with os.fdopen(fd, 'wb') as f:
                f.write(raw)
        except BaseException:
            path.unlink(missing_ok=True)
            raise
        return
    fd, tmp = tempfile.mkstemp(prefix=f'.{path.name[:64]}.', suffix='.tmp', dir=path.parent)
    try:
        with os.fdopen(fd, 'wb') as f:
            f.write(raw)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
