"""Scanning MCAP bytes: record boundaries, the summary section, the conformance path.

:func:`scan_records` walks records one by one; :func:`record_offsets` finds the records of a
decompressed chunk in bulk (vectorised once a repeating pattern of records shows);
:func:`read_summary` reads the summary section (schemas, channels, statistics, chunk
indexes) when it is intact; :func:`iter_records` yields every record of a file in file
order, chunks expanded in place, which is what the MCAP conformance suite checks.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from inertia_ros.io.mcap_codecs import decompress
from inertia_ros.io.mcap_records import (
    MAGIC,
    OP_CHUNK,
    OP_FOOTER,
    OP_MESSAGE_INDEX,
    REC_HEAD,
    Channel,
    Chunk,
    ChunkIndex,
    Footer,
    McapError,
    Record,
    Schema,
    Statistics,
    parse_record,
)


def scan_records(buf: bytes | memoryview, start: int = 0,
          end: int | None = None) -> Iterator[tuple[int, int, int]]:
    """Yield (opcode, body_start, body_end) for the records in ``buf[start:end]``.

    Raises
    ------
    McapError
        If a record runs past ``end``.
    """
    end = len(buf) if end is None else end
    pos = start
    unpack = REC_HEAD.unpack_from
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


def u64_at(arr: np.ndarray, pos: int) -> int:
    """The little-endian uint64 at byte ``pos`` of uint8 array ``arr``; -1 past its end."""
    return int(arr[pos:pos + 8].view('<u8')[0]) if pos + 8 <= arr.size else -1


#: Longest record-length pattern the chunk scan recognises and verifies in bulk.
_MAX_PERIOD = 8


def record_offsets(arr: np.ndarray, start: int = 0, end: int | None = None,
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
        ln = u64_at(arr, pos + 1)
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
            pos = int(jumped[-1]) + 9 + u64_at(arr, int(jumped[-1]) + 1)
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
            ok = (arr[q] == ops[None, :]) & (gather_u64(arr, q.ravel() + 1).reshape(q.shape)
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


def gather_u64(arr: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """Little-endian uint64 at (unaligned) byte offsets ``offs`` of uint8 array ``arr``."""
    if arr.shape[0] < 8 or not arr.flags.c_contiguous:
        return sliding_window_view(arr, 8)[offs].view('<u8').ravel()
    return np.ndarray(shape=(arr.shape[0] - 7,), dtype='<u8', buffer=arr, strides=(1,))[offs]


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
    for op, b0, b1 in scan_records(data, 8, len(data) - 8 if data.endswith(MAGIC) else len(data)):
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
            for o in record_offsets(arr).tolist():
                body_end = o + 9 + u64_at(arr, o + 1)
                yield parse_record(int(arr[o]), memoryview(inner)[o + 9:body_end])
            continue
        yield parse_record(op, body)


@dataclass
class Summary:
    """What :func:`read_summary` found at the end of a file.

    Attributes
    ----------
    footer : Footer or None
        The Footer record, when the file ends with one (kept even if the summary is not).
    schemas, channels : dict
        Schema and Channel records of the summary, by id.
    statistics : Statistics or None
        The Statistics record.
    chunk_indexes : list of ChunkIndex
        One per chunk, in summary order.
    ok : bool
        True when the summary was read whole and intact (its records can be trusted).
    notes : list of str
        One line per problem found (the summary is then ignored).
    """

    footer: Footer | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    statistics: Statistics | None = None
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    ok: bool = False
    notes: list[str] = field(default_factory=list)


def read_summary(fh: BinaryIO, size: int) -> Summary:
    """Read the footer and, if intact, the summary section of an open MCAP file.

    Parameters
    ----------
    fh : binary file
        The file, opened for reading (its position is moved).
    size : int
        The file's size [bytes].

    Returns
    -------
    Summary
        The footer and summary records; empty (``ok`` False) when the file has no footer,
        no summary, or a damaged one (then ``notes`` says why and only the footer is kept).
    """
    out = Summary()
    if size < 8 + 9 + 20 + 8:
        return out
    try:
        fh.seek(size - 8 - 29)
        tail = fh.read(29 + 8)
        if tail[-8:] != MAGIC or tail[0] != OP_FOOTER:
            return out
        footer = parse_record(OP_FOOTER, tail[9:29])
        assert isinstance(footer, Footer)
        out.footer = footer
        if footer.summary_start == 0:
            return out
        if not 8 <= footer.summary_start <= size - 8 - 29:
            out.notes.append(
                f'footer damaged (summary start {footer.summary_start} outside the file): '
                'summary ignored, the data section is read forward')
            return out
        fh.seek(footer.summary_start)
        summary = fh.read(size - 8 - 29 - footer.summary_start)
        if footer.summary_crc:
            crc = zlib.crc32(tail[:9 + 16], zlib.crc32(summary))
            if crc != footer.summary_crc:
                out.notes.append('summary CRC mismatch: summary ignored')
                return out
        for op, b0, b1 in scan_records(summary):
            rec = parse_record(op, memoryview(summary)[b0:b1])
            if isinstance(rec, Schema):
                out.schemas[rec.id] = rec
            elif isinstance(rec, Channel):
                out.channels[rec.id] = rec
            elif isinstance(rec, Statistics):
                out.statistics = rec
            elif isinstance(rec, ChunkIndex):
                out.chunk_indexes.append(rec)
        out.ok = True
    except (McapError, struct.error, UnicodeDecodeError) as exc:
        return Summary(footer=out.footer, notes=[f'summary unreadable ({exc}): ignored'])
    return out
