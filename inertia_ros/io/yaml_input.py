"""One bounded, strict reader for the user's YAML files (scenes, wheels, rotors).

``yaml.safe_load`` of a file the user names is not safe enough for a command line that must
answer every input with a report or one line: it reads ``/dev/zero`` without end, blocks on a
FIFO, expands an alias bomb ("billion laughs") into gigabytes as soon as the result is
printed or copied, recurses until ``RecursionError`` on deep nesting, raises Python's
``ValueError`` on a 5000-digit integer, silently keeps the last of duplicated keys and reads
``1e-1`` as the string ``'1e-1'`` (YAML 1.1 wants a dot in a float).  :func:`read_yaml`:

- opens without blocking and refuses anything but a regular file, and files over
  :data:`MAX_YAML_BYTES`;
- decodes strict UTF-8 (the error names the file and the byte offset);
- composes with a depth limit (:data:`MAX_DEPTH`), then refuses a document whose aliases
  expand to more than :data:`MAX_NODES` nodes, or nest (expanded) deeper than
  :data:`MAX_DEPTH`, or refer to themselves;
- refuses duplicated mapping keys and integers of more than :data:`MAX_INT_DIGITS` digits;
- reads YAML 1.2 floats without a dot (``1e-1``, ``2E+3``) as numbers.

Every problem is one :class:`YamlInputError` line (a ``ValueError``) naming the file and,
where known, the line.
"""
from __future__ import annotations

import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from inertia_ros.core._validate import show

__all__ = ['MAX_DEPTH', 'MAX_INT_DIGITS', 'MAX_NODES', 'MAX_YAML_BYTES', 'YamlInputError',
           'read_yaml', 'show']

#: Largest YAML file read [bytes]: description files are a few kB, and the pure-Python
#: parser (the only one whose nesting is bounded) takes ~3 s for 64 KiB of small tokens.
MAX_YAML_BYTES = 1 << 16
#: Deepest nesting of collections, aliases expanded.
MAX_DEPTH = 64
#: Most nodes of the document, aliases expanded (each use of an anchor counts it again).
MAX_NODES = 200_000
#: Most digits of an integer.
MAX_INT_DIGITS = 40

_MERGE_TAG = 'tag:yaml.org,2002:merge'
_FLOAT_12 = re.compile(r'^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$')


class YamlInputError(ValueError):
    """A user YAML file that cannot be read: one line naming the file."""


class _Loader(yaml.SafeLoader):
    """``SafeLoader`` with a nesting limit, no duplicate keys, bounded integers and YAML 1.2
    floats."""

    yaml_implicit_resolvers = {k: list(v) for k, v in
                               yaml.SafeLoader.yaml_implicit_resolvers.items()}
    yaml_constructors = dict(yaml.SafeLoader.yaml_constructors)

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:  # type: ignore[override]
        """Compose one node, refusing nesting deeper than :data:`MAX_DEPTH`."""
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise yaml.MarkedYAMLError(None, None, f'nested deeper than {MAX_DEPTH} '
                                           'levels', mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: MappingNode, deep: bool = False) -> dict:
        """A mapping, refusing a key given twice (merge keys ``<<`` excepted)."""
        if isinstance(node, MappingNode):
            seen: set[tuple[str, str]] = set()
            for key_node, _ in node.value:
                if isinstance(key_node, ScalarNode) and key_node.tag != _MERGE_TAG:
                    k = (key_node.tag, key_node.value)
                    if k in seen:
                        raise ConstructorError(None, None, f'duplicate key {show(k[1], 40)}',
                                               key_node.start_mark)
                    seen.add(k)
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node: ScalarNode) -> int:  # type: ignore[override]
        """An integer of at most :data:`MAX_INT_DIGITS` characters."""
        value = str(node.value)
        if len(value.replace('_', '')) > MAX_INT_DIGITS:
            raise ConstructorError(None, None, f'an integer of {len(value)} digits (at most '
                                   f'{MAX_INT_DIGITS})', node.start_mark)
        return super().construct_yaml_int(node)


_Loader.add_constructor('tag:yaml.org,2002:int', _Loader.construct_yaml_int)
_Loader.add_constructor('tag:yaml.org,2002:map', _Loader.construct_yaml_map)
_Loader.add_implicit_resolver('tag:yaml.org,2002:float', _FLOAT_12, list('-+0123456789'))


def _check_expansion(root: Node) -> None:
    """Refuse a node graph whose expansion (aliases repeated) is too large, too deep or
    cyclic; iterative, so no input can exhaust the Python stack."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    stack: list[tuple[Node, bool]] = [(root, False)]
    active: set[int] = set()
    while stack:
        node, done = stack.pop()
        nid = id(node)
        kids: list[Node] = []
        if isinstance(node, SequenceNode):
            kids = list(node.value)
        elif isinstance(node, MappingNode):
            kids = [n for pair in node.value for n in pair]
        if done:
            active.discard(nid)
            size[nid] = 1 + sum(size[id(k)] for k in kids)
            depth[nid] = 1 + max((depth[id(k)] for k in kids), default=0)
            if size[nid] > MAX_NODES:
                raise yaml.MarkedYAMLError(None, None, f'its aliases expand to more than '
                                           f'{MAX_NODES} values (an alias bomb?)',
                                           node.start_mark)
            if depth[nid] > MAX_DEPTH:
                raise yaml.MarkedYAMLError(None, None, f'nested deeper than {MAX_DEPTH} '
                                           'levels (aliases expanded)', node.start_mark)
            continue
        if nid in size:
            continue
        if nid in active:
            raise yaml.MarkedYAMLError(None, None, 'an alias refers to a collection that '
                                       'contains it', node.start_mark)
        active.add(nid)
        stack.append((node, True))
        stack.extend((k, False) for k in kids if id(k) not in size)


def _read_bytes(p: Path, what: str) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_YAML_BYTES`, opened without
    blocking (a FIFO or a device is refused, never read)."""
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    except FileNotFoundError:
        raise YamlInputError(f'{p}: no such {what} file') from None
    except OSError as exc:
        raise YamlInputError(f'{p}: cannot read the {what} file '
                             f'({exc.strerror or exc.__class__.__name__})') from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise YamlInputError(f'{p}: is a directory, expected a {what} .yaml file')
        if not stat.S_ISREG(st.st_mode):
            raise YamlInputError(f'{p}: not a regular file (a FIFO, socket or device); give '
                                 f'a {what} .yaml file')
        if st.st_size > MAX_YAML_BYTES:
            raise YamlInputError(f'{p}: {st.st_size} bytes, more than a {what} file can be '
                                 f'({MAX_YAML_BYTES} bytes)')
        chunks, n = [], 0
        while n <= MAX_YAML_BYTES:
            b = os.read(fd, MAX_YAML_BYTES + 1 - n)
            if not b:
                break
            chunks.append(b)
            n += len(b)
        if n > MAX_YAML_BYTES:
            raise YamlInputError(f'{p}: more than {MAX_YAML_BYTES} bytes, more than a {what} '
                                 'file can be')
        return b''.join(chunks)
    except OSError as exc:
        raise YamlInputError(f'{p}: cannot read the {what} file '
                             f'({exc.strerror or exc.__class__.__name__})') from None
    finally:
        os.close(fd)


def read_yaml(path: str | os.PathLike[str], what: str) -> Any:
    """Parse one user YAML file, within the limits of this module.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What it is (``'scene'``, ``'wheels'``, ``'rotors'``), for the messages.

    Returns
    -------
    Any
        The document (``None`` for an empty file).

    Raises
    ------
    YamlInputError
        One line ``PATH: problem`` (with ``line N`` where the YAML says where).
    """
    p = Path(path)
    data = _read_bytes(p, what)
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise YamlInputError(f'{p}: not UTF-8 text (byte {exc.start}); save the {what} file '
                             'as UTF-8') from None
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise YamlInputError(f'{p}: {_yaml_problem(exc)}') from None
    except RecursionError:                 # a safety net: the limits above should prevent it
        raise YamlInputError(f'{p}: nested too deeply') from None
    finally:
        loader.dispose()


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """``line N: not valid YAML: problem`` of a PyYAML error, on one line."""
    mark = getattr(exc, 'problem_mark', None)
    where = f'line {mark.line + 1}: ' if mark is not None else ''
    problem = getattr(exc, 'problem', None) or str(exc)
    return f'{where}not valid YAML: {" ".join(str(problem).split())[:200]}'
