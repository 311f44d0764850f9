"""MCAP chunks: loading them into shared buffers and handing out their messages in bulk.

A chunk's records are read (positional reads) and decompressed straight into a slot of a
:class:`ChunkGroup` buffer, which holds consecutive chunks back to back; :func:`locate_messages`
finds each chunk's Message records (from its message indexes, scanning what they do not
cover) and :func:`group_batches` gives the messages of a group as one :class:`MessageBatch`
per channel, ready for vectorised decoding (:mod:`inertia_ros.io.cdr_decode`).
:class:`ChunkFiller` does the loading and touches nothing else, so that it can run on the
reader's worker thread.
"""
from __future__ import annotations

import os
import struct
import sys
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, BinaryIO

import numpy as np

from inertia_ros.io.mcap_codecs import codec_module, decompress_into
from inertia_ros.io.mcap_records import (
    MSG_FIELDS,
    MSG_HEAD,
    OP_CHANNEL,
    OP_CHUNK,
    OP_MESSAGE,
    OP_SCHEMA,
    U32,
    U64,
    Channel,
    Chunk,
    McapError,
    Schema,
    parse_record,
)
from inertia_ros.io.mcap_scan import gather_u64, record_offsets, u64_at


@dataclass(frozen=True)
class MessageBatch:
    """Messages of one channel from one chunk (or a run of unchunked messages).

    Payload ``k`` is ``buf[starts[k]:starts[k] + lengths[k]]``.

    Attributes
    ----------
    channel : Channel
        The channel the messages were published on.
    schema : Schema or None
        Its schema (None for schemaless channels).
    buf : numpy.ndarray
        uint8 array (B,), the buffer holding the payloads (a decompressed chunk).
    starts : numpy.ndarray
        int64 array (n,), byte offsets of the payloads in ``buf``.
    lengths : numpy.ndarray
        int64 array (n,), payload lengths [bytes].
    log_time : numpy.ndarray
        uint64 array (n,), MCAP log times [ns].
    ordinal : numpy.ndarray
        int64 array (n,), the position of each message in the file (0 = first message), so
        that arrival order can be restored across batches.
    sequence : numpy.ndarray or None
        uint32 array (n,), the Message records' ``sequence`` fields (the publisher's or
        recorder's counter; 0 when the writer does not set it), None when unknown.
    """

    channel: Channel
    schema: Schema | None
    buf: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    log_time: np.ndarray
    ordinal: np.ndarray
    sequence: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.starts.shape[0])

    def payload(self, k: int) -> bytes:
        """Return payload ``k`` as bytes (a copy)."""
        s = int(self.starts[k])
        return self.buf[s:s + int(self.lengths[k])].tobytes()


ChannelFilter = Callable[[Channel, Schema | None], bool]
CHUNK_HEAD = struct.Struct('<QQQI')


#: A Message record's head as it lies in the buffer (unaligned): opcode, record length,
#: channel id, sequence, log time [ns].
HEAD_DT = np.dtype({'names': ['op', 'len', 'chan', 'seq', 'log_time'],
                     'formats': ['u1', '<u8', '<u2', '<u4', '<u8'],
                     'offsets': [0, 1, 9, 11, 15], 'itemsize': 23})


HEAD_V = np.dtype(f'V{HEAD_DT.itemsize}')


@dataclass(frozen=True)
class Extent:
    """Where a record body lies in the file: ``length`` bytes from offset ``start``."""

    start: int
    length: int


@dataclass
class PendingChunk:
    """A chunk whose records are being loaded into a group slot (or the error that stopped it).

    ``result`` is ``(error, crc)`` once loaded: a :class:`McapError` (or None) and the
    CRC-32 of the uncompressed records (0 when the chunk declares none); while the chunk is
    loaded on the reader's worker thread it is that thread's loader, which gives the pairs
    in the order the chunks were handed to it.  ``indexes`` are the
    chunk's MessageIndex records (channel id -> (k, 2) array of log time and offset), which
    follow the chunk in the file; ``seen`` is the number of data-section bytes read up to
    and including the chunk, for the reader's bytes-per-message estimate once it is checked.
    """

    off: int
    chunk: Chunk
    stored: int
    group: ChunkGroup | None
    at: int
    result: Any
    indexes: dict[int, np.ndarray] = field(default_factory=dict)
    seen: int = 0
    need: int = 0

    def outcome(self) -> tuple[McapError | None, int]:
        """``(error, crc)``, waiting for the worker thread if it is still loading the chunk.

        Chunks loaded on the worker must be asked for in the order they were handed to it.
        """
        if not isinstance(self.result, tuple):      # the worker's loader
            self.result = self.result.result()
        return self.result


class ChunkGroup:
    """Consecutive chunks' records, back to back in one buffer, and their messages.

    Slots are reserved in file order (``reserved`` is where the next one starts) and a
    chunk's messages are committed once it is checked; a damaged chunk leaves an unused
    slot.  The buffers come from ``pool`` (the reader's) and go back to it: a buffer is
    reused only when nothing outside the pool refers to it any more (no batch, view or
    decoded array of an earlier group), so reuse never changes what a caller holds, and
    fresh memory (and its page faults) is paid for once rather than once per group.
    """

    #: Buffers kept for reuse: one a caller may still read, one being finished, one filling.
    POOL = 3

    def __init__(self, pool: list[np.ndarray], capacity: int) -> None:
        self.pool = pool
        self.capacity = capacity
        self.buf: np.ndarray = _EMPTY
        self.reserved = 0
        self.used = 0
        self.loading = 0            # chunks with a slot here not yet checked
        self.offs: list[np.ndarray] = []
        self.heads: list[np.ndarray] = []
        self.bases: list[int] = []

    def fits(self, need: int) -> bool:
        """Whether ``need`` more bytes fit the current buffer (True for an empty group)."""
        return self.reserved == 0 or self.reserved + need <= self.buf.shape[0]

    def slot(self, need: int) -> tuple[int, memoryview]:
        """Reserve the ``need`` bytes after the group's slots: (offset, writable view)."""
        if self.reserved + need > self.buf.shape[0]:
            assert self.reserved == 0, 'start a new group before this one overflows'
            if self.buf is not _EMPTY:
                self.pool.append(self.buf)
            self.buf = self._take(need)
        at = self.reserved
        self.reserved += need
        self.loading += 1
        return at, memoryview(self.buf)[at:at + need]

    def _take(self, need: int) -> np.ndarray:
        """A free pooled buffer of at least ``need`` bytes, or a new one."""
        for k in range(len(self.pool)):
            # free when only the pool list (and getrefcount's argument) refers to it
            if self.pool[k].shape[0] >= need and sys.getrefcount(self.pool[k]) <= 2:
                return self.pool.pop(k)
        return np.empty(max(need, self.capacity), dtype=np.uint8)

    def records(self, at: int, size: int) -> np.ndarray:
        """The ``size`` bytes of the slot at ``at``, as a uint8 array."""
        return self.buf[at:at + size]

    def commit(self, at: int, size: int, offs: np.ndarray, heads: np.ndarray,
               base: int) -> None:
        """Keep the messages (chunk offsets, heads) of the ``size``-byte slot at ``at``."""
        if offs.shape[0]:
            self.offs.append(offs + at)
            self.heads.append(heads)
            self.bases.append(base)
            self.used = max(self.used, at + size)

    def reset(self) -> None:
        """Empty the group; its buffer goes back to the pool."""
        if self.buf is not _EMPTY:
            self.pool.append(self.buf)
            del self.pool[:-self.POOL]
        self.buf = _EMPTY
        self.reserved = self.used = self.loading = 0
        self.offs, self.heads, self.bases = [], [], []


_EMPTY = np.zeros(0, dtype=np.uint8)


def pread_into(fd: int, out: memoryview, at: int) -> int:
    """Read ``len(out)`` bytes of file ``fd`` from offset ``at`` into ``out``; bytes read.

    Positional reads (no shared file position), so a worker thread can read while the
    reader goes on through the file.
    """
    got = 0
    while got < len(out):
        if hasattr(os, 'preadv'):
            n = os.preadv(fd, [out[got:]], at + got)
        else:                                       # pragma: no cover (not Linux/BSD)
            data = os.pread(fd, len(out) - got, at + got)
            out[got:got + len(data)] = data
            n = len(data)
        if n <= 0:
            break
        got += n
    return got


def read_chunk_header(fh: BinaryIO, ext: Extent) -> tuple[Chunk, int | bytes, int]:
    """Read a Chunk record's fields, not its records.

    Parameters
    ----------
    fh : binary file
        The MCAP file (its position is moved).
    ext : Extent
        Where the Chunk record's body lies in the file.

    Returns
    -------
    tuple
        ``(chunk, at, stored)``: the Chunk with empty ``records``, the file offset of its
        records (or the records themselves, when the header had to be read whole) and their
        length [bytes].  A header that does not parse at a glance is read and parsed whole,
        so damage gives the same error as :func:`~inertia_ros.io.mcap_records.parse_record`.

    Raises
    ------
    McapError, UnicodeDecodeError
        An unreadable chunk header.
    """
    fh.seek(ext.start)
    head = fh.read(min(ext.length, 256))
    if len(head) >= 40:
        c_len = U32.unpack_from(head, 28)[0]
        if 40 + c_len <= len(head):
            t0, t1, usize, crc = CHUNK_HEAD.unpack_from(head, 0)
            stored = U64.unpack_from(head, 32 + c_len)[0]
            if 40 + c_len + stored <= ext.length:
                comp = head[32:32 + c_len].decode('utf-8')
                return (Chunk(t0, t1, usize, crc, comp, b''), ext.start + 40 + c_len,
                        stored)
    fh.seek(ext.start)
    rec = parse_record(OP_CHUNK, fh.read(ext.length))
    assert isinstance(rec, Chunk)
    return rec, rec.records, len(rec.records)


class ChunkFiller:
    """Loads chunks' records into buffer slots: ``filler(*job) -> (error, crc)``.

    Reads with positional reads and touches nothing but its zstd decompressor (created at
    the first zstd chunk and reused), so it can run on the reader's worker thread (one
    chunk at a time, in file order); the file reads, zstd decompression and CRC all release
    the GIL.

    Parameters
    ----------
    fd : int
        File descriptor of the MCAP file.
    """

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._dctx: Any = None

    def __call__(self, compression: str, at: int | bytes, stored: int, slot: memoryview,
                 size: int, want_crc: bool) -> tuple[McapError | None, int]:
        """Load a chunk's records into ``slot`` and compute their CRC: ``(error, crc)``.

        Parameters
        ----------
        compression : str
            The chunk's compression (``''``, ``'zstd'`` or ``'lz4'``).
        at : int or bytes
            File offset of the chunk's (compressed) records, or the records themselves.
        stored : int
            Their length in the file [bytes].
        slot : memoryview
            Writable bytes for the uncompressed records (released on return).
        size : int
            The uncompressed size the chunk declares [bytes].
        want_crc : bool
            Compute the CRC-32 of the uncompressed records (0 otherwise).

        Returns
        -------
        tuple
            ``(error, crc)``: failures are returned (a :class:`McapError`, codec missing
            included), to be counted once the chunk's message indexes (which say how many
            messages were lost) have been read.
        """
        try:
            if compression == '' and isinstance(at, int):
                got = pread_into(self.fd, slot[:size], at)
                if got != size:
                    raise McapError(f'uncompressed chunk holds {got} bytes, declared {size}')
            else:
                data = os.pread(self.fd, stored, at) if isinstance(at, int) else at
                if compression == 'zstd' and self._dctx is None:
                    self._dctx = codec_module('zstd').ZstdDecompressor()
                decompress_into(compression, data, slot, size, self._dctx)
            return None, (zlib.crc32(slot[:size]) if want_crc else 0)
        except McapError as exc:          # CodecMissingError included
            return exc, 0
        finally:
            slot.release()


def _indexed_messages(arr: np.ndarray, heads_at: np.ndarray | None,
                      indexes: dict[int, np.ndarray]
                      ) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]] | None:
    """Messages located by a chunk's message indexes, if they are consistent.

    Returns ``(offsets, heads, spans)`` (``spans`` the byte ranges the indexes leave
    uncovered, to be scanned), or None when the indexes are empty or do not match the
    records (the whole chunk is then scanned).
    """
    size = arr.shape[0]
    parts = [v[:, 1] for v in indexes.values()]
    offs = (np.concatenate(parts) if len(parts) > 1 else parts[0]).astype(np.int64)
    offs.sort(kind='stable')         # merges the channels' sorted runs
    if not (offs.size > 0 and offs[0] >= 0 and offs[-1] + MSG_HEAD <= size):
        return None
    assert heads_at is not None
    heads = heads_at[offs]
    fields = heads.view(HEAD_DT)
    if not (bool(np.all(fields['op'] == OP_MESSAGE)) and bool(np.all(offs[1:] > offs[:-1]))):
        return None
    lens = fields['len']
    if not bool(np.all((lens >= MSG_FIELDS.size) & (lens <= size))):
        return None
    ends = offs + 9 + lens.astype(np.int64)
    if not (bool(np.all(ends[:-1] <= offs[1:])) and int(ends[-1]) <= size):
        return None
    gaps = np.flatnonzero(offs[1:] > ends[:-1])
    spans = [(int(ends[g]), int(offs[g + 1])) for g in gaps.tolist()]
    if offs[0] > 0:
        spans.insert(0, (0, int(offs[0])))
    if ends[-1] < size:
        spans.append((int(ends[-1]), size))
    return offs, heads, spans


def locate_messages(arr: np.ndarray, indexes: dict[int, np.ndarray],
                    register: Callable[[int, bytes], None]) -> tuple[np.ndarray, np.ndarray]:
    """Return (offsets, heads) of every Message record in a chunk, in file order.

    Message indexes locate the messages; the byte ranges they do not cover are scanned
    record by record, so a chunk with missing or partial indexes is still read completely.

    Parameters
    ----------
    arr : numpy.ndarray
        uint8 array (B,), the chunk's uncompressed records.
    indexes : dict
        The chunk's MessageIndex records: channel id -> (k, 2) uint64 array of log time
        [ns] and byte offset in the chunk.
    register : callable
        ``register(opcode, body)`` is called for each Schema and Channel record met while
        scanning, in chunk order.

    Returns
    -------
    offsets : numpy.ndarray
        int64 (n,), byte offsets of the Message records in ``arr``.
    heads : numpy.ndarray
        :data:`HEAD_V` (n,) (:data:`HEAD_DT` once viewed): each record's opcode, length,
        channel id, sequence and log time, gathered while the chunk is fresh in the cache.

    Raises
    ------
    McapError
        Records that do not parse (garbage, a record past the end, a short message).
    """
    size = arr.shape[0]
    if size < MSG_HEAD:
        heads_at = None
    else:
        # plain void items: gathering and joining them is several times faster than
        # with the structured dtype, which only views the result
        heads_at = np.ndarray(shape=(size - HEAD_DT.itemsize + 1,), dtype=HEAD_V,
                              buffer=arr, strides=(1,))
    offs_list: list[np.ndarray] = []
    heads_list: list[np.ndarray] = []
    found = _indexed_messages(arr, heads_at, indexes) if indexes else None
    spans = [(0, size)]
    if found is not None:
        offs_list.append(found[0])
        heads_list.append(found[1])
        spans = found[2]
    for s0, s1 in spans:
        recs = record_offsets(arr, s0, s1, keep=(OP_MESSAGE, OP_SCHEMA, OP_CHANNEL))
        ops = arr[recs]
        for o in recs[(ops == OP_SCHEMA) | (ops == OP_CHANNEL)].tolist():
            ln = u64_at(arr, o + 1)
            register(int(arr[o]), arr[o + 9:o + 9 + ln].tobytes())
        msgs = recs[ops == OP_MESSAGE]
        if msgs.size:
            short = gather_u64(arr, msgs + 1) < MSG_FIELDS.size
            if short.any():
                raise McapError(f'{int(short.sum())} message record(s) shorter than the '
                                f'{MSG_FIELDS.size}-byte message header')
            assert heads_at is not None
            offs_list.append(msgs)
            heads_list.append(heads_at[msgs])
    if not offs_list:
        return np.zeros(0, np.int64), np.zeros(0, HEAD_V)
    if len(offs_list) == 1:
        return offs_list[0], heads_list[0]
    offs = np.concatenate(offs_list)
    order = np.argsort(offs, kind='stable')
    return offs[order], np.concatenate(heads_list)[order]


def group_batches(group: ChunkGroup, wanted: Callable[[int], bool],
                  channels: dict[int, Channel],
                  schemas: dict[int, Schema]) -> Iterator[MessageBatch]:
    """One batch per wanted channel over a run of consecutive chunks.

    The chunks' records lie back to back in the group's buffer, so the per-batch work of
    the caller (decoding) runs once per run of chunks rather than once per chunk.

    Parameters
    ----------
    group : ChunkGroup
        The run of chunks, their messages committed.
    wanted : callable
        ``wanted(channel_id) -> bool``: the channels to give out.
    channels, schemas : dict
        The file's Channel and Schema records by id.

    Yields
    ------
    MessageBatch
        One per wanted channel with messages in the group, in channel-id order.
    """
    arr = group.buf[:group.used]
    if len(group.offs) == 1:
        offs, heads = group.offs[0], group.heads[0]
        ords = group.bases[0] + np.arange(offs.shape[0], dtype=np.int64)
    else:
        offs = np.concatenate(group.offs)
        heads = np.concatenate(group.heads)
        ords = np.concatenate([b + np.arange(o.shape[0], dtype=np.int64)
                               for o, b in zip(group.offs, group.bases, strict=True)])
    chans = heads.view(HEAD_DT)['chan']
    # channel ids are uint16: a count per id is cheaper than np.unique's hashing
    for ch_id in np.flatnonzero(np.bincount(chans)).tolist():
        if not wanted(ch_id):
            continue
        sel = np.flatnonzero(chans == ch_id)
        h = heads[sel].view(HEAD_DT)
        ch = channels[ch_id]
        yield MessageBatch(ch, schemas.get(ch.schema_id), arr, offs[sel] + MSG_HEAD,
                           h['len'].astype(np.int64) - MSG_FIELDS.size,
                           h['log_time'].astype(np.uint64), ords[sel],
                           h['seq'].astype(np.uint32))


def batches_from_records(recs: list[tuple[int, bytes]], ords: list[int],
                         channels: dict[int, Channel],
                         schemas: dict[int, Schema]) -> Iterator[MessageBatch]:
    """Batches from a run of unchunked Message record bodies.

    Parameters
    ----------
    recs : list of (int, bytes)
        ``(channel_id, body)`` per wanted message, in file order.
    ords : list of int
        Each message's position in the file (0 = first message).
    channels, schemas : dict
        The file's Channel and Schema records by id.

    Yields
    ------
    MessageBatch
        One per channel, in order of first appearance.
    """
    by_ch: dict[int, list[int]] = {}
    for k, (ch_id, _) in enumerate(recs):
        by_ch.setdefault(ch_id, []).append(k)
    for ch_id, ks in by_ch.items():
        bodies = [recs[k][1] for k in ks]
        lens = np.array([len(b) - MSG_FIELDS.size for b in bodies], dtype=np.int64)
        buf = np.frombuffer(b''.join(b[MSG_FIELDS.size:] for b in bodies), dtype=np.uint8)
        starts = np.zeros(len(ks), dtype=np.int64)
        np.cumsum(lens[:-1], out=starts[1:])
        log_time = np.array([U64.unpack_from(b, 6)[0] for b in bodies], dtype=np.uint64)
        seq = np.array([U32.unpack_from(b, 2)[0] for b in bodies], dtype=np.uint32)
        ch = channels[ch_id]
        yield MessageBatch(ch, schemas.get(ch.schema_id), buf, starts, lens, log_time,
                           np.asarray([ords[k] for k in ks], dtype=np.int64), seq)
