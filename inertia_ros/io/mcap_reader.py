"""A streaming MCAP reader of our own, with a vectorised bulk path for message payloads.

Two ways in:

:func:`~inertia_ros.io.mcap_scan.iter_records`
    Every record of the file in file order, chunks expanded in place (their Schema, Channel
    and Message records are yielded where the chunk stood; the Chunk and MessageIndex records
    themselves are not).  This is what the MCAP conformance suite checks.
:class:`McapReader`
    Reads a file once, chunk by chunk, and hands out :class:`MessageBatch` objects: for one
    channel, the message payloads of one chunk as offsets into the decompressed chunk buffer,
    ready for vectorised decoding (:mod:`inertia_ros.io.cdr_decode`).  Message indexes, when
    present, locate the messages without a per-record Python loop.

Damaged files (truncated downloads, killed recorders, flipped bits) are read as far as they
are intact: a chunk whose CRC or decompression fails is skipped, a record running past the end
of the file ends the read, and :attr:`McapReader.damage` says what was lost.

The file is read with ordinary buffered and positional reads (never memory-mapped), so the
memory held at any time is a few groups of chunks, whatever the size of the file.

The reader's jobs live in their own modules: the record formats and parsing
(:mod:`~inertia_ros.io.mcap_records`), the codecs (:mod:`~inertia_ros.io.mcap_codecs`),
scanning records and the summary (:mod:`~inertia_ros.io.mcap_scan`) and loading chunks and
cutting them into batches (:mod:`~inertia_ros.io.mcap_chunks`); this module walks the file,
counts damage and runs the chunk-loading worker thread.
"""
from __future__ import annotations

import os
import struct
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from inertia_ros.io.mcap_chunks import (
    ChannelFilter,
    ChunkFiller,
    ChunkGroup,
    Extent,
    MessageBatch,
    PendingChunk,
    batches_from_records,
    group_batches,
    locate_messages,
    read_chunk_header,
)
from inertia_ros.io.mcap_codecs import MAX_CHUNK_BYTES, check_chunk_size
from inertia_ros.io.mcap_records import (
    MAGIC,
    MSG_FIELDS,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    REC_HEAD,
    U16,
    Channel,
    Chunk,
    ChunkIndex,
    CodecMissingError,
    Footer,
    Header,
    McapError,
    MessageIndex,
    Metadata,
    Schema,
    Statistics,
    parse_record,
)
from inertia_ros.io.mcap_scan import read_summary

#: Top-level records the batch reader reads; others (attachments, indexes, statistics) are
#: skipped without being read.
_READ_OPS = frozenset((0x01, 0x03, 0x04, 0x05, 0x06, 0x07, 0x0C, 0x0F))


@dataclass
class Damage:
    """What a read could not recover from a damaged file.

    Attributes
    ----------
    truncated : bool
        The file ends before its footer (or a record runs past the end of the file).
    corrupt_chunks : int
        Chunks skipped because their CRC, compression or records were bad.
    bytes_lost : int
        Bytes of the data section that could not be read [bytes].
    messages_lost : int
        Messages known to be lost (from chunk indexes/statistics) or, when the file gives no
        count, estimated from ``bytes_lost`` and the average record size read so far.
    notes : list of str
        One line per problem found.
    """

    truncated: bool = False
    corrupt_chunks: int = 0
    bytes_lost: int = 0
    messages_lost: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def any(self) -> bool:
        """True if anything was lost or found damaged."""
        return bool(self.truncated or self.corrupt_chunks or self.bytes_lost
                    or self.messages_lost or self.notes)


class _Loader:
    """A worker thread that loads chunks one after the other, in the order they are given.

    ``fill(*job)`` (a :class:`~inertia_ros.io.mcap_chunks.ChunkFiller`) runs on the thread;
    its results are taken with :meth:`result` in the same order.  Whatever it raises is
    raised again by :meth:`result`, in the caller's thread.  The thread is a daemon and
    :meth:`close` stops it after the job it is running (the jobs not started are dropped),
    so an error or Ctrl-C in the caller never waits for the rest of the file.
    """

    def __init__(self, fill: Callable[..., tuple[McapError | None, int]]) -> None:
        import queue  # only when a log is read with a worker
        import threading

        self._fill = fill
        self._jobs: Any = queue.SimpleQueue()
        self._done: Any = queue.SimpleQueue()
        self._stop = False
        self._thread = threading.Thread(target=self._run, name='mcap-chunks', daemon=True)
        self._thread.start()

    def submit(self, job: tuple) -> _Loader:
        """Queue ``fill(*job)``; returns the loader, to ask for the result."""
        self._jobs.put(job)
        return self

    def result(self) -> tuple[McapError | None, int]:
        """The result of the oldest job not yet asked for, waiting for it if need be."""
        ok, value = self._done.get()
        if not ok:
            raise value
        return value

    def _run(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None or self._stop:
                return
            try:
                self._done.put((True, self._fill(*job)))
            except BaseException as exc:     # handed to the caller's thread
                self._done.put((False, exc))

    def close(self) -> None:
        """Stop the thread once its current job is done, and wait for that."""
        self._stop = True
        self._jobs.put(None)
        self._thread.join()


def _cpus() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):              # pragma: no cover (not Linux)
        return os.cpu_count() or 1


def _nothing() -> None:
    """Do nothing (a default callback)."""


class McapReader:
    """Read an MCAP file once, chunk by chunk, tolerating damage.

    Parameters
    ----------
    path : str or Path
        The MCAP file.  It is opened read-only and never modified.
    progress : callable, optional
        Called as ``progress(bytes_done, bytes_total)`` after each top-level record batch.
    max_chunk_bytes : int
        Largest uncompressed chunk read [bytes]; larger ones (or chunks whose compressed data
        expands past their declared size) are counted as damaged chunks.  Memory use is
        bounded by a few times this, whatever the file holds.

    Examples
    --------
    >>> with McapReader('log.mcap') as r:                      # doctest: +SKIP
    ...     for batch in r.iter_batches(lambda ch, sc: ch.topic == '/imu'):
    ...         ...
    ...     print(r.damage)
    """

    #: Unchunked messages are grouped into batches of at most this many messages.
    UNCHUNKED_BATCH = 4096
    #: Consecutive chunks are decompressed back to back into one buffer, and given out as one
    #: batch per channel, up to about this many uncompressed bytes (bounded memory; one
    #: decode per run of chunks, not per chunk).
    GROUP_BYTES = 8 << 20
    #: Top-level records are read in blocks of at least this many bytes.
    BLOCK = 1 << 20
    #: Load chunks (file read, decompression, CRC: all release the GIL) on a worker thread
    #: (on a machine with more than one CPU), up to :attr:`LOOKAHEAD` bytes ahead of the
    #: chunk being checked, so that the next group of chunks loads while the caller decodes
    #: the last one.  Results never depend on it: chunks are checked, and damage counted, in
    #: file order as without it.  Loading only the next chunk ahead (one chunk in flight)
    #: measured no faster, since the worker then idled while a whole group was decoded; a
    #: group ahead takes ~0.1 s off the read of the one-hour log when a CPU is free (and
    #: costs ~0.05-0.1 s more CPU).
    THREADS = True
    #: With the worker thread: bytes of chunks loaded ahead of the chunk being checked
    #: (about one group; memory grows by about this much).
    LOOKAHEAD = 8 << 20

    def __init__(self, path: str | Path, *,
                 progress: Callable[[int, int], None] | None = None,
                 max_chunk_bytes: int = MAX_CHUNK_BYTES) -> None:
        self.path = Path(path)
        self.max_chunk_bytes = int(max_chunk_bytes)
        try:
            self._fh: BinaryIO = open(self.path, 'rb')
        except FileNotFoundError as exc:
            raise McapError(f'{self.path}: no such file') from exc
        except IsADirectoryError as exc:
            raise McapError(f'{self.path}: is a directory, not an MCAP file') from exc
        self.size = self.path.stat().st_size
        magic = self._fh.read(8)
        if magic != MAGIC:
            self._fh.close()
            what = 'empty file' if self.size == 0 else 'bad magic bytes'
            raise McapError(f'{self.path}: not an MCAP file ({what})')
        self._progress = progress
        self.header: Header | None = None
        self.footer: Footer | None = None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.statistics: Statistics | None = None
        self.chunk_indexes: list[ChunkIndex] = []
        self.metadata: list[Metadata] = []
        self.damage = Damage()
        self.messages_read = 0
        self._bytes_per_message = 0.0
        self._summary_ok = False
        self._buffers: list[np.ndarray] = []
        self._filler = ChunkFiller(self._fh.fileno())
        self._read_summary()

    # context manager ----------------------------------------------------------------------
    def __enter__(self) -> McapReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the file."""
        self._fh.close()

    # summary --------------------------------------------------------------------------------
    def _read_summary(self) -> None:
        """Read schemas, channels, statistics and chunk indexes from the summary, if intact."""
        found = read_summary(self._fh, self.size)
        self.footer = found.footer
        self.schemas.update(found.schemas)
        self.channels.update(found.channels)
        self.statistics = found.statistics
        self.chunk_indexes = found.chunk_indexes
        self._summary_ok = found.ok
        self.damage.notes.extend(found.notes)

    # top-level record stream ----------------------------------------------------------------
    def _top_level(self, lazy_chunks: bool = False, settle: Callable[[], None] | None = None
                   ) -> Iterator[tuple[int, int, bytes | Extent]]:
        """Yield (opcode, file_offset, body) for data-section records; stops at damage.

        With ``lazy_chunks`` a Chunk record's body is not read: an :class:`Extent` (where it
        is in the file) is yielded instead, and the caller reads what it needs of it before
        asking for the next record.  ``settle()``, if given, is called before damage is
        counted, so that the caller's chunks still being loaded are counted first.
        """
        settle = settle or _nothing
        fh = self._fh
        pos = 8
        fh.seek(pos)
        end = self.size
        if self._summary_ok and self.footer is not None and self.footer.summary_start:
            end = self.footer.summary_start
        chunk_starts = sorted(ci.chunk_start_offset for ci in self.chunk_indexes)
        chunk_len = {ci.chunk_start_offset: ci.chunk_length for ci in self.chunk_indexes}
        while pos < end:
            head = fh.read(9)
            if len(head) < 9:
                settle()
                self._lost(pos, 'file ends inside a record header')
                return
            op, ln = REC_HEAD.unpack(head)
            if pos in chunk_len and (op != OP_CHUNK or 9 + ln != chunk_len[pos]):
                # a damaged chunk header: the chunk index knows where the chunk ends
                settle()
                self.damage.notes.append(f'chunk header at byte {pos} damaged: its extent '
                                         'is taken from the chunk index')
                op, ln = OP_CHUNK, chunk_len[pos] - 9
            if op == 0 or pos + 9 + ln > self.size:
                # Garbage or a cut-off record: jump to the next indexed chunk if there is one.
                settle()
                nxt = next((s for s in chunk_starts if s > pos), None)
                reason = (f'invalid record at byte {pos}' if op == 0 else
                          f'record at byte {pos} (opcode 0x{op:02x}) runs past the end of '
                          f'the file')
                if nxt is None:
                    self._lost(pos, reason, None if op == 0 else 9 + ln)
                    return
                self.damage.notes.append(f'{reason}: skipped to the next chunk at byte {nxt}')
                self.damage.bytes_lost += nxt - pos
                pos = nxt
                fh.seek(pos)
                continue
            if op == OP_FOOTER:
                return
            if op not in _READ_OPS or ln > self.max_chunk_bytes + (1 << 20):
                # attachments and the like are never needed: skipped unread, whatever their
                # size; a needed record over the ceiling is damage, not an allocation
                if op in _READ_OPS:
                    settle()
                    what = 'chunk' if op == OP_CHUNK else f'record (opcode 0x{op:02x})'
                    if op == OP_CHUNK:
                        self._bad_chunk(pos, None, ln, f'{ln} bytes, over the limit of '
                                        f'{self.max_chunk_bytes}')
                    else:
                        self.damage.bytes_lost += 9 + ln
                        self.damage.notes.append(f'{what} at byte {pos} skipped: {ln} bytes, '
                                                 f'over the limit of {self.max_chunk_bytes}')
                pos += 9 + ln
                fh.seek(pos)
                continue
            if lazy_chunks and op == OP_CHUNK:
                yield op, pos, Extent(pos + 9, ln)
                pos += 9 + ln
                fh.seek(pos)
            else:
                body = fh.read(ln)
                yield op, pos, body
                pos += 9 + ln
            if self._progress is not None:
                self._progress(pos, self.size)
            if op == OP_DATA_END:
                return

    def _lost(self, pos: int, reason: str, declared: int | None = None) -> None:
        """Record that the file is unreadable from byte ``pos`` on.

        Without an intact summary the size of what followed is unknown: the loss is then
        estimated from the record cut off (``declared`` bytes long) and is a lower bound.
        """
        self.damage.truncated = True
        lost = max(self.size - pos, 0)
        self.damage.bytes_lost += lost
        bound = ''
        if self.statistics is not None:
            msgs = max(self.statistics.message_count - self.messages_read, 0)
        else:
            known = max(lost, declared or 0)
            msgs = (int(round(known / self._bytes_per_message))
                    if self._bytes_per_message > 0 else 0)
            bound = 'at least '
        self.damage.messages_lost += msgs
        if bound and msgs == 0:
            count = 'an unknown number of messages'
        else:
            count = f'{bound}~{msgs} messages'
        self.damage.notes.append(f'{reason}: {lost} bytes unreadable, {count} lost')

    # bulk batches ---------------------------------------------------------------------------
    def iter_batches(self, select: ChannelFilter | None = None) -> Iterator[MessageBatch]:
        """Yield the messages of the selected channels as :class:`MessageBatch` objects.

        Parameters
        ----------
        select : callable, optional
            ``select(channel, schema) -> bool`` picks the channels to read (all if None).  It
            is called once per channel, when the channel is first seen.

        Yields
        ------
        MessageBatch
            Batches in file order of their chunks; within a batch, file order.
        """
        worker = _Loader(self._filler) if self.THREADS and _cpus() > 1 else None
        try:
            yield from _BatchStream(self, select, worker).run()
        finally:
            if worker is not None:
                worker.close()

    def _other_record(self, op: int, body: bytes) -> None:
        """Register a top-level Schema/Channel/Header/Metadata record."""
        if op not in (OP_SCHEMA, OP_CHANNEL, OP_HEADER, OP_METADATA):
            return
        try:
            rec = parse_record(op, body)
        except (McapError, UnicodeDecodeError) as exc:
            self.damage.notes.append(f'unreadable record (opcode 0x{op:02x}): {exc}')
            return
        if isinstance(rec, Schema):
            self.schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            self.channels[rec.id] = rec
        elif isinstance(rec, Header):
            self.header = rec
        elif isinstance(rec, Metadata):
            self.metadata.append(rec)

    def _bad_chunk(self, off: int, n_msgs: int | None, size: int, reason: str) -> None:
        """Count a chunk at file offset ``off`` skipped as unreadable.

        ``n_msgs`` is the message count its indexes give, or None to estimate it from its
        uncompressed ``size`` [bytes] and the average message size read so far.
        """
        self.damage.corrupt_chunks += 1
        if n_msgs is None:
            n_msgs = (int(round(size / self._bytes_per_message))
                      if self._bytes_per_message > 0 else 0)
        self.damage.messages_lost += n_msgs
        self.damage.bytes_lost += size
        self.damage.notes.append(
            f'chunk at byte {off} skipped: {reason} (~{n_msgs} messages lost)')


    def _chunk_messages(self, done: PendingChunk, indexes: dict[int, np.ndarray]) -> None:
        """Check one loaded chunk and locate its messages; add them to its group.

        A damaged chunk (decompression, CRC or records) is counted and left out (its slot
        stays unused); a chunk without messages adds nothing.
        """
        off, chunk = done.off, done.chunk
        n_idx = sum(len(v) for v in indexes.values()) or None
        error, crc = done.outcome()
        if isinstance(error, CodecMissingError):
            raise CodecMissingError(f'{self.path}: {error}') from None
        if error is not None:
            self._bad_chunk(off, n_idx, min(chunk.uncompressed_size, done.stored), str(error))
            return
        assert done.group is not None
        arr = done.group.records(done.at, chunk.uncompressed_size)
        if chunk.uncompressed_crc and crc != chunk.uncompressed_crc:
            self._bad_chunk(off, n_idx, chunk.uncompressed_size,
                            'CRC mismatch')
            return
        try:
            offs, heads = locate_messages(arr, indexes, self._other_record)
        except (McapError, struct.error, UnicodeDecodeError) as exc:
            self._bad_chunk(off, n_idx, chunk.uncompressed_size,
                            f'bad records ({exc})')
            return
        base = self.messages_read
        self.messages_read += offs.shape[0]
        done.group.commit(done.at, chunk.uncompressed_size, offs, heads, base)

    # convenience ----------------------------------------------------------------------------
    def iter_messages(self, select: ChannelFilter | None = None
                      ) -> Iterator[tuple[Schema | None, Channel, int, bytes]]:
        """Yield ``(schema, channel, log_time_ns, payload)`` per message (slow; for tests)."""
        for b in self.iter_batches(select):
            for k in range(len(b)):
                yield b.schema, b.channel, int(b.log_time[k]), b.payload(k)


class _BatchStream:
    """One pass of :meth:`McapReader.iter_batches`: chunks loading, groups filling.

    ``loading`` holds the chunks, in file order, whose records are loaded or loading but not
    yet checked; the MessageIndex records after a chunk go to the last one (to the next
    chunk, through ``stray``, when none is loading).  Groups of chunks wait in ``full``
    until their chunks are all checked and are then given out.  Without a worker thread
    each chunk is checked as soon as the next one is met; with one, up to
    :attr:`McapReader.LOOKAHEAD` more bytes load while earlier chunks are checked and
    decoded.  Unchunked messages wait in ``pending`` (with their file positions in
    ``pend_ord``) and are given out in runs.
    """

    def __init__(self, reader: McapReader, select: ChannelFilter | None,
                 worker: _Loader | None) -> None:
        self.reader = reader
        self.select = select
        self.decided: dict[int, bool] = {}
        self.pending: list[tuple[int, bytes]] = []
        self.pend_ord: list[int] = []
        self.loading: deque[PendingChunk] = deque()
        self.queued = 0                    # bytes of the chunks in ``loading``
        self.stray: dict[int, np.ndarray] = {}
        self.bytes_seen = 0
        self.cap = reader.GROUP_BYTES + (2 << 20)
        self.group = ChunkGroup(reader._buffers, self.cap)
        self.full: deque[ChunkGroup] = deque()
        self.worker = worker
        self.ahead = reader.LOOKAHEAD if worker is not None else 0

    def run(self) -> Iterator[MessageBatch]:
        """Read the file's data section, yielding batches in file order."""
        r = self.reader
        for op, off, body in r._top_level(lazy_chunks=True, settle=self.settle):
            if op == OP_MESSAGE_INDEX:
                assert isinstance(body, bytes)
                self._index(body)
                continue
            if op == OP_CHUNK:
                assert isinstance(body, Extent)
                yield from self._chunk(off, body)
                continue
            yield from self.flush_groups()     # batches stay in file order
            assert isinstance(body, bytes)
            if op == OP_MESSAGE:
                if self._message(off, body):
                    yield from self.flush_unchunked()
                continue
            yield from self.flush_unchunked()
            r._other_record(op, body)
        yield from self.flush_groups()
        yield from self.flush_unchunked()

    def wanted(self, ch_id: int) -> bool:
        """Whether channel ``ch_id`` is read (``select`` asked once per defined channel)."""
        ok = self.decided.get(ch_id)
        if ok is None:
            r = self.reader
            ch = r.channels.get(ch_id)
            if ch is None:
                return False  # not (yet) defined: cannot be decoded
            ok = True if self.select is None else bool(
                self.select(ch, r.schemas.get(ch.schema_id)))
            self.decided[ch_id] = ok
        return ok

    def _index(self, body: bytes) -> None:
        """File a MessageIndex record with its chunk."""
        try:
            rec = parse_record(OP_MESSAGE_INDEX, body)
            assert isinstance(rec, MessageIndex)
            (self.loading[-1].indexes if self.loading else self.stray)[rec.channel_id] = \
                rec.records
        except McapError:
            pass  # the chunk is then scanned record by record

    def _chunk(self, off: int, ext: Extent) -> Iterator[MessageBatch]:
        """Start loading the chunk at file offset ``off``; give out what is then ready."""
        try:
            chunk, at, stored = read_chunk_header(self.reader._fh, ext)
        except (McapError, UnicodeDecodeError) as exc:
            self.check(0)
            yield from self.flush_full()
            yield from self.flush_unchunked()
            self.reader._bad_chunk(off, None, ext.length, f'unreadable chunk header ({exc})')
            return
        # the next chunk loads (on the worker) while earlier ones are checked
        nxt = self.start_chunk(off, chunk, at, stored)
        nxt.indexes, self.stray = self.stray, {}
        self.loading.append(nxt)
        self.queued += nxt.need
        self.check(1, self.ahead)
        yield from self.flush_full()
        yield from self.flush_unchunked()
        self.bytes_seen += 9 + ext.length
        nxt.seen = self.bytes_seen

    def _message(self, off: int, body: bytes) -> bool:
        """Take an unchunked Message record; True when a run of them is due to be given out."""
        r = self.reader
        if len(body) < MSG_FIELDS.size:
            r.damage.notes.append(
                f'message record at byte {off} is {len(body)} bytes, shorter than '
                f'its {MSG_FIELDS.size}-byte header: skipped')
            r.damage.messages_lost += 1
            r.damage.bytes_lost += 9 + len(body)
            return False
        ch_id = U16.unpack_from(body, 0)[0]
        ordinal = r.messages_read
        r.messages_read += 1
        self.bytes_seen += 9 + len(body)
        r._bytes_per_message = self.bytes_seen / r.messages_read
        if self.wanted(ch_id):
            self.pend_ord.append(ordinal)
            self.pending.append((ch_id, body))
        return len(self.pending) >= r.UNCHUNKED_BATCH

    def start_chunk(self, off: int, chunk: Chunk, at: int | bytes, stored: int
                    ) -> PendingChunk:
        """Reserve the chunk's slot (in a new group when the current one is full) and load
        it, on the worker thread when there is one."""
        r = self.reader
        size = chunk.uncompressed_size
        try:
            check_chunk_size(chunk.compression, stored, size, r.max_chunk_bytes)
            if chunk.compression not in ('', 'zstd', 'lz4'):
                raise McapError(f'unsupported chunk compression {chunk.compression!r}')
        except McapError as exc:
            return PendingChunk(off, chunk, stored, None, 0, (exc, 0))
        need = size + (chunk.compression != '')
        group = self.group
        if group.reserved and (group.reserved >= r.GROUP_BYTES or not group.fits(need)):
            self.full.append(group)
            group = self.group = ChunkGroup(r._buffers, self.cap)
        slot_at, slot = group.slot(need)
        job = (chunk.compression, at, stored, slot, size, bool(chunk.uncompressed_crc))
        result = self.worker.submit(job) if self.worker is not None else r._filler(*job)
        return PendingChunk(off, chunk, stored, group, slot_at, result, need=need)

    def check(self, keep: int, more: int = 0) -> None:
        """Check the oldest loading chunks, leaving the last ``keep`` of them and at least
        ``more`` bytes loading."""
        r = self.reader
        loading = self.loading
        while len(loading) > keep and self.queued - loading[0].need >= more:
            done = loading.popleft()
            self.queued -= done.need
            r._chunk_messages(done, done.indexes)
            if done.group is not None:
                done.group.loading -= 1
            if r.messages_read:
                r._bytes_per_message = done.seen / r.messages_read

    def settle(self) -> None:
        """Check all loading chunks but the last, before damage met by the top-level walk
        is counted (as if each chunk were checked when the next one is met, whatever the
        lookahead)."""
        self.check(1)

    def flush(self, g: ChunkGroup) -> Iterator[MessageBatch]:
        """Give out a group's batches and empty it."""
        if g.offs:
            yield from group_batches(g, self.wanted, self.reader.channels, self.reader.schemas)
        g.reset()

    def flush_full(self) -> Iterator[MessageBatch]:
        """Give out the full groups whose chunks are all checked, oldest first."""
        while self.full and self.full[0].loading == 0:
            yield from self.flush(self.full.popleft())

    def flush_groups(self) -> Iterator[MessageBatch]:
        """Check every loading chunk and give out every group."""
        self.check(0)
        yield from self.flush_full()
        yield from self.flush(self.group)

    def flush_unchunked(self) -> Iterator[MessageBatch]:
        """Give out the pending unchunked messages."""
        if self.pending:
            yield from batches_from_records(self.pending, self.pend_ord,
                                            self.reader.channels, self.reader.schemas)
            self.pending.clear()
            self.pend_ord.clear()
