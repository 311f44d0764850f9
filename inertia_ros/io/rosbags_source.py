"""Every other rosbag2 storage (sqlite3, file- or message-compressed) read through ``rosbags``.

Our own MCAP reader (:mod:`inertia_ros.io.mcap_reader`) is the fast path for plain MCAP.
Bags it cannot read — ``.db3`` (sqlite3) storage, and bags whose files or messages are
zstd-compressed — are read with the `rosbags <https://gitlab.com/ternaris/rosbags>`_ library
(imported only here, and only when such a bag is read).  :class:`RosbagsSource` hands out the
same :class:`~inertia_ros.io.mcap_reader.MessageBatch` objects as
:meth:`McapReader.iter_batches <inertia_ros.io.mcap_reader.McapReader.iter_batches>`, so the
raw CDR payloads go through the same vectorised decoder and cleaning.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from inertia_ros.io.mcap_reader import Channel, ChannelFilter, Damage, MessageBatch, Schema
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
        self._reader = rosbag2.Reader(self.path)
        try:
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

