"""Every other rosbag2 storage (sqlite3, file- or message-compressed) read through ``rosbags``.

Our own MCAP reader (:mod:`inertia_ros.io.mcap_reader`) is the fast path for plain MCAP.
Bags it cannot read — ``.db3`` (sqlite3) storage, and bags whose files or messages are
zstd-compressed — are read with the `rosbags <https://gitlab.com/ternaris/rosbags>`_ library
(imported only here, and only when such a bag is read).  :class:`RosbagsSource` hands out the
same :class:`~inertia_ros.io.mcap_chunks.MessageBatch` objects as
:meth:`McapReader.iter_batches <inertia_ros.io.mcap_reader.McapReader.iter_batches>`, so the
raw CDR payloads go through the same vectorised decoder and cleaning.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from inertia_ros.io.mcap_chunks import ChannelFilter, MessageBatch
from inertia_ros.io.mcap_codecs import MAX_CHUNK_BYTES, decompress
from inertia_ros.io.mcap_reader import Damage
from inertia_ros.io.mcap_records import Channel, McapError, Schema
from inertia_ros.io.rosbag2 import BagInfo

#: The rosbags release this code is tested with (requirements.txt pins it).
ROSBAGS_PIN = 'rosbags==0.11.9'


class RosbagsError(ValueError):
    """The bag cannot be read through rosbags; the message is one line with the fix."""


def _import_rosbag2(info: BagInfo) -> Any:
    what = (f'{info.storage} storage' if info.storage != 'mcap'
            else f'{info.compression_format}-compressed ({info.compression_mode.lower()}) bags')
    try:
        from rosbags import rosbag2
    except ImportError as exc:
        missing = getattr(exc, 'name', None) or 'rosbags'
        raise RosbagsError(f'{info.directory}: reading {what} needs the Python package '
                           f'{missing!r} (missing): pip install {ROSBAGS_PIN}') from None
    return rosbag2


class _BoundedZstd:
    """Stands in for the ``zstd`` module inside rosbags' reader: bounded output.

    rosbags decompresses message-compressed payloads with ``zstd.decompress(data)`` and
    file-compressed storage files with ``zstd.open``, trusting the frame's own size; here a
    payload is limited to ``per_message`` bytes and a file to ``per_file`` bytes (the free
    space of the temporary directory it is written to), so a bomb is an error, not a memory
    or disk spike.
    """

    def __init__(self, real: Any, per_message: int, per_file: int) -> None:
        self._real = real
        self._per_message = per_message
        self._per_file = per_file

    def __getattr__(self, name: str) -> Any:
        return getattr(self._real, name)

    def decompress(self, data: bytes) -> bytes:
        d = self._real.ZstdDecompressor()
        out = d.decompress(data, max_length=self._per_message + 1)
        if len(out) > self._per_message:
            raise McapError(f'a zstd-compressed message expands past {self._per_message} '
                            'bytes (a decompression bomb or damaged data)')
        if not d.eof:
            raise McapError('a zstd-compressed message is truncated')
        return out

    def open(self, fh: Any, mode: str = 'rb') -> Any:
        return _CappedReader(self._real.open(fh, mode), self._per_file)


class _CappedReader:
    """A file-like reader that raises once more than ``limit`` bytes were read."""

    def __init__(self, inner: Any, limit: int) -> None:
        self._inner = inner
        self._left = limit

    def __enter__(self) -> _CappedReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self._inner.close()

    def read(self, n: int = -1) -> bytes:
        data = self._inner.read(n if n is not None and n >= 0 else 1 << 20)
        self._left -= len(data)
        if self._left < 0:
            raise McapError('a zstd-compressed bag file expands past the free space of the '
                            'temporary directory (a decompression bomb or a huge bag)')
        return data

    def readinto(self, buf: Any) -> int:
        data = self.read(len(buf))
        buf[:len(data)] = data
        return len(data)


class _Bounded:
    """Context manager: rosbags' decompression bounded while one of our reads runs."""

    def __init__(self, per_message: int = MAX_CHUNK_BYTES) -> None:
        self._per_message = per_message
        self._saved: list[tuple[Any, str, Any]] = []

    def __enter__(self) -> _Bounded:
        import shutil
        import tempfile

        from rosbags.rosbag2 import reader, storage_mcap

        free = shutil.disk_usage(tempfile.gettempdir()).free
        self._saved = [(reader, 'zstd', reader.zstd)]
        reader.zstd = _BoundedZstd(reader.zstd, self._per_message, max(free - (1 << 30), 0))
        table = storage_mcap.DECOMPRESSORS
        for codec in ('lz4', 'zstd'):
            self._saved.append((table, codec, table[codec]))
            table[codec] = (lambda c: lambda data, size: decompress(
                c, data, size, limit=self._per_message))(codec)
        return self

    def __exit__(self, *exc: object) -> None:
        for owner, key, val in reversed(self._saved):
            if isinstance(owner, dict):
                owner[key] = val
            else:
                setattr(owner, key, val)
        self._saved = []


class RosbagsSource:
    """Read a rosbag2 bag through ``rosbags``, batch by batch, like :class:`McapReader`.

    Parameters
    ----------
    info : BagInfo
        The validated metadata of the bag directory.
    progress : callable, optional
        ``progress(messages_done, messages_total)`` while reading.
    batch : int
        Messages per :class:`MessageBatch` (memory is about ``batch`` payloads at a time).

    Attributes
    ----------
    channels, schemas : dict
        One :class:`Channel` (and :class:`Schema` naming its message type) per rosbag2
        connection, by connection id.
    metadata : list
        Always empty (rosbag2 metadata records are not exposed by rosbags).
    damage : Damage
        Stays empty: rosbags raises rather than skipping damage; that is turned into a
        :class:`RosbagsError`.
    messages_read : int
        Messages read so far.
    """

    def __init__(self, info: BagInfo, *, progress: Callable[[int, int], None] | None = None,
                 batch: int = 4096) -> None:
        self.info = info
        self.path = info.directory
        self._progress = progress
        self._batch = int(batch)
        self.channels: dict[int, Channel] = {}
        self.schemas: dict[int, Schema] = {}
        self.metadata: list = []
        self.damage = Damage()
        self.messages_read = 0
        rosbag2 = _import_rosbag2(info)
        try:
            self._reader = rosbag2.Reader(self.path)
            with _Bounded():
                self._reader.open()
        except Exception as exc:  # rosbags raises ReaderError, apsw/sqlite and codec errors
            raise RosbagsError(self._explain(exc)) from None
        for c in self._reader.connections:
            self.schemas[c.id] = Schema(c.id, c.msgtype, 'ros2msg', b'')
            self.channels[c.id] = Channel(c.id, c.id, c.topic, 'cdr', {})

    def _explain(self, exc: BaseException) -> str:
        text = ' '.join(str(exc).split()) or exc.__class__.__name__
        if isinstance(exc, ImportError):
            name = getattr(exc, 'name', None) or 'a codec'
            return (f'{self.path}: reading this bag needs the Python package {name!r} '
                    f'(missing): pip install {name}')
        return (f'{self.path}: rosbags cannot read this {self.info.storage} bag ({text}); check '
                'the bag with "ros2 bag info"')

    def __enter__(self) -> RosbagsSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the bag (and remove rosbags' temporary decompressed files)."""
        try:
            self._reader.close()
        except Exception:  # closing a half-opened reader must not mask the first error
            pass

    def iter_batches(self, select: ChannelFilter | None = None) -> Iterator[MessageBatch]:
        """Yield the messages of the selected connections as :class:`MessageBatch` objects.

        Parameters
        ----------
        select : callable, optional
            ``select(channel, schema) -> bool`` picks the channels (all if None).

        Yields
        ------
        MessageBatch
            Consecutive runs of one channel's messages, in bag order; ``ordinal`` numbers
            every message read (0 = first), so arrival order is kept across batches.
        """
        conns = [c for c in self._reader.connections
                 if select is None or select(self.channels[c.id], self.schemas[c.id])]
        if not conns:
            return
        total = int(sum(getattr(c, 'msgcount', 0) or 0 for c in conns))
        pend: dict[int, tuple[list[bytes], list[int], list[int]]] = {}
        try:
            bounded = _Bounded()
            bounded.__enter__()
            for conn, stamp, data in self._reader.messages(connections=conns):
                p = pend.setdefault(conn.id, ([], [], []))
                p[0].append(bytes(data))
                p[1].append(int(stamp))
                p[2].append(self.messages_read)
                self.messages_read += 1
                if len(p[0]) >= self._batch:
                    yield self._make(conn.id, pend.pop(conn.id))
                    if self._progress is not None:
                        self._progress(self.messages_read, max(total, self.messages_read))
        except Exception as exc:  # sqlite/apsw errors, zstd errors, rosbags ReaderError
            raise RosbagsError(self._explain(exc)) from None
        finally:
            bounded.__exit__()
        for cid in list(pend):
            yield self._make(cid, pend.pop(cid))

    def _make(self, cid: int, p: tuple[list[bytes], list[int], list[int]]) -> MessageBatch:
        payloads, stamps, ords = p
        lens = np.fromiter((len(b) for b in payloads), dtype=np.int64, count=len(payloads))
        starts = np.zeros(len(payloads), dtype=np.int64)
        np.cumsum(lens[:-1], out=starts[1:])
        buf = np.frombuffer(b''.join(payloads), dtype=np.uint8)
        ch = self.channels[cid]
        return MessageBatch(ch, self.schemas[cid], buf, starts, lens,
                            np.asarray(stamps, dtype=np.uint64), np.asarray(ords, np.int64))

