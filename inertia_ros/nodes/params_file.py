"""``--params-file`` checked before rcl reads it: one line naming the file when it cannot be used.

rcl reports a missing or unparsable parameters file as "Couldn't parse params file" (after an
``[ERROR] [rcl]`` log line) without saying which file or why; :func:`params_file_problem`
finds the same problems first and names them.  No rclpy here.
"""
from __future__ import annotations

import os
import stat
import sys
from collections.abc import Sequence
from typing import Any

__all__ = ['MAX_PARAMS_FILE_BYTES', 'params_file_problem', 'params_files']

#: Largest parameters file read [bytes] (a parameters file is a few kB; /dev/zero is not one).
MAX_PARAMS_FILE_BYTES = 16 * 1024 * 1024
#: The key under which a node's parameters sit in a ROS 2 parameters file.
ROS_PARAMETERS = 'ros__parameters'


def params_files(argv: Sequence[str]) -> list[str]:
    """The ``--params-file`` arguments inside the ``--ros-args`` sections of ``argv``."""
    out: list[str] = []
    inside = False
    args = list(argv)
    for k, arg in enumerate(args):
        if arg == '--ros-args':
            inside = True
        elif arg == '--':
            inside = False
        elif inside and arg == '--params-file' and k + 1 < len(args):
            out.append(args[k + 1])
    return out


def _has_parameters(doc: Any, seen: set[int]) -> bool:
    """Whether ``doc`` is a mapping of (namespaces of) node names to ``ros__parameters``."""
    if not isinstance(doc, dict) or id(doc) in seen:
        return False
    seen.add(id(doc))
    for key, value in doc.items():
        if key == ROS_PARAMETERS:
            if not isinstance(value, dict):
                return False
        elif not _has_parameters(value, seen):
            return False
    return True


def _problem(path: str) -> str:
    """What is wrong with one parameters file ('' when rcl can be left to read it)."""
    import yaml

    try:
        st = os.stat(path)
    except OSError as exc:
        what = ('does not exist' if not os.path.lexists(path)
                else f'cannot be read ({exc.strerror})')
        return f'--params-file {path}: the file {what}'
    if not stat.S_ISREG(st.st_mode):
        return f'--params-file {path}: not a regular file'
    if st.st_size > MAX_PARAMS_FILE_BYTES:
        return (f'--params-file {path}: {st.st_size} bytes, more than a parameters file '
                f'({MAX_PARAMS_FILE_BYTES} bytes at most)')
    try:
        with open(path, 'rb') as f:
            doc = yaml.safe_load(f)
    except OSError as exc:
        return f'--params-file {path}: the file cannot be read ({exc.strerror})'
    except (yaml.YAMLError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        detail = ' '.join(str(exc).split())[:200]
        return f'--params-file {path}: cannot be parsed as YAML ({detail})'
    if doc is not None and not _has_parameters(doc, set()):   # (rcl accepts an empty file)
        return (f'--params-file {path}: not a ROS 2 parameters file (expected '
                f'"<node name>: {ROS_PARAMETERS}: {{name: value, ...}}", as in '
                'config/inertia_estimator.yaml)')
    return ''


def params_file_problem(argv: Sequence[str] | None) -> str:
    """The first unusable ``--params-file`` of ``argv`` (default ``sys.argv``), named in one
    line ('' when every one exists and parses as a ROS 2 parameters file)."""
    for path in params_files(sys.argv[1:] if argv is None else argv):
        problem = _problem(path)
        if problem:
            return problem
    return ''
