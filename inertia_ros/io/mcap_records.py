"""MCAP records: opcodes, the record structures and their parsing.

The format layer shared by the reader's jobs (:mod:`~inertia_ros.io.mcap_scan`,
:mod:`~inertia_ros.io.mcap_chunks`, :mod:`~inertia_ros.io.mcap_reader`): the magic bytes,
the opcodes, the fixed-layout structs, one frozen dataclass per record type and
:func:`parse_record`, which turns a record body into its dataclass.

References
----------
MCAP format specification, https://mcap.dev/spec (records, opcodes and field layouts).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

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

#: Little-endian field layouts: integers, a record's opcode and length, a Message record's
#: fixed fields (channel id, sequence, log time, publish time).
U16 = struct.Struct('<H')
U32 = struct.Struct('<I')
U64 = struct.Struct('<Q')
REC_HEAD = struct.Struct('<BQ')
MSG_FIELDS = struct.Struct('<HIQQ')
MSG_HEAD = 9 + MSG_FIELDS.size  # opcode + length + fixed message fields = 31 bytes


class McapError(ValueError):
    """The file is not a readable MCAP file (bad magic, or nothing intact to read)."""


class CodecMissingError(McapError):
    """A chunk's compression needs a Python package that is not installed."""


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
        return U16.unpack(self._take(2))[0]

    def u32(self) -> int:
        return U32.unpack(self._take(4))[0]

    def u64(self) -> int:
        return U64.unpack(self._take(8))[0]

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
        ch, seq, lt, pt = MSG_FIELDS.unpack_from(body, 0)
        return Message(ch, seq, lt, pt, bytes(body[MSG_FIELDS.size:]))
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
    mi_len = U64.unpack_from(body, pos)[0]
    c_len = U32.unpack_from(body, pos + 8)[0]
    pos += 12
    if pos + c_len + 16 > n:
        return None
    try:
        comp = bytes(body[pos:pos + c_len]).decode('utf-8')
    except UnicodeDecodeError:
        return None
    csize, usize = _CHUNK_INDEX_TAIL.unpack_from(body, pos + c_len)
    return ChunkIndex(t0, t1, start, length, offsets, mi_len, comp, csize, usize)
