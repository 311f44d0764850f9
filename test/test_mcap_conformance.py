"""Our MCAP reader against the MCAP format's own conformance files (every legal layout)."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.io import mcap_records as mr
from inertia_ros.io.mcap_reader import McapReader
from inertia_ros.io.mcap_scan import iter_records

# A copy of the MCAP project's conformance data (MIT, see its LICENSE) travels with the tests,
# so a clean clone anywhere runs them; the copy is the shared one, byte for byte.
CONFORMANCE = ROOT / 'test' / 'data' / 'mcap-conformance'
FILES = sorted(CONFORMANCE.glob('*/*.mcap')) if CONFORMANCE.is_dir() else []
SKIP = pytest.mark.skipif(not FILES, reason=f'MCAP conformance data not found at {CONFORMANCE}')


# ------------------------------------------------------------------------------------------
# The conformance .mcap files in the shared directory are Git LFS pointers (the binaries were
# never fetched).  Each pointer holds the sha256 and size of the real file, and the JSON beside
# it lists every record; the files were made by the MCAP project's conformance generator with
# a fixed, documented layout (one uncompressed chunk, indexes and summary groups in spec
# order).  We rebuild each file from its JSON with that layout and accept it only when its
# sha256 and size equal the pointer's: the bytes read below are then the genuine file.


class _Out:
    """Little-endian MCAP record serialiser (test-only)."""

    def __init__(self, pad: bool = False) -> None:
        self.buf = bytearray()
        self.pad = pad

    def __len__(self) -> int:
        return len(self.buf)

    def record(self, op: int, body: bytes, pad: bool | None = None) -> int:
        if self.pad if pad is None else pad:
            body += b'\x01\xff\xff'
        start = len(self.buf)
        self.buf += struct.pack('<BQ', op, len(body)) + body
        return len(self.buf) - start


def _s(text: str) -> bytes:
    raw = text.encode()
    return struct.pack('<I', len(raw)) + raw


def _smap(d: dict[str, str]) -> bytes:
    body = b''.join(_s(k) + _s(v) for k, v in d.items())
    return struct.pack('<I', len(body)) + body


def _b(v: list[str]) -> bytes:
    return bytes(int(x) for x in v)


def _schema(f: dict) -> bytes:
    data = _b(f['data'])
    return (struct.pack('<H', int(f['id'])) + _s(f['name']) + _s(f['encoding'])
            + struct.pack('<I', len(data)) + data)


def _channel(f: dict) -> bytes:
    return (struct.pack('<HH', int(f['id']), int(f['schema_id'])) + _s(f['topic'])
            + _s(f['message_encoding']) + _smap(f['metadata']))


def _message(f: dict) -> bytes:
    return struct.pack('<HIQQ', int(f['channel_id']), int(f['sequence']), int(f['log_time']),
                       int(f['publish_time'])) + _b(f['data'])


def rebuild_conformance_file(records: list[dict], features: set[str]) -> bytes:
    """Serialise a conformance variant from its JSON records (the generator's layout)."""
    pad = 'pad' in features
    out = _Out(pad)
    out.buf += mr.MAGIC
    out.record(mr.OP_HEADER, _s('') + _s(''))
    chunk = _Out(False) if 'ch' in features else None
    msg_index: dict[int, list[tuple[int, int]]] = {}
    logical = [(r['type'], dict(r['fields'])) for r in records
               if r['type'] in ('Schema', 'Channel', 'Message', 'Attachment', 'Metadata')]
    seen: set[tuple[str, str]] = set()
    uniq = []
    for typ, f in logical:  # the JSON repeats schemas/channels in the summary: keep the first
        key = (typ, json.dumps(f, sort_keys=True)) if typ in ('Schema', 'Channel') else None
        if key is not None and key in seen:
            continue
        if key is not None:
            seen.add(key)
        uniq.append((typ, f))
    counts: dict[int, int] = {}
    n_msg = n_sch = n_ch = n_att = n_md = 0
    t0 = t1 = None
    c0 = c1 = None
    att_idx: list[bytes] = []
    md_idx: list[bytes] = []
    for typ, f in uniq:
        if typ == 'Schema':
            n_sch += 1
            (out if chunk is None else chunk).record(mr.OP_SCHEMA, _schema(f))
        elif typ == 'Channel':
            n_ch += 1
            if chunk is not None and 'mx' in features:
                msg_index.setdefault(int(f['id']), [])
            (out if chunk is None else chunk).record(mr.OP_CHANNEL, _channel(f))
        elif typ == 'Message':
            n_msg += 1
            ch, lt = int(f['channel_id']), int(f['log_time'])
            counts[ch] = counts.get(ch, 0) + 1
            t0 = lt if t0 is None else min(t0, lt)
            t1 = lt if t1 is None else max(t1, lt)
            if chunk is not None:
                c0 = lt if c0 is None else min(c0, lt)
                c1 = lt if c1 is None else max(c1, lt)
                if 'mx' in features:
                    msg_index.setdefault(ch, []).append((lt, len(chunk)))
                chunk.record(mr.OP_MESSAGE, _message(f), pad=False)
            else:
                out.record(mr.OP_MESSAGE, _message(f), pad=False)
        elif typ == 'Attachment':
            n_att += 1
            off = len(out)
            data = _b(f['data'])
            body = (struct.pack('<QQ', int(f['log_time']), int(f['create_time']))
                    + _s(f['name']) + _s(f['media_type']) + struct.pack('<Q', len(data)) + data)
            ln = out.record(mr.OP_ATTACHMENT, body + struct.pack('<I', zlib.crc32(body)))
            if 'ax' in features:
                att_idx.append(struct.pack('<QQQQQ', off, ln, int(f['log_time']),
                                           int(f['create_time']), len(data))
                               + _s(f['name']) + _s(f['media_type']))
        elif typ == 'Metadata':
            n_md += 1
            off = len(out)
            ln = out.record(mr.OP_METADATA, _s(f['name']) + _smap(f['metadata']))
            if 'mdx' in features:
                md_idx.append(struct.pack('<QQ', off, ln) + _s(f['name']))
    chunk_idx: list[bytes] = []
    if chunk is not None:
        recs = bytes(chunk.buf)
        start = len(out)
        body = (struct.pack('<QQQI', c0 or 0, c1 or 0, len(recs), zlib.crc32(recs)) + _s('')
                + struct.pack('<Q', len(recs)) + recs)
        clen = out.record(mr.OP_CHUNK, body, pad=False)
        offsets = []
        mi_len = 0
        for ch, pairs in msg_index.items():
            offsets.append(struct.pack('<HQ', ch, len(out)))
            arr = b''.join(struct.pack('<QQ', a, b) for a, b in pairs)
            mi_len += out.record(mr.OP_MESSAGE_INDEX,
                                 struct.pack('<HI', ch, len(arr)) + arr)
        if 'chx' in features:
            omap = b''.join(offsets)
            chunk_idx.append(struct.pack('<QQQQ', c0 or 0, c1 or 0, start, clen)
                             + struct.pack('<I', len(omap)) + omap
                             + struct.pack('<Q', mi_len) + _s('')
                             + struct.pack('<QQ', len(recs), len(recs)))
    out.record(mr.OP_DATA_END, struct.pack('<I', zlib.crc32(out.buf)), pad=False)
    summary_start = len(out)
    groups = []

    def group(op: int, bodies: list[bytes]) -> None:
        g0 = len(out)
        for body in bodies:
            out.record(op, body)
        if len(out) > g0:
            groups.append((op, g0, len(out) - g0))

    group(mr.OP_SCHEMA, [_schema(f) for t, f in uniq if t == 'Schema'] if 'rsh' in features
          else [])
    group(mr.OP_CHANNEL, [_channel(f) for t, f in uniq if t == 'Channel'] if 'rch' in features
          else [])
    if 'st' in features:
        cm = b''.join(struct.pack('<HQ', k, v) for k, v in counts.items())
        group(mr.OP_STATISTICS, [struct.pack('<QHIIIIQQ', n_msg, n_sch, n_ch, n_att, n_md,
                                             1 if chunk is not None else 0, t0 or 0, t1 or 0)
                                 + struct.pack('<I', len(cm)) + cm])
    group(mr.OP_METADATA_INDEX, md_idx)
    group(mr.OP_ATTACHMENT_INDEX, att_idx)
    group(mr.OP_CHUNK_INDEX, chunk_idx)
    has_summary = len(out) != summary_start
    so_start = 0
    if 'sum' in features:
        so_start = len(out)
        for op, g0, gl in groups:
            out.record(mr.OP_SUMMARY_OFFSET, struct.pack('<BQQ', op, g0, gl))
    foot = struct.pack('<BQQQ', mr.OP_FOOTER, 20, summary_start if has_summary else 0, so_start)
    crc = zlib.crc32(foot, zlib.crc32(bytes(out.buf[summary_start:])))
    out.buf += foot + struct.pack('<I', crc) + mr.MAGIC
    return bytes(out.buf)


def _lfs_pointer(path: Path) -> tuple[str, int] | None:
    """(sha256, size) if ``path`` is a Git LFS pointer file, else None."""
    head = path.read_bytes()[:200]
    if not head.startswith(b'version https://git-lfs'):
        return None
    fields = dict(line.split(' ', 1) for line in head.decode().splitlines() if ' ' in line)
    return fields['oid'].removeprefix('sha256:'), int(fields['size'])


def conformance_bytes(path: Path) -> bytes:
    """The genuine bytes of a conformance file: as stored, or rebuilt and hash-verified."""
    pointer = _lfs_pointer(path)
    if pointer is None:
        return path.read_bytes()
    meta = json.loads(path.with_suffix('.json').read_text())
    data = rebuild_conformance_file(meta['records'], set(meta['meta']['variant']['features']))
    sha, size = pointer
    assert (hashlib.sha256(data).hexdigest(), len(data)) == (sha, size), \
        f'rebuilt {path.name} does not match its LFS pointer'
    return data


@pytest.fixture
def genuine(tmp_path: Path, request: pytest.FixtureRequest) -> Path:
    """The conformance file of the test parameter, as a real .mcap in tmp_path."""
    path: Path = request.node.callspec.params['path']
    out = tmp_path / path.name
    out.write_bytes(conformance_bytes(path))
    return out


def _ids(paths: list[Path]) -> list[str]:
    return [p.stem for p in paths]


def _jsonish(value: object) -> object:
    """A field value in the conformance JSON's form: integers and bytes as strings."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return str(value)
    if isinstance(value, bytes):
        return [str(b) for b in value]
    if isinstance(value, dict):
        return {str(k): _jsonish(v) for k, v in value.items()}
    return value


def _as_json(rec: object) -> dict:
    """Our record in the conformance JSON's shape, limited to the fields the JSON names."""
    fields = {f.name: _jsonish(getattr(rec, f.name)) for f in dataclasses.fields(rec)}
    return {'type': type(rec).__name__, 'fields': fields}


def _expected(path: Path) -> list[dict]:
    return json.loads(path.with_suffix('.json').read_text())['records']


@SKIP
@pytest.mark.parametrize('path', FILES, ids=_ids(FILES))
def test_streaming_reader_yields_every_record(path: Path, genuine: Path) -> None:
    """iter_records yields exactly the conformance JSON's records, in order, every field equal."""
    expected = _expected(path)
    got = [_as_json(r) for r in iter_records(genuine)]
    assert [g['type'] for g in got] == [e['type'] for e in expected]
    for g, e in zip(got, expected, strict=True):
        want = dict(e['fields'])
        have = {k: g['fields'][k] for k in want}
        assert have == want, f'{e["type"]} differs'


@SKIP
@pytest.mark.parametrize('path', FILES, ids=_ids(FILES))
def test_bulk_reader_yields_every_message(path: Path, genuine: Path) -> None:
    """McapReader's batch path yields the JSON's Message records (file order, all fields)."""
    expected = [dict(e['fields']) for e in _expected(path) if e['type'] == 'Message']
    with McapReader(genuine) as reader:
        batches = list(reader.iter_batches())
        assert not reader.damage.any, reader.damage.notes
    rows = []
    for b in batches:
        for k in range(len(b)):
            rows.append((int(b.ordinal[k]), b.channel.id, int(b.log_time[k]), b.payload(k)))
    rows.sort()
    assert [r[0] for r in rows] == list(range(len(expected)))
    got = [{'channel_id': str(c), 'log_time': str(t), 'data': [str(x) for x in d]}
           for _, c, t, d in rows]
    want = [{k: e[k] for k in ('channel_id', 'log_time', 'data')} for e in expected]
    assert got == want


@SKIP
def test_conformance_covers_the_layouts() -> None:
    """The conformance set holds chunked, indexed, padded and summary variants (not a stub)."""
    names = ' '.join(p.stem for p in FILES)
    assert len(FILES) >= 100
    for feature in ('-ch', '-chx', '-mx', '-pad', '-rch', '-rsh', '-st', '-sum'):
        assert feature in names


def test_rejects_non_mcap(tmp_path: Path) -> None:
    """A file without the MCAP magic raises McapError saying so."""
    bad = tmp_path / 'x.mcap'
    bad.write_bytes(b'not an mcap file at all')
    with pytest.raises(mr.McapError, match='not an MCAP file'):
        McapReader(bad)
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    with pytest.raises(mr.McapError, match='empty file'):
        McapReader(empty)
    with pytest.raises(mr.McapError, match='no such file'):
        McapReader(tmp_path / 'missing.mcap')


def test_message_index_parse_shape() -> None:
    """A MessageIndex body parses into an (n, 2) uint64 array of [log_time, offset]."""
    pairs = np.array([[5, 0], [7, 40]], dtype='<u8')
    body = (3).to_bytes(2, 'little') + (16 * 2).to_bytes(4, 'little') + pairs.tobytes()
    rec = mr.parse_record(mr.OP_MESSAGE_INDEX, body)
    assert isinstance(rec, mr.MessageIndex)
    assert rec.channel_id == 3
    np.testing.assert_array_equal(rec.records, pairs)


def test_conformance_data_is_present():
    """The vendored conformance set is complete (416 layouts), so no test above is skipped."""
    assert len(FILES) == 416, f'{len(FILES)} conformance files under {CONFORMANCE}'
