"""rosbag2 bag directories: ``metadata.yaml`` parsed once into a typed, validated structure.

A rosbag2 bag is a directory holding ``metadata.yaml`` and one or more storage files
(``.mcap`` or ``.db3``, each possibly zstd-compressed as a whole).  :func:`read_bag_info`
reads the metadata file once and checks every field used downstream, so a damaged or
hand-edited file (not UTF-8, not YAML, a number where a list belongs, ``[null]`` file names)
is one :class:`BagMetadataError` line naming the file, the field and the fix, never a
``TypeError`` deep inside a reader.

Field names and meanings follow rosbag2's ``BagMetadata`` (``rosbag2_storage``), versions
1-9: ``storage_identifier``, ``relative_file_paths``, ``compression_format``,
``compression_mode`` and ``topics_with_message_count``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any

#: Largest metadata.yaml read [bytes]; real ones are a few KiB (one entry per topic/file).
MAX_METADATA_BYTES = 16 << 20


class BagMetadataError(ValueError):
    """``metadata.yaml`` cannot be used; the message is one line naming file, field and fix."""


@dataclass(frozen=True)
class BagInfo:
    """What a rosbag2 ``metadata.yaml`` says, validated.

    Attributes
    ----------
    directory : Path
        The bag directory.
    storage : str
        ``storage_identifier``: ``'mcap'``, ``'sqlite3'``, ... (``'mcap'`` when absent).
    files : list of Path
        ``relative_file_paths`` resolved inside ``directory`` (order kept; may not exist).
    compression_format : str
        ``''`` (none) or the codec name (``'zstd'``).
    compression_mode : str
        ``''`` (none), ``'FILE'`` (each storage file compressed) or ``'MESSAGE'`` (each
        message payload compressed), upper case.
    message_counts : dict of str to int
        Messages per topic the recorder wrote (topics with an unreadable entry left out).
    version : int or None
        The metadata version, if given as an integer.
    """

    directory: Path
    storage: str = 'mcap'
    files: list[Path] = field(default_factory=list)
    compression_format: str = ''
    compression_mode: str = ''
    message_counts: dict[str, int] = field(default_factory=dict)
    version: int | None = None

    @property
    def compressed(self) -> bool:
        """True for file- or message-compressed bags."""
        return bool(self.compression_format) and self.compression_mode not in ('', 'NONE')

    @property
    def own_mcap_path(self) -> bool:
        """True when our own MCAP reader can read the files (uncompressed MCAP storage)."""
        return self.storage == 'mcap' and not self.compressed


def _fail(meta: Path, what: str) -> BagMetadataError:
    return BagMetadataError(f'{meta}: {what}; fix metadata.yaml or remove it (the .mcap files '
                            'of the directory are then read in name order)')


def _text(meta: Path) -> str:
    try:
        size = meta.stat().st_size
        if size > MAX_METADATA_BYTES:
            raise _fail(meta, f'is {size} bytes, not rosbag2 metadata (at most '
                              f'{MAX_METADATA_BYTES} expected)')
        raw = meta.read_bytes()
    except OSError as exc:
        raise BagMetadataError(f'{meta}: cannot be read ({exc.strerror or exc})') from None
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise _fail(meta, f'is not UTF-8 text (byte {exc.start})') from None


def _str_field(meta: Path, info: dict, key: str, default: str) -> str:
    val = info.get(key, default)
    if val is None:
        return default
    if not isinstance(val, str):
        raise _fail(meta, f'{key} is {val!r} ({type(val).__name__}), not a string')
    return val


def read_bag_info(directory: str | Path) -> BagInfo | None:
    """Read and validate a bag directory's ``metadata.yaml``.

    Parameters
    ----------
    directory : str or Path
        The bag directory.

    Returns
    -------
    BagInfo or None
        None when the directory has no ``metadata.yaml``.

    Raises
    ------
    BagMetadataError
        The file is not UTF-8, not YAML, not a mapping, or a field used has the wrong type
        (``relative_file_paths`` not a list of non-empty strings, ``storage_identifier`` not
        a string, ...).  Entries of ``topics_with_message_count`` that are malformed are
        skipped (they only serve the lost-message count).
    """
    d = Path(directory)
    meta = d / 'metadata.yaml'
    if not meta.is_file():
        return None
    import yaml

    text = _text(meta)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        raise _fail(meta, f'is not valid YAML{where}') from None
    except (RecursionError, ValueError, OverflowError) as exc:
        raise _fail(meta, f'is not usable YAML ({exc.__class__.__name__})') from None
    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise _fail(meta, f'holds a {type(doc).__name__}, not a mapping')
    info: Any = doc.get('rosbag2_bagfile_information', doc)
    if not isinstance(info, dict):
        raise _fail(meta, f'rosbag2_bagfile_information is {_short(info)} '
                          f'({type(info).__name__}), not a mapping')
    storage = _str_field(meta, info, 'storage_identifier', 'mcap') or 'mcap'
    fmt = _str_field(meta, info, 'compression_format', '')
    mode = _str_field(meta, info, 'compression_mode', '').upper()
    rel = info.get('relative_file_paths')
    files: list[Path] = []
    if rel is not None:
        if not isinstance(rel, list):
            raise _fail(meta, f'relative_file_paths is {_short(rel)} ({type(rel).__name__}), '
                              'not a list of file names')
        for k, r in enumerate(rel):
            if not isinstance(r, str) or not r.strip() or '\0' in r:
                raise _fail(meta, f'relative_file_paths[{k}] is {_short(r)}, not a file name')
            # rosbag2 writes names relative to the bag; never leave the directory
            files.append(d / PurePath(r).name)
    counts: dict[str, int] = {}
    twmc = info.get('topics_with_message_count')
    if isinstance(twmc, list):
        for ent in twmc:
            try:
                name = ent['topic_metadata']['name']
                n = ent['message_count']
            except (TypeError, KeyError, IndexError):
                continue
            if isinstance(name, str) and isinstance(n, int) and not isinstance(n, bool) \
                    and n >= 0:
                counts[name] = n
    ver = info.get('version')
    version = ver if isinstance(ver, int) and not isinstance(ver, bool) else None
    return BagInfo(d, storage, files, fmt, mode, counts, version)


def _short(val: object) -> str:
    text = repr(val)
    return text if len(text) <= 40 else text[:37] + '...'
