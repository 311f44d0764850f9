"""ROS 2 message-type metadata: type names, ``ros2msg`` schema texts and RIHS01 type hashes.

The one home of everything this package knows *about* message types (not their payloads,
which :mod:`inertia_ros.io.cdr_encode` and :mod:`inertia_ros.io.cdr_decode` handle):

- type names: :func:`normalise_type` (``pkg/Type`` -> ``pkg/msg/Type``), :func:`short_type`
  (the reverse) and :func:`split_type`, the one parser behind both;
- the hand-written field lists :data:`MSG_FIELDS` of the types the simulator writes, so that
  logs can be written without any ROS install, and :func:`schema_text` built from them;
- the installed interface files: :func:`share_prefixes` gives the one lookup precedence
  (``AMENT_PREFIX_PATH`` first, as a sourced workspace overlays, then ``sys.prefix``, where
  the ROS wheels install), used by both :func:`schema_text_from_share` (``.msg`` files) and
  :func:`type_description_hash` (``.json`` type descriptions): both come from the same install
  of a package;
- the dependency walk (:func:`field_types`) shared by the hand-written and installed schemas.

A schema text is what rosbag2 stores in an MCAP schema record: the type's own fields, then
for every (transitive) dependency, depth first in order of first use, a line of 80 ``=``, a
line ``MSG: pkg/Type`` and that type's fields.

This module imports nothing from ROS: it reads text files only.
"""
from __future__ import annotations

import functools
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

__all__ = [
    'MSG_FIELDS',
    'field_types',
    'find_share_file',
    'normalise_type',
    'schema_text',
    'schema_text_from_share',
    'share_prefixes',
    'short_type',
    'split_type',
    'type_description_hash',
]

#: Field definitions (ros2msg syntax, comments omitted) of every type we write and its
#: dependencies, keyed by ``pkg/Type``.  Field types are fully qualified.
MSG_FIELDS: dict[str, str] = {
    'sensor_msgs/Imu': (
        'std_msgs/Header header\n'
        'geometry_msgs/Quaternion orientation\n'
        'float64[9] orientation_covariance\n'
        'geometry_msgs/Vector3 angular_velocity\n'
        'float64[9] angular_velocity_covariance\n'
        'geometry_msgs/Vector3 linear_acceleration\n'
        'float64[9] linear_acceleration_covariance\n'),
    'geometry_msgs/WrenchStamped': (
        'std_msgs/Header header\n'
        'geometry_msgs/Wrench wrench\n'),
    'geometry_msgs/Wrench': (
        'geometry_msgs/Vector3 force\n'
        'geometry_msgs/Vector3 torque\n'),
    'geometry_msgs/InertiaStamped': (
        'std_msgs/Header header\n'
        'geometry_msgs/Inertia inertia\n'),
    'geometry_msgs/Inertia': (
        'float64 m\n'
        'geometry_msgs/Vector3 com\n'
        'float64 ixx\n'
        'float64 ixy\n'
        'float64 ixz\n'
        'float64 iyy\n'
        'float64 iyz\n'
        'float64 izz\n'),
    'sensor_msgs/JointState': (
        'std_msgs/Header header\n'
        'string[] name\n'
        'float64[] position\n'
        'float64[] velocity\n'
        'float64[] effort\n'),
    'geometry_msgs/Vector3': (
        'float64 x\n'
        'float64 y\n'
        'float64 z\n'),
    'geometry_msgs/Quaternion': (
        'float64 x 0\n'
        'float64 y 0\n'
        'float64 z 0\n'
        'float64 w 1\n'),
    'std_msgs/Header': (
        'builtin_interfaces/Time stamp\n'
        'string frame_id\n'),
    'builtin_interfaces/Time': (
        'int32 sec\n'
        'uint32 nanosec\n'),
}

_SEPARATOR = '=' * 80
_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'})


# --------------------------------------------------------------------------- type names
def split_type(name: str) -> tuple[str, str, str]:
    """Split a ROS 2 interface name into ``(package, kind, type)``.

    Parameters
    ----------
    name : str
        ``pkg/Type`` (a message) or ``pkg/<kind>/Type`` (``kind`` is ``msg``, ``srv`` or
        ``action``).

    Returns
    -------
    tuple of str
        ``(pkg, kind, Type)``, ``kind`` = ``'msg'`` for the two-part form.

    Raises
    ------
    ValueError
        If the name has another shape or an empty part.
    """
    parts = name.split('/') if isinstance(name, str) else []
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts) or parts[1] not in ('msg', 'srv', 'action'):
        raise ValueError(f"msgtype: expected 'pkg/msg/Type' or 'pkg/Type', got {name!r}")
    return parts[0], parts[1], parts[2]


def normalise_type(name: str) -> str:
    """Return ``pkg/msg/Type`` for ``pkg/Type`` or ``pkg/msg/Type``; other names unchanged.

    Lenient on purpose: schema names read from a log are compared with the supported types
    as they are, and a name that is not a message type simply matches none of them.
    """
    try:
        pkg, kind, typ = split_type(name)
    except ValueError:
        return name
    return f'{pkg}/{kind}/{typ}'


def short_type(name: str) -> str:
    """Return ``pkg/Type`` for ``pkg/msg/Type`` (the ``MSG:`` form); other names unchanged."""
    try:
        pkg, kind, typ = split_type(name)
    except ValueError:
        return name
    return f'{pkg}/{typ}' if kind == 'msg' else name


# --------------------------------------------------------------------------- dependency walk
def field_types(text: str, pkg: str) -> list[str]:
    """The complex types ``pkg/Type`` used by the fields of a ``.msg`` text, in order.

    Parameters
    ----------
    text : str
        ``.msg`` file text (comments, constants and default values allowed).
    pkg : str
        Package of the message, for field types written without a package.

    Returns
    -------
    list of str
        Each complex field type once, as ``pkg/Type`` (``Header`` is ``std_msgs/Header``).
    """
    out: list[str] = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line or '=' in line:
            continue  # blank, comment or constant (NAME=value)
        ftype = re.sub(r'\[.*\]$', '', line.split()[0])
        base = ftype.split('<=')[0]
        if base in _PRIMITIVES:
            continue
        if '/' not in base:
            base = 'std_msgs/Header' if base == 'Header' else f'{pkg}/{base}'
        else:
            parts = base.split('/')
            base = f'{parts[0]}/{parts[-1]}'
        if base not in out:
            out.append(base)
    return out


def _walk(root: str, read: Callable[[str], str]) -> tuple[dict[str, str], list[str]]:
    """Texts of ``root`` and its dependencies; dependencies depth first in order of first use.

    ``read`` maps ``pkg/Type`` to its ``.msg`` text.
    """
    texts: dict[str, str] = {}
    order: list[str] = []

    def visit(name: str) -> None:
        text = read(name)
        texts[name] = text
        for dep in field_types(text, name.split('/')[0]):
            if dep not in texts:
                order.append(dep)
                visit(dep)

    visit(root)
    return texts, order


def schema_text(msgtype: str) -> str:
    """The ``ros2msg`` schema text of a type in :data:`MSG_FIELDS` (no ROS install needed).

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Type`` (or ``pkg/Type``), one of the types in :data:`MSG_FIELDS`.

    Returns
    -------
    str
        The type's fields, then for each dependency ``=`` * 80, ``MSG: pkg/Type`` and its
        fields, as rosbag2 writes them into MCAP schema records.

    Raises
    ------
    ValueError
        If the type is not one this module knows.
    """
    short = short_type(msgtype)
    if short not in MSG_FIELDS:
        raise ValueError(f'msgtype: no schema for {msgtype!r} '
                         f'(known: {", ".join(sorted(MSG_FIELDS))})')
    texts, order = _walk(short, MSG_FIELDS.__getitem__)
    blocks = [texts[short]] + [f'{_SEPARATOR}\nMSG: {dep}\n{texts[dep]}' for dep in order]
    return '\n'.join(blocks)


# --------------------------------------------------------------------------- installed files
def share_prefixes() -> list[str]:
    """Install prefixes searched for interface files, in precedence order.

    ``AMENT_PREFIX_PATH`` (a sourced workspace and its underlays, highest first), then
    ``sys.prefix`` (where the ROS 2 wheels install ``share/``).  The one precedence of every
    lookup in this module.
    """
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.append(sys.prefix)
    return prefixes


def find_share_file(msgtype: str, suffix: str) -> Path | None:
    """``<prefix>/share/<pkg>/<kind>/<Type><suffix>`` of the first prefix that has it.

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Type`` or ``pkg/Type``.
    suffix : str
        ``'.msg'`` (definition) or ``'.json'`` (type description with the RIHS01 hash).

    Returns
    -------
    pathlib.Path or None
        None when no prefix of :func:`share_prefixes` has the file.

    Raises
    ------
    ValueError
        If ``msgtype`` is malformed.
    """
    pkg, kind, typ = split_type(msgtype)
    for prefix in share_prefixes():
        path = Path(prefix, 'share', pkg, kind, f'{typ}{suffix}')
        if path.is_file():
            return path
    return None


def _msg_text(short: str) -> str:
    path = find_share_file(short, '.msg')
    if path is None:
        pkg, _, typ = split_type(short)
        raise ValueError(f'msgtype: no {pkg}/msg/{typ}.msg under the share/ of '
                         f'{share_prefixes()}')
    return path.read_text()


def schema_text_from_share(msgtype: str) -> str:
    """The ``ros2msg`` schema text of any installed message type, as rosbag2 stores it.

    The type's own ``.msg`` text, then for every (transitive) dependency a line of 80 ``=``,
    ``MSG: pkg/Type`` and that type's ``.msg`` text; every file is found through
    :func:`share_prefixes`.

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Type`` or ``pkg/Type``, e.g. ``visualization_msgs/msg/MarkerArray``.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        If the name is malformed or a ``.msg`` file cannot be found.
    """
    pkg, kind, typ = split_type(msgtype)
    if kind != 'msg':
        raise ValueError(f"msgtype: expected 'pkg/msg/Type', got {msgtype!r}")
    root = f'{pkg}/{typ}'
    texts, order = _walk(root, _msg_text)
    blocks = [texts[root].rstrip('\n')]
    blocks += [f"{_SEPARATOR}\nMSG: {dep}\n{texts[dep].rstrip(chr(10))}" for dep in order]
    return '\n'.join(blocks) + '\n'


def type_description_hash(msgtype: str) -> str:
    """The REP-2011 type hash (``RIHS01_...``) of a message type, or '' when unknown.

    Read from the ``share/<pkg>/msg/<Type>.json`` type description that every ROS 2 Jazzy
    interface package installs, found through :func:`share_prefixes` (the same install as
    :func:`schema_text_from_share` reads): rosbag2 records the same string as
    ``topic_type_hash`` / ``type_description_hash``.

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Type`` (or ``pkg/Type``).

    Returns
    -------
    str
        The hash string, or '' if the name is malformed or no installed description names it.
    """
    try:
        full = normalise_type(msgtype)
        split_type(full)
    except ValueError:
        return ''
    return _hash(full, tuple(share_prefixes()))


@functools.lru_cache(maxsize=64)
def _hash(full: str, prefixes: tuple[str, ...]) -> str:
    """Cached per type and precedence list (``prefixes`` keys the cache only)."""
    path = find_share_file(full, '.json')
    if path is None:
        return ''
    try:
        hashes = json.loads(path.read_text(encoding='utf-8')).get('type_hashes', [])
    except (OSError, ValueError):
        return ''
    for h in hashes:
        if isinstance(h, dict) and h.get('type_name') == full:
            return str(h.get('hash_string', ''))
    return ''
