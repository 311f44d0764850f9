"""A streaming MCAP reader of our own, with a vectorised bulk path for message payloads.

Two ways in:

:func:`iter_records`
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

References
----------
MCAP format specification, https://mcap.dev/spec (records, opcodes and field layouts).
"""
from __future__ import annotations

import os
import struct
import sys
import zlib
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

MAGIC = b'\x89MCAP0\r\n'

OP_HEADER = 0x01
OP_FOOTER = 0x02
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_MESSAGE_INDEX = 0x07
OP_CHUNK_INDEX = 0x08
OP_ATTACHMENT = 0x09
OP_ATTACHMENT_INDEX = 0x0A
OP_STATISTICS = 0x0B
OP_METADATA = 0x0C
OP_METADATA_INDEX = 0x0D
OP_SUMMARY_OFFSET = 0x0E
OP_DATA_END = 0x0F

_U16 = struct.Struct('<H')
_U32 = struct.Struct('<I')
_U64 = struct.Struct('<Q')
_REC = struct.Struct('<BQ')
_MSG = struct.Struct('<HIQQ')
_MSG_HEAD = 9 + _MSG.size  # opcode + length + fixed message fields = 31 bytes


#: Top-level records the batch reader reads; others (attachments, indexes, statistics) are
#: skipped without being read.
_READ_OPS = frozenset((0x01, 0x03, 0x04, 0x05, 0x06, 0x07, 0x0C, 0x0F))


class McapError(ValueError):
    """The file is not a readable MCAP file (bad magic, or nothing intact to read)."""


class CodecMissingError(McapError):
    """A chunk's compression needs a Python package that is not installed."""


_CODEC_PACKAGES = {'zstd': ('zstandard', 'zstandard'), 'lz4': ('lz4.frame', 'lz4')}


# --------------------------------------------------------------------------------------------
# Records


@dataclass(frozen=True)
class Header:
    """MCAP Header record (opcode 0x01)."""

    profile: str
    library: str


@dataclass(frozen=True)
class Footer:
    """MCAP Footer record (opcode 0x02); offsets in bytes from the start of the file."""

    summary_start: int
    summary_offset_start: int
    summary_crc: int


@dataclass(frozen=True)
class Schema:
    """MCAP Schema record (opcode 0x03): message type name, encoding and definition text."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class Channel:
    """MCAP Channel record (opcode 0x04): a topic, its message encoding and schema."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class Message:
    """MCAP Message record (opcode 0x05); times are integer nanoseconds."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass(frozen=True)
class Chunk:
    """MCAP Chunk record (opcode 0x06); ``records`` is still compressed."""

    message_start_time: int
    message_end_time: int
    uncompressed_size: int
    uncompressed_crc: int
    compression: str
    records: bytes


@dataclass(frozen=True)
class MessageIndex:
    """MCAP MessageIndex record (opcode 0x07); ``records``: (n, 2) uint64 [log_time, offset]."""

    channel_id: int
    records: np.ndarray


@dataclass(frozen=True)
class ChunkIndex:
    """MCAP ChunkIndex record (opcode 0x08)."""

    message_start_time: int
    message_end_time: int
    chunk_start_offset: int
    chunk_length: int
    message_index_offsets: dict[int, int]
    message_index_length: int
    compression: str
    compressed_size: int
    uncompressed_size: int


@dataclass(frozen=True)
class Attachment:
    """MCAP Attachment record (opcode 0x09)."""

    log_time: int
    create_time: int
    name: str
    media_type: str
    data: bytes
    crc: int


@dataclass(frozen=True)
class AttachmentIndex:
    """MCAP AttachmentIndex record (opcode 0x0A)."""

    offset: int
    length: int
    log_time: int
    create_time: int
    data_size: int
    name: str
    media_type: str


@dataclass(frozen=True)
class Statistics:
    """MCAP Statistics record (opcode 0x0B)."""

    message_count: int
    schema_count: int
    channel_count: int
    attachment_count: int
    metadata_count: int
    chunk_count: int
    message_start_time: int
    message_end_time: int
    channel_message_counts: dict[int, int]


@dataclass(frozen=True)
class Metadata:
    """MCAP Metadata record (opcode 0x0C): a named string-to-string map."""

    name: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class MetadataIndex:
    """MCAP MetadataIndex record (opcode 0x0D)."""

    offset: int
    length: int
    name: str


@dataclass(frozen=True)
class SummaryOffset:
    """MCAP SummaryOffset record (opcode 0x0E)."""

    group_opcode: int
    group_start: int
    group_length: int


@dataclass(frozen=True)
class DataEnd:
    """MCAP DataEnd record (opcode 0x0F)."""

    data_section_crc: int


@dataclass(frozen=True)
class UnknownRecord:
    """A record with an opcode this reader does not know (the spec says: skip it)."""

    opcode: int
    data: bytes


Record = (Header | Footer | Schema | Channel | Message | Chunk | MessageIndex | ChunkIndex
          | Attachment | AttachmentIndex | Statistics | Metadata | MetadataIndex
          | SummaryOffset | DataEnd | UnknownRecord)


class _Cursor:
    """Sequential little-endian field reader over one record body."""

    __slots__ = ('buf', 'pos')

    def __init__(self, buf: bytes | memoryview) -> None:
        self.buf = buf
        self.pos = 0

    def _take(self, n: int) -> memoryview | bytes:
        if self.pos + n > len(self.buf):
            raise McapError(f'record field runs past the record end ({self.pos + n} > '
                            f'{len(self.buf)} bytes)')
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def u8(self) -> int:
        return self._take(1)[0]

    def u16(self) -> int:
        return _U16.unpack(self._take(2))[0]

    def u32(self) -> int:
        return _U32.unpack(self._take(4))[0]

    def u64(self) -> int:
        return _U64.unpack(self._take(8))[0]

    def string(self) -> str:
        return bytes(self._take(self.u32())).decode('utf-8')

    def bytes32(self) -> bytes:
        return bytes(self._take(self.u32()))

    def bytes64(self) -> bytes:
        return bytes(self._take(self.u64()))

    def str_map(self) -> dict[str, str]:
        end = self.u32() + self.pos
        out: dict[str, str] = {}
        while self.pos < end:
            k = self.string()
            out[k] = self.string()
        return out

    def u16_u64_map(self) -> dict[int, int]:
        end = self.u32() + self.pos
        out: dict[int, int] = {}
        while self.pos < end:
            k = self.u16()
            out[k] = self.u64()
        return out

    def rest(self) -> bytes:
        out = bytes(self.buf[self.pos:])
        self.pos = len(self.buf)
        return out


def parse_record(opcode: int, body: bytes | memoryview) -> Record:
    """Parse one record body (the bytes after opcode and length) into its dataclass.

    Parameters
    ----------
    opcode : int
        The record opcode (0x01-0x0F known; anything else gives :class:`UnknownRecord`).
    body : bytes
        The record content, possibly followed by padding, which is ignored.

    Returns
    -------
    Record
        The parsed record.

    Raises
    ------
    McapError
        If a field runs past the end of the record.
    """
    if opcode == OP_MESSAGE:
        ch, seq, lt, pt = _MSG.unpack_from(body, 0)
        return Message(ch, seq, lt, pt, bytes(body[_MSG.size:]))
    if opcode in (OP_MESSAGE_INDEX, OP_CHUNK_INDEX):
        # the records read by the hundred per file: struct first, the cursor (and its
        # errors) only when the record does not parse at a glance
        fast = _fast_index(opcode, body)
        if fast is not None:
            return fast
    c = _Cursor(body)
    if opcode == OP_HEADER:
        return Header(c.string(), c.string())
    if opcode == OP_FOOTER:
        return Footer(c.u64(), c.u64(), c.u32())
    if opcode == OP_SCHEMA:
        return Schema(c.u16(), c.string(), c.string(), c.bytes32())
    if opcode == OP_CHANNEL:
        return Channel(c.u16(), c.u16(), c.string(), c.string(), c.str_map())
    if opcode == OP_CHUNK:
        return Chunk(c.u64(), c.u64(), c.u64(), c.u32(), c.string(), c.bytes64())
    if opcode == OP_MESSAGE_INDEX:
        ch = c.u16()
        raw = c.bytes32()
        if len(raw) % 16:
            raise McapError(f'message index of channel {ch} has {len(raw)} bytes, '
                            'not a multiple of 16')
        return MessageIndex(ch, np.frombuffer(raw, dtype='<u8').reshape(-1, 2))
    if opcode == OP_CHUNK_INDEX:
        return ChunkIndex(c.u64(), c.u64(), c.u64(), c.u64(), c.u16_u64_map(), c.u64(),
                          c.string(), c.u64(), c.u64())
    if opcode == OP_ATTACHMENT:
        return Attachment(c.u64(), c.u64(), c.string(), c.string(), c.bytes64(), c.u32())
    if opcode == OP_ATTACHMENT_INDEX:
        return AttachmentIndex(c.u64(), c.u64(), c.u64(), c.u64(), c.u64(), c.string(),
                               c.string())
    if opcode == OP_STATISTICS:
        return Statistics(c.u64(), c.u16(), c.u32(), c.u32(), c.u32(), c.u32(), c.u64(),
                          c.u64(), c.u16_u64_map())
    if opcode == OP_METADATA:
        return Metadata(c.string(), c.str_map())
    if opcode == OP_METADATA_INDEX:
        return MetadataIndex(c.u64(), c.u64(), c.string())
    if opcode == OP_SUMMARY_OFFSET:
        return SummaryOffset(c.u8(), c.u64(), c.u64())
    if opcode == OP_DATA_END:
        return DataEnd(c.u32())
    return UnknownRecord(opcode, bytes(body))


_CHUNK_INDEX_HEAD = struct.Struct('<QQQQI')
_CHUNK_INDEX_TAIL = struct.Struct('<QQ')


def _fast_index(opcode: int, body: bytes | memoryview) -> MessageIndex | ChunkIndex | None:
    """A MessageIndex or ChunkIndex record parsed with struct, or None to use the cursor.

    Gives what the cursor path of :func:`parse_record` gives for every well-formed record;
    None (never an error) for anything else, so errors keep the cursor's messages.
    """
    n = len(body)
    if opcode == OP_MESSAGE_INDEX:
        if n < 6:
            return None
        ch, ln = struct.unpack_from('<HI', body, 0)
        if 6 + ln > n or ln % 16:
            return None
        return MessageIndex(ch, np.frombuffer(bytes(body[6:6 + ln]), dtype='<u8').reshape(-1, 2))
    if n < _CHUNK_INDEX_HEAD.size:
        return None
    t0, t1, start, length, map_len = _CHUNK_INDEX_HEAD.unpack_from(body, 0)
    pos = _CHUNK_INDEX_HEAD.size
    if map_len % 10 or pos + map_len + 12 > n:
        return None
    offsets: dict[int, int] = {}
    for k, v in struct.iter_unpack('<HQ', bytes(body[pos:pos + map_len])):
        offsets[k] = v
    pos += map_len
    mi_len = _U64.unpack_from(body, pos)[0]
    c_len = _U32.unpack_from(body, pos + 8)[0]
    pos += 12
    if pos + c_len + 16 > n:
        return None
    try:
        comp = bytes(body[pos:pos + c_len]).decode('utf-8')
    except UnicodeDecodeError:
        return None
    csize, usize = _CHUNK_INDEX_TAIL.unpack_from(body, pos + c_len)
    return ChunkIndex(t0, t1, start, length, offsets, mi_len, comp, csize, usize)


#: Largest piece an LZ4 frame is decompressed in [bytes].
_PIECE = 16 << 20

#: Default ceiling on one chunk's uncompressed size [bytes]: a chunk declaring more, or a
#: compressed stream producing more than its chunk declares, is a damaged chunk (a
#: decompression bomb), never an allocation.
MAX_CHUNK_BYTES = 256 << 20


def decompress(compression: str, data: bytes | memoryview, size: int, *,
               limit: int = MAX_CHUNK_BYTES) -> bytes | bytearray:
    """Decompress a chunk's records, never producing more than ``size`` bytes.

    The declared size is checked against ``limit`` before anything is allocated, and the
    codecs are driven through bounded APIs (the size a zstd or LZ4 frame claims for itself
    is never trusted), so a decompression bomb costs at most ``size + 1`` bytes of memory.

    Parameters
    ----------
    compression : str
        ``''`` (none), ``'zstd'`` or ``'lz4'`` (LZ4 frame format).
    data : bytes
        The compressed records.
    size : int
        The uncompressed size the chunk declares [bytes].
    limit : int
        Largest uncompressed chunk accepted [bytes] (default :data:`MAX_CHUNK_BYTES`).

    Returns
    -------
    bytes or bytearray
        The uncompressed records, exactly ``size`` bytes long.

    Raises
    ------
    McapError
        Unknown compression, a declared size over ``limit``, a decompression failure, or
        output longer or shorter than declared.
    CodecMissingError
        The codec package (``zstandard`` or ``lz4``) is not installed.
    """
    check_chunk_size(compression, len(data), size, limit)
    if compression == '':
        return bytes(data)
    buf = bytearray(size + 1)
    view = memoryview(buf)
    try:
        decompress_into(compression, data, view, size)
    finally:
        view.release()
    del buf[size:]
    return buf


def check_chunk_size(compression: str, stored: int, size: int, limit: int) -> None:
    """Check a chunk's declared sizes before anything is allocated or read.

    Parameters
    ----------
    compression : str
        The chunk's compression (``''`` for none).
    stored : int
        Length of its (compressed) records field [bytes].
    size : int
        The uncompressed size the chunk declares [bytes].
    limit : int
        Largest uncompressed chunk accepted [bytes].

    Raises
    ------
    McapError
        A declared size over ``limit``, or an uncompressed chunk whose records field is not
        ``size`` bytes long.
    """
    if size > limit:
        raise McapError(f'chunk declares {size} uncompressed bytes, over the limit of '
                        f'{limit} (a decompression bomb or a damaged chunk header)')
    if compression == '' and stored != size:
        raise McapError(f'uncompressed chunk holds {stored} bytes, declared {size}')


def decompress_into(compression: str, data: bytes | memoryview, out: memoryview, size: int,
                    dctx: Any = None) -> None:
    """Decompress a chunk's records into ``out[:size]``, never writing past ``out[size]``.

    The bounded core of :func:`decompress` (which checks the declared size first, with
    :func:`check_chunk_size`): the output goes straight into the caller's buffer, e.g. a
    slot of a buffer holding several chunks back to back.

    Parameters
    ----------
    compression : str
        ``''``, ``'zstd'`` or ``'lz4'``.
    data : bytes
        The compressed records.
    out : memoryview
        Writable bytes, at least ``size + 1`` long (the extra byte detects output longer than
        declared) unless ``compression`` is ``''`` (then ``size``).
    size : int
        The uncompressed size the chunk declares [bytes].
    dctx : zstandard.ZstdDecompressor, optional
        A decompressor to reuse for zstd (a new one otherwise).

    Raises
    ------
    McapError
        Unknown compression, a decompression failure, or output longer or shorter than
        declared.
    CodecMissingError
        The codec package is not installed.
    """
    if compression == '':
        if len(data) != size:
            raise McapError(f'uncompressed chunk holds {len(data)} bytes, declared {size}')
        out[:size] = data
        return
    if compression not in ('zstd', 'lz4'):
        raise McapError(f'unsupported chunk compression {compression!r}')
    if len(out) < size + 1:
        raise ValueError(f'out: {len(out)} bytes, needs size + 1 = {size + 1}')
    codec = _codec(compression)
    got = 0
    try:
        if compression == 'zstd':
            if dctx is None:
                dctx = codec.ZstdDecompressor()
            with dctx.stream_reader(data, read_across_frames=True) as r:
                while got <= size:
                    n = r.readinto(out[got:size + 1])
                    if not n:
                        break
                    got += n
        else:
            # in pieces: peak memory is the chunk plus one piece
            dec = codec.LZ4FrameDecompressor()
            piece = dec.decompress(bytes(data), max_length=min(size + 1, _PIECE))
            while True:
                out[got:got + len(piece)] = piece
                got += len(piece)
                if dec.eof or got > size or dec.needs_input:
                    break
                piece = dec.decompress(b'', max_length=min(size + 1 - got, _PIECE))
                if not piece:
                    break
    except Exception as exc:  # the codecs raise their own error types
        raise McapError(f'{compression} decompression failed: {exc}') from exc
    if got > size:
        raise McapError(f'{compression} data decompresses to more than the {size} bytes the '
                        'chunk declares (a decompression bomb or a damaged chunk)')
    if got != size:
        raise McapError(f'chunk decompressed to {got} bytes, declared {size}')


def _codec(compression: str) -> Any:
    """Import the codec module of ``compression`` or raise :class:`CodecMissingError`."""
    import importlib

    module, package = _CODEC_PACKAGES[compression]
    try:
        return importlib.import_module(module)
    except ImportError:
        raise CodecMissingError(f'{compression}-compressed chunks need the Python package '
                                f'{package!r}: pip install {package}') from None


def _scan(buf: bytes | memoryview, start: int = 0,
          end: int | None = None) -> Iterator[tuple[int, int, int]]:
    """Yield (opcode, body_start, body_end) for the records in ``buf[start:end]``.

    Raises
    ------
    McapError
        If a record runs past ``end``.
    """
    end = len(buf) if end is None else end
    pos = start
    unpack = _REC.unpack_from
    while pos < end:
        if pos + 9 > end:
            raise McapError(f'record header at byte {pos} runs past the end ({end})')
        op, ln = unpack(buf, pos)
        body = pos + 9
        pos = body + ln
        if pos > end:
            raise McapError(f'record at byte {body - 9} (opcode 0x{op:02x}, {ln} bytes) runs '
                            f'past the end ({end})')
        yield op, body, pos


def _u64_at(arr: np.ndarray, pos: int) -> int:
    return int(arr[pos:pos + 8].view('<u8')[0]) if pos + 8 <= arr.size else -1


#: Longest record-length pattern the chunk scan recognises and verifies in bulk.
_MAX_PERIOD = 8


def _record_offsets(arr: np.ndarray, start: int = 0, end: int | None = None,
                    keep: tuple[int, ...] | None = None) -> np.ndarray:
    """Byte offsets of the records in ``arr[start:end]``, in order (vectorised).

    Chunks usually repeat a short pattern of records (the messages of a few fixed-size
    topics, interleaved).  Records are walked one by one only until such a pattern shows;
    its continuation is then verified in bulk (opcode and length of every predicted record),
    so a chunk of 256 MiB costs milliseconds, not a Python step per record, whatever it holds.

    Parameters
    ----------
    arr : numpy.ndarray
        uint8 array, the buffer (a decompressed chunk).
    start, end : int
        Byte range to scan (``end`` defaults to the buffer's end).
    keep : tuple of int, optional
        Return only the records with these opcodes (all if None); the others are checked and
        skipped without being stored, so memory stays proportional to what is kept.

    Returns
    -------
    numpy.ndarray
        int64 (k,) offsets of the record headers (opcode byte).

    Raises
    ------
    McapError
        An opcode 0 (not a record: zero fill or garbage) or a record running past ``end``.
    """
    end = arr.size if end is None else end
    found: list[np.ndarray] = []
    hist: list[int] = []
    pos = start
    retry_at = 2
    while pos < end:
        if pos + 9 > end:
            raise McapError(f'record header at byte {pos} runs past the end ({end})')
        op = int(arr[pos])
        ln = _u64_at(arr, pos + 1)
        if op == 0:
            raise McapError(f'invalid record at byte {pos} (opcode 0x00: zero fill or '
                            'garbage)')
        if ln < 0 or ln > end - pos - 9:
            raise McapError(f'record at byte {pos} (opcode 0x{op:02x}, {ln} bytes) runs past '
                            f'the end ({end})')
        hist.append(pos)
        pos += 9 + ln
        if len(hist) >= retry_at and pos < end:
            jumped = _jump(arr, hist, pos, end)
            if jumped is None:
                retry_at = len(hist) + 2 * _MAX_PERIOD  # not periodic here: walk on a while
                continue
            pos = int(jumped[-1]) + 9 + _u64_at(arr, int(jumped[-1]) + 1)
            found.append(_only(arr, np.asarray(hist, dtype=np.int64), keep))
            found.append(_only(arr, jumped, keep))
            hist = []
            retry_at = 2
    found.append(_only(arr, np.asarray(hist, dtype=np.int64), keep))
    return np.concatenate(found) if len(found) > 1 else found[0]


def _only(arr: np.ndarray, offs: np.ndarray, keep: tuple[int, ...] | None) -> np.ndarray:
    """The record offsets ``offs`` whose opcode is in ``keep`` (all if None)."""
    return offs if keep is None else offs[np.isin(arr[offs], keep)]


def _jump(arr: np.ndarray, hist: list[int], pos: int, end: int,
          max_block: int = 1 << 17) -> np.ndarray | None:
    """Offsets of the records continuing the periodic pattern that ends ``hist`` (or None).

    ``hist`` holds the offsets of the records walked so far, ``pos`` the offset of the next.
    The smallest period ``P`` whose last two repetitions agree in opcodes and lengths is
    extrapolated and checked in blocks; the offsets of the verified records are returned
    (None if no pattern or not even one more repetition verifies).
    """
    tail = [*hist[-2 * _MAX_PERIOD:], pos]
    steps = [b - a for a, b in zip(tail[:-1], tail[1:], strict=True)]
    for p in range(1, _MAX_PERIOD + 1):
        if 2 * p > len(steps) or steps[-p:] != steps[-2 * p:-p]:
            continue
        tmpl = np.asarray(hist[-p:], dtype=np.int64) - hist[-p]
        ops = arr[np.asarray(hist[-p:])]
        if not np.array_equal(ops, arr[np.asarray(hist[-2 * p:-p])]):
            continue
        lens = np.asarray(steps[-p:], dtype=np.int64) - 9
        period = int(pos - hist[-p])
        out: list[np.ndarray] = []
        base = pos
        block = 64
        while True:
            reps = min(block, (end - base) // period)
            if reps <= 0:
                break
            q = (base + period * np.arange(reps, dtype=np.int64))[:, None] + tmpl[None, :]
            ok = (arr[q] == ops[None, :]) & (_gather_u64(arr, q.ravel() + 1).reshape(q.shape)
                                             .astype(np.int64) == lens[None, :])
            good = ok.all(axis=1)
            m = reps if good.all() else int(np.argmin(good))
            if m:
                out.append(q[:m].ravel())
                base += m * period
            if m < reps or sum(o.size for o in out) >= max_block * 8:
                break
            block = min(4 * block, max_block)
        if not out:
            return None
        return np.concatenate(out)
    return None


# --------------------------------------------------------------------------------------------
# Damage accounting


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


# --------------------------------------------------------------------------------------------
# Streaming record iteration (the conformance path)


def iter_records(path: str | Path, *, expand_chunks: bool = True,
                 include_message_indexes: bool = False,
                 check_crc: bool = True) -> Iterator[Record]:
    """Yield every record of an MCAP file in file order.

    Parameters
    ----------
    path : str or Path
        The MCAP file.
    expand_chunks : bool
        Yield the records inside each chunk in place of the Chunk record (default) rather than
        the Chunk record itself.
    include_message_indexes : bool
        Also yield MessageIndex records (off by default, as a streaming reader of messages
        has no use for them).
    check_crc : bool
        Verify each chunk's uncompressed CRC (when it is not 0) and raise on a mismatch.

    Yields
    ------
    Record
        Parsed records; the closing magic is checked after the Footer.

    Raises
    ------
    McapError
        Bad magic, a record running past the end of the file, or a bad chunk.
    """
    with open(path, 'rb') as fh:
        data = fh.read()
    if data[:8] != MAGIC:
        raise McapError(f'{path}: not an MCAP file (bad magic bytes)')
    for op, b0, b1 in _scan(data, 8, len(data) - 8 if data.endswith(MAGIC) else len(data)):
        body = memoryview(data)[b0:b1]
        if op == OP_MESSAGE_INDEX and not include_message_indexes:
            continue
        if op == OP_CHUNK and expand_chunks:
            chunk = parse_record(op, body)
            assert isinstance(chunk, Chunk)
            inner = decompress(chunk.compression, chunk.records, chunk.uncompressed_size)
            if check_crc and chunk.uncompressed_crc and \
                    zlib.crc32(inner) != chunk.uncompressed_crc:
                raise McapError(f'{path}: chunk CRC mismatch')
            arr = np.frombuffer(inner, dtype=np.uint8)
            for o in _record_offsets(arr).tolist():
                body_end = o + 9 + _u64_at(arr, o + 1)
                yield parse_record(int(arr[o]), memoryview(inner)[o + 9:body_end])
            continue
        yield parse_record(op, body)


# --------------------------------------------------------------------------------------------
# Bulk message reading


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


def _gather_u64(arr: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """Little-endian uint64 at (unaligned) byte offsets ``offs`` of uint8 array ``arr``."""
    if arr.shape[0] < 8 or not arr.flags.c_contiguous:
        return sliding_window_view(arr, 8)[offs].view('<u8').ravel()
    return np.ndarray(shape=(arr.shape[0] - 7,), dtype='<u8', buffer=arr, strides=(1,))[offs]


ChannelFilter = Callable[[Channel, Schema | None], bool]

_CHUNK_HEAD = struct.Struct('<QQQI')

#: A Message record's head as it lies in the buffer (unaligned): opcode, record length,
#: channel id, sequence, log time [ns].
_HEAD_DT = np.dtype({'names': ['op', 'len', 'chan', 'seq', 'log_time'],
                     'formats': ['u1', '<u8', '<u2', '<u4', '<u8'],
                     'offsets': [0, 1, 9, 11, 15], 'itemsize': 23})
_HEAD_V = np.dtype(f'V{_HEAD_DT.itemsize}')


@dataclass(frozen=True)
class _Extent:
    """Where a record body lies in the file: ``length`` bytes from offset ``start``."""

    start: int
    length: int


@dataclass
class _PendingChunk:
    """A chunk whose records are being loaded into a group slot (or the error that stopped it).

    ``result`` is ``(error, crc)`` once loaded: a :class:`McapError` (or None) and the
    CRC-32 of the uncompressed records (0 when the chunk declares none); while the chunk is
    loaded on the reader's worker thread it is that :class:`_Loader`, which gives the pairs
    in the order the chunks were handed to it.  ``indexes`` are the
    chunk's MessageIndex records (channel id -> (k, 2) array of log time and offset), which
    follow the chunk in the file; ``seen`` is the number of data-section bytes read up to
    and including the chunk, for the reader's bytes-per-message estimate once it is checked.
    """

    off: int
    chunk: Chunk
    stored: int
    group: _Group | None
    at: int
    result: Any
    indexes: dict[int, np.ndarray] = field(default_factory=dict)
    seen: int = 0
    need: int = 0

    def outcome(self) -> tuple[McapError | None, int]:
        """``(error, crc)``, waiting for the worker thread if it is still loading the chunk.

        Chunks loaded on the worker must be asked for in the order they were handed to it.
        """
        if not isinstance(self.result, tuple):      # a _Loader
            self.result = self.result.result()
        return self.result


class _Loader:
    """A worker thread that loads chunks one after the other, in the order they are given.

    ``fill(*job)`` (:meth:`McapReader._fill`) runs on the thread; its results are taken
    with :meth:`result` in the same order.  Whatever it raises is raised again by
    :meth:`result`, in the caller's thread.  The thread is a daemon and :meth:`close`
    stops it after the job it is running (the jobs not started are dropped), so an error
    or Ctrl-C in the caller never waits for the rest of the file.
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


class _Group:
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


def _cpus() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):              # pragma: no cover (not Linux)
        return os.cpu_count() or 1


def _pread_into(fd: int, out: memoryview, at: int) -> int:
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


_EMPTY = np.zeros(0, dtype=np.uint8)


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
        self._dctx: Any = None
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
        if self.size < 8 + 9 + 20 + 8:
            return
        try:
            self._fh.seek(self.size - 8 - 29)
            tail = self._fh.read(29 + 8)
            if tail[-8:] != MAGIC or tail[0] != OP_FOOTER:
                return
            footer = parse_record(OP_FOOTER, tail[9:29])
            assert isinstance(footer, Footer)
            self.footer = footer
            if footer.summary_start == 0:
                return
            if not 8 <= footer.summary_start <= self.size - 8 - 29:
                self.damage.notes.append(
                    f'footer damaged (summary start {footer.summary_start} outside the file): '
                    'summary ignored, the data section is read forward')
                return
            self._fh.seek(footer.summary_start)
            summary = self._fh.read(self.size - 8 - 29 - footer.summary_start)
            if footer.summary_crc:
                crc = zlib.crc32(tail[:9 + 16], zlib.crc32(summary))
                if crc != footer.summary_crc:
                    self.damage.notes.append('summary CRC mismatch: summary ignored')
                    return
            for op, b0, b1 in _scan(summary):
                rec = parse_record(op, memoryview(summary)[b0:b1])
                if isinstance(rec, Schema):
                    self.schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    self.channels[rec.id] = rec
                elif isinstance(rec, Statistics):
                    self.statistics = rec
                elif isinstance(rec, ChunkIndex):
                    self.chunk_indexes.append(rec)
            self._summary_ok = True
        except (McapError, struct.error, UnicodeDecodeError) as exc:
            self.damage.notes.append(f'summary unreadable ({exc}): ignored')
            self.schemas.clear()
            self.channels.clear()
            self.statistics = None
            self.chunk_indexes = []

    # top-level record stream ----------------------------------------------------------------
    def _top_level(self, lazy_chunks: bool = False, settle: Callable[[], None] | None = None
                   ) -> Iterator[tuple[int, int, bytes | _Extent]]:
        """Yield (opcode, file_offset, body) for data-section records; stops at damage.

        With ``lazy_chunks`` a Chunk record's body is not read: an :class:`_Extent` (where it
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
            op, ln = _REC.unpack(head)
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
                yield op, pos, _Extent(pos + 9, ln)
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
        self.damage.notes.append(f'{reason}: {lost} bytes unreadable, {bound}~{msgs} messages '
                                 'lost')

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
        decided: dict[int, bool] = {}

        def wanted(ch_id: int) -> bool:
            ok = decided.get(ch_id)
            if ok is None:
                ch = self.channels.get(ch_id)
                if ch is None:
                    return False  # not (yet) defined: cannot be decoded
                ok = True if select is None else bool(select(ch, self.schemas.get(ch.schema_id)))
                decided[ch_id] = ok
            return ok

        pending: list[tuple[int, bytes]] = []
        pend_ord: list[int] = []
        # chunks in file order whose records are loaded or loading but not yet checked; the
        # MessageIndex records after a chunk go to the last one (to the next chunk when none
        # is loading)
        loading: deque[_PendingChunk] = deque()
        queued = 0                         # their uncompressed bytes
        stray: dict[int, np.ndarray] = {}
        bytes_seen = 0
        cap = self.GROUP_BYTES + (2 << 20)
        group = _Group(self._buffers, cap)
        full: deque[_Group] = deque()      # given out once their chunks are all checked
        worker = _Loader(self._fill) if self.THREADS and _cpus() > 1 else None
        # without a worker each chunk is checked as soon as the next one is met; with one,
        # up to LOOKAHEAD more bytes load while earlier chunks are checked and decoded
        ahead = self.LOOKAHEAD if worker is not None else 0

        def flush_unchunked() -> Iterator[MessageBatch]:
            if pending:
                yield from self._batches_from_records(pending, pend_ord, wanted)
                pending.clear()
                pend_ord.clear()

        def flush(g: _Group) -> Iterator[MessageBatch]:
            if g.offs:
                yield from self._group_batches(g, wanted)
            g.reset()

        def check(keep: int, more: int = 0) -> None:
            """Check the oldest loading chunks, leaving the last ``keep`` of them and at least
            ``more`` bytes loading."""
            nonlocal queued
            while len(loading) > keep and queued - loading[0].need >= more:
                done = loading.popleft()
                queued -= done.need
                self._chunk_messages(done, done.indexes)
                if done.group is not None:
                    done.group.loading -= 1
                if self.messages_read:
                    self._bytes_per_message = done.seen / self.messages_read

        def settle() -> None:
            # damage met by _top_level is counted as if each chunk were checked when the
            # next one is met, whatever the lookahead
            check(1)

        def flush_full() -> Iterator[MessageBatch]:
            while full and full[0].loading == 0:
                yield from flush(full.popleft())

        def flush_groups() -> Iterator[MessageBatch]:
            check(0)
            yield from flush_full()
            yield from flush(group)

        def start_chunk(off: int, chunk: Chunk, at: int | bytes, stored: int
                        ) -> _PendingChunk:
            """Reserve the chunk's slot (in a new group when the current one is full) and
            load it, on the worker thread when there is one."""
            nonlocal group
            size = chunk.uncompressed_size
            try:
                check_chunk_size(chunk.compression, stored, size, self.max_chunk_bytes)
                if chunk.compression not in ('', 'zstd', 'lz4'):
                    raise McapError(f'unsupported chunk compression {chunk.compression!r}')
            except McapError as exc:
                return _PendingChunk(off, chunk, stored, None, 0, (exc, 0))
            need = size + (chunk.compression != '')
            if group.reserved and (group.reserved >= self.GROUP_BYTES
                                   or not group.fits(need)):
                full.append(group)
                group = _Group(self._buffers, cap)
            slot_at, slot = group.slot(need)
            job = (chunk.compression, at, stored, slot, size, bool(chunk.uncompressed_crc))
            result = worker.submit(job) if worker is not None else self._fill(*job)
            return _PendingChunk(off, chunk, stored, group, slot_at, result, need=need)

        try:
            for op, off, body in self._top_level(lazy_chunks=True, settle=settle):
                if op == OP_MESSAGE_INDEX:
                    assert isinstance(body, bytes)
                    try:
                        rec = parse_record(op, body)
                        assert isinstance(rec, MessageIndex)
                        (loading[-1].indexes if loading else stray)[rec.channel_id] = \
                            rec.records
                    except McapError:
                        pass  # the chunk is then scanned record by record
                    continue
                if op == OP_CHUNK:
                    assert isinstance(body, _Extent)
                    try:
                        chunk, at, stored = self._chunk_header(body)
                    except (McapError, UnicodeDecodeError) as exc:
                        check(0)
                        yield from flush_full()
                        yield from flush_unchunked()
                        self._bad_chunk(off, None, body.length,
                                        f'unreadable chunk header ({exc})')
                        continue
                    # the next chunk loads (on the worker) while earlier ones are checked
                    nxt = start_chunk(off, chunk, at, stored)
                    nxt.indexes, stray = stray, {}
                    loading.append(nxt)
                    queued += nxt.need
                    check(1, ahead)
                    yield from flush_full()
                    yield from flush_unchunked()
                    bytes_seen += 9 + body.length
                    nxt.seen = bytes_seen
                    continue
                yield from flush_groups()     # batches stay in file order
                if op == OP_MESSAGE:
                    assert isinstance(body, bytes)
                    if len(body) < _MSG.size:
                        self.damage.notes.append(
                            f'message record at byte {off} is {len(body)} bytes, shorter than '
                            f'its {_MSG.size}-byte header: skipped')
                        self.damage.messages_lost += 1
                        self.damage.bytes_lost += 9 + len(body)
                        continue
                    ch_id = _U16.unpack_from(body, 0)[0]
                    pend_ord.append(self.messages_read)
                    self.messages_read += 1
                    bytes_seen += 9 + len(body)
                    self._bytes_per_message = bytes_seen / self.messages_read
                    if wanted(ch_id):
                        pending.append((ch_id, body))
                    else:
                        pend_ord.pop()
                    if len(pending) >= self.UNCHUNKED_BATCH:
                        yield from flush_unchunked()
                    continue
                yield from flush_unchunked()
                assert isinstance(body, bytes)
                self._other_record(op, body)
            yield from flush_groups()
            yield from flush_unchunked()
        finally:
            if worker is not None:
                worker.close()

    def _chunk_header(self, ext: _Extent) -> tuple[Chunk, int | bytes, int]:
        """Read a Chunk record's fields, not its records.

        Returns ``(chunk, at, stored)``: the Chunk with empty ``records``, the file offset of
        its records (or the records themselves, when the header had to be read whole) and
        their length [bytes].  A header that does not parse at a glance is read and parsed
        whole, so damage gives the same error as :func:`parse_record`.

        Raises
        ------
        McapError, UnicodeDecodeError
            An unreadable chunk header.
        """
        fh = self._fh
        fh.seek(ext.start)
        head = fh.read(min(ext.length, 256))
        if len(head) >= 40:
            c_len = _U32.unpack_from(head, 28)[0]
            if 40 + c_len <= len(head):
                t0, t1, usize, crc = _CHUNK_HEAD.unpack_from(head, 0)
                stored = _U64.unpack_from(head, 32 + c_len)[0]
                if 40 + c_len + stored <= ext.length:
                    comp = head[32:32 + c_len].decode('utf-8')
                    return (Chunk(t0, t1, usize, crc, comp, b''), ext.start + 40 + c_len,
                            stored)
        fh.seek(ext.start)
        rec = parse_record(OP_CHUNK, fh.read(ext.length))
        assert isinstance(rec, Chunk)
        return rec, rec.records, len(rec.records)

    def _fill(self, compression: str, at: int | bytes, stored: int, slot: memoryview,
              size: int, want_crc: bool) -> tuple[McapError | None, int]:
        """Load a chunk's records into ``slot`` and compute their CRC: ``(error, crc)``.

        Reads with positional reads and touches no reader state but the zstd decompressor,
        so it can run on the worker thread (one chunk at a time, in file order); the file
        reads, zstd decompression and CRC all release the GIL.  Failures are returned, to
        be counted once the chunk's message indexes (which say how many messages were lost)
        have been read.
        """
        try:
            if compression == '' and isinstance(at, int):
                got = _pread_into(self._fh.fileno(), slot[:size], at)
                if got != size:
                    raise McapError(f'uncompressed chunk holds {got} bytes, declared {size}')
            else:
                data = os.pread(self._fh.fileno(), stored, at) if isinstance(at, int) else at
                if compression == 'zstd' and self._dctx is None:
                    self._dctx = _codec('zstd').ZstdDecompressor()
                decompress_into(compression, data, slot, size, self._dctx)
            return None, (zlib.crc32(slot[:size]) if want_crc else 0)
        except McapError as exc:          # CodecMissingError included
            return exc, 0
        finally:
            slot.release()

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

    def _batches_from_records(self, recs: list[tuple[int, bytes]], ords: list[int],
                              wanted: Callable[[int], bool]) -> Iterator[MessageBatch]:
        """Batches from a run of unchunked Message record bodies."""
        by_ch: dict[int, list[int]] = {}
        for k, (ch_id, _) in enumerate(recs):
            by_ch.setdefault(ch_id, []).append(k)
        for ch_id, ks in by_ch.items():
            bodies = [recs[k][1] for k in ks]
            lens = np.array([len(b) - _MSG.size for b in bodies], dtype=np.int64)
            buf = np.frombuffer(b''.join(b[_MSG.size:] for b in bodies), dtype=np.uint8)
            starts = np.zeros(len(ks), dtype=np.int64)
            np.cumsum(lens[:-1], out=starts[1:])
            log_time = np.array([_U64.unpack_from(b, 6)[0] for b in bodies], dtype=np.uint64)
            seq = np.array([_U32.unpack_from(b, 2)[0] for b in bodies], dtype=np.uint32)
            ch = self.channels[ch_id]
            yield MessageBatch(ch, self.schemas.get(ch.schema_id), buf, starts, lens, log_time,
                               np.asarray([ords[k] for k in ks], dtype=np.int64), seq)

    def _chunk_messages(self, done: _PendingChunk, indexes: dict[int, np.ndarray]) -> None:
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
            offs, heads = self._locate_messages(arr, indexes)
        except (McapError, struct.error, UnicodeDecodeError) as exc:
            self._bad_chunk(off, n_idx, chunk.uncompressed_size,
                            f'bad records ({exc})')
            return
        base = self.messages_read
        self.messages_read += offs.shape[0]
        done.group.commit(done.at, chunk.uncompressed_size, offs, heads, base)

    def _group_batches(self, group: _Group,
                       wanted: Callable[[int], bool]) -> Iterator[MessageBatch]:
        """One batch per wanted channel over a run of consecutive chunks.

        The chunks' records lie back to back in the group's buffer, so the per-batch work of
        the caller (decoding) runs once per run of chunks rather than once per chunk.
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
        chans = heads.view(_HEAD_DT)['chan']
        # channel ids are uint16: a count per id is cheaper than np.unique's hashing
        for ch_id in np.flatnonzero(np.bincount(chans)).tolist():
            if not wanted(ch_id):
                continue
            sel = np.flatnonzero(chans == ch_id)
            h = heads[sel].view(_HEAD_DT)
            ch = self.channels[ch_id]
            yield MessageBatch(ch, self.schemas.get(ch.schema_id), arr, offs[sel] + _MSG_HEAD,
                               h['len'].astype(np.int64) - _MSG.size,
                               h['log_time'].astype(np.uint64), ords[sel],
                               h['seq'].astype(np.uint32))

    def _locate_messages(self, arr: np.ndarray,
                         indexes: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Return (offsets, heads) of every Message record in a chunk, in file order.

        ``heads`` is a :data:`_HEAD_V` array (:data:`_HEAD_DT` once viewed): each record's
        opcode, length, channel id, sequence and log time, gathered while the chunk is fresh
        in the cache.  Also registers the Schema and Channel records the chunk holds.
        Message indexes locate the messages; the byte ranges they do not cover are scanned
        record by record, so a chunk with missing or partial indexes is still read
        completely.
        """
        size = arr.shape[0]
        if size < _MSG_HEAD:
            heads_at = None
        else:
            # plain void items: gathering and joining them is several times faster than
            # with the structured dtype, which only views the result
            heads_at = np.ndarray(shape=(size - _HEAD_DT.itemsize + 1,), dtype=_HEAD_V,
                                  buffer=arr, strides=(1,))
        offs_list: list[np.ndarray] = []
        heads_list: list[np.ndarray] = []
        if indexes:
            parts = [v[:, 1] for v in indexes.values()]
            offs = (np.concatenate(parts) if len(parts) > 1 else parts[0]).astype(np.int64)
            offs.sort(kind='stable')         # merges the channels' sorted runs
            good = offs.size > 0 and offs[0] >= 0 and offs[-1] + _MSG_HEAD <= size
            if good:
                assert heads_at is not None
                heads = heads_at[offs]
                fields = heads.view(_HEAD_DT)
                good = bool(np.all(fields['op'] == OP_MESSAGE)) and bool(np.all(offs[1:] >
                                                                              offs[:-1]))
            if good:
                lens = fields['len']
                good = bool(np.all((lens >= _MSG.size) & (lens <= size)))
            if good:
                ends = offs + 9 + lens.astype(np.int64)
                good = bool(np.all(ends[:-1] <= offs[1:])) and int(ends[-1]) <= size
            if good:
                offs_list.append(offs)
                heads_list.append(heads)
                gaps = np.flatnonzero(offs[1:] > ends[:-1])
                spans = [(int(ends[g]), int(offs[g + 1])) for g in gaps.tolist()]
                if offs[0] > 0:
                    spans.insert(0, (0, int(offs[0])))
                if ends[-1] < size:
                    spans.append((int(ends[-1]), size))
            else:
                spans = [(0, size)]
        else:
            spans = [(0, size)]
        for s0, s1 in spans:
            recs = _record_offsets(arr, s0, s1, keep=(OP_MESSAGE, OP_SCHEMA, OP_CHANNEL))
            ops = arr[recs]
            for o in recs[(ops == OP_SCHEMA) | (ops == OP_CHANNEL)].tolist():
                ln = _u64_at(arr, o + 1)
                self._other_record(int(arr[o]), arr[o + 9:o + 9 + ln].tobytes())
            msgs = recs[ops == OP_MESSAGE]
            if msgs.size:
                short = _gather_u64(arr, msgs + 1) < _MSG.size
                if short.any():
                    raise McapError(f'{int(short.sum())} message record(s) shorter than the '
                                    f'{_MSG.size}-byte message header')
                assert heads_at is not None
                offs_list.append(msgs)
                heads_list.append(heads_at[msgs])
        if not offs_list:
            return np.zeros(0, np.int64), np.zeros(0, _HEAD_V)
        if len(offs_list) == 1:
            return offs_list[0], heads_list[0]
        offs = np.concatenate(offs_list)
        order = np.argsort(offs, kind='stable')
        return offs[order], np.concatenate(heads_list)[order]

    # convenience ----------------------------------------------------------------------------
    def iter_messages(self, select: ChannelFilter | None = None
                      ) -> Iterator[tuple[Schema | None, Channel, int, bytes]]:
        """Yield ``(schema, channel, log_time_ns, payload)`` per message (slow; for tests)."""
        for b in self.iter_batches(select):
            for k in range(len(b)):
                yield b.schema, b.channel, int(b.log_time[k]), b.payload(k)
