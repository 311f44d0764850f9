"""A seeded corpus of damaged and adversarial logs, generated from one small simulated log.

Nothing here is stored in git: :func:`build_corpus` writes every case into a directory in
about a second.  Each case is a path (an ``.mcap`` file or a rosbag2 directory) with what is
known about it:

``kind``
    The family (``truncate``, ``flip``, ``bomb``, ``metadata``, ``short_record``,
    ``footer``, ``clock``, ``pause``, ``garbage``).
``truth``
    The true inertia tensor (3, 3) [kg m^2] when whatever is read is still genuine data
    (truncations and byte flips, as chunk CRCs catch the flips; clock faults, pauses and
    damaged footers): a report with status ``ok`` must then lie within 5 standard
    deviations of it, element by element.

The base log is 20 s of the nominal scene (gyro 100 Hz, torque 50 Hz), written with the
``mcap`` package's writer (not ours) so that sequence numbers, log times, chunking and
compression are controlled per case.
"""
from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from conftest import ROOT

MAGIC = b'\x89MCAP0\r\n'
T0 = 1_704_067_200_000_000_000  # 2024-01-01T00:00Z [ns]
GYRO, TORQUE, TRUTH = '/imu', '/torque', '/truth/inertia'


@dataclass(frozen=True)
class Case:
    """One corpus entry."""

    name: str
    kind: str
    path: Path
    truth: np.ndarray | None = None


@dataclass
class Base:
    """The simulated streams everything is made from (stamps [ns], values SI)."""

    tg: np.ndarray
    w: np.ndarray
    tt: np.ndarray
    tau: np.ndarray
    inertia: np.ndarray


def simulate_base(duration: float = 20.0, seed: int = 1) -> Base:
    """20 s of the nominal scene (bags/default.yaml), gyro at 100 Hz."""
    from inertia_ros.core.scene import Scene
    from inertia_ros.core.simulation import simulate

    d = yaml.safe_load((ROOT / 'bags' / 'default.yaml').read_text())
    d['duration'] = duration
    d['gyro']['rate'] = 100.0
    res = simulate(Scene.from_dict(d), seed=seed)
    tg = T0 + np.round(np.asarray(res.t_gyro) * 1e9).astype(np.int64)
    tt = T0 + np.round(np.asarray(res.t_torque) * 1e9).astype(np.int64)
    return Base(tg, np.asarray(res.omega), tt, np.asarray(res.torque),
                np.asarray(res.inertia))


def write_mcap(path: Path, b: Base, *, compression: str = 'zstd', chunk_size: int = 1 << 16,
               log_g: np.ndarray | None = None, log_t: np.ndarray | None = None,
               sequence: bool = True, sort: bool = True, chunked: bool = True) -> Path:
    """Write ``b`` as a ros2 MCAP file with the ``mcap`` package's writer.

    ``log_g``/``log_t`` are the log times (default: the header stamps).  With ``sort`` the
    messages are stored in log-time order (as recorders and our writer do), else gyro and
    torque are interleaved in their given order by log time of arrival.  ``sequence`` sets
    each message's sequence number to its index on its topic (False: all 0).
    """
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    from inertia_ros.io import cdr_encode as ce

    ts = get_typestore(Stores.ROS2_JAZZY)
    log_g = b.tg if log_g is None else log_g
    log_t = b.tt if log_t is None else log_t
    rows = []
    topics = [(GYRO, ce.IMU, log_g, ce.encode_imu(b.tg, b.w, 'base_link')),
              (TORQUE, ce.WRENCH_STAMPED, log_t, ce.encode_wrench_stamped(b.tt, b.tau,
                                                                          'base_link')),
              (TRUTH, ce.INERTIA_STAMPED, b.tg[:1],
               ce.encode_inertia_stamped(b.tg[:1], b.inertia[None], 'base_link'))]
    comp = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
            'none': CompressionType.NONE}[compression]
    with open(path, 'wb') as fh:
        w = Writer(fh, compression=comp, chunk_size=chunk_size, use_chunking=chunked)
        w.start(profile='ros2', library='fuzz')
        for topic, typ, t_ns, pay in topics:
            sid = w.register_schema(typ, 'ros2msg',
                                    ts.generate_msgdef(typ, ros_version=2)[0].encode())
            ch = w.register_channel(topic, 'cdr', sid)
            rows.extend((int(t), ch, k, p) for k, (t, p) in enumerate(zip(t_ns, pay,
                                                                           strict=True)))
        if sort:
            rows.sort(key=lambda r: r[0])
        for t, ch, k, p in rows:
            w.add_message(ch, t, p, t, k if sequence else 0)
        w.finish()
    return path


# --------------------------------------------------------------------------------------------
# raw record surgery


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of the top-level records of an intact MCAP file."""
    out = []
    pos = 8
    while pos + 9 <= len(data) - 8:
        op, ln = struct.unpack_from('<BQ', data, pos)
        out.append((op, pos, pos + 9 + ln))
        pos += 9 + ln
        if op == 0x02:
            break
    return out


def _rec(op: int, body: bytes) -> bytes:
    return struct.pack('<BQ', op, len(body)) + body


def _chunk(compression: str, payload: bytes, usize: int, crc: int = 0) -> bytes:
    c = compression.encode()
    body = (struct.pack('<QQQI', T0, T0, usize, crc) + struct.pack('<I', len(c)) + c
            + struct.pack('<Q', len(payload)) + payload)
    return _rec(0x06, body)


def _no_summary(data: bytes, extra: bytes, at: str = 'start') -> bytes:
    """The data section of ``data`` with ``extra`` inserted, a bare footer, no summary."""
    recs = records(data)
    head = data[recs[0][1]:recs[0][2]]
    body = b''.join(data[s:e] for op, s, e in recs[1:] if op in (0x03, 0x04, 0x05, 0x06,
                                                                 0x07, 0x0C))
    footer = _rec(0x02, struct.pack('<QQI', 0, 0, 0))
    mid = extra + body if at == 'start' else body + extra
    return MAGIC + head + mid + _rec(0x0F, b'\0\0\0\0') + footer + MAGIC


def zstd_stream(n: int, unit: bytes = b'\0') -> bytes:
    """A zstd frame of ``n`` bytes of repeated ``unit``, compressed in 4 MiB pieces."""
    import zstandard

    c = zstandard.ZstdCompressor(level=1).compressobj()
    block = unit * ((4 << 20) // len(unit))
    out = [c.compress(block) for _ in range(n // len(block))]
    out.append(c.compress(unit * ((n % len(block)) // len(unit))))
    out.append(c.flush())
    return b''.join(out)


def lz4_stream(n: int, unit: bytes = b'\0') -> bytes:
    """An LZ4 frame of ``n`` bytes of repeated ``unit``."""
    import lz4.frame

    c = lz4.frame.LZ4FrameCompressor()
    block = unit * ((4 << 20) // len(unit))
    out = [c.begin()] + [c.compress(block) for _ in range(n // len(block))]
    out.append(c.compress(unit * ((n % len(block)) // len(unit))))
    out.append(c.flush())
    return b''.join(out)


def bomb_cases(out: Path, base_file: Path) -> list[Case]:
    """Decompression bombs and record floods in zstd and LZ4 chunks (each < 5 MiB on disk)."""
    data = base_file.read_bytes()
    zero_rec = b'\x80' + b'\0' * 8  # an unknown zero-length record, 9 bytes
    msg = b'\x05' + struct.pack('<Q', 22) + b'\x01\x00' + b'\0' * 20  # empty message, ch 1
    specs = {
        'zstd_claims_4GiB': _chunk('zstd', zstd_stream(1 << 20), 4 << 30),
        'zstd_frame_1GiB_claims_1KiB': _chunk('zstd', zstd_stream(1 << 30), 1000),
        'zstd_zeros_200MiB': _chunk('zstd', zstd_stream(200 << 20), 200 << 20),
        'zstd_unknown_records_230MiB': _chunk('zstd', zstd_stream((230 << 20) // 9 * 9,
                                                                  zero_rec),
                                              (230 << 20) // 9 * 9),
        'zstd_empty_messages_120MiB': _chunk('zstd', zstd_stream(31 << 22, msg), 31 << 22),
        'lz4_frame_1GiB_claims_1KiB': _chunk('lz4', lz4_stream(1 << 30), 1000),
        'lz4_zeros_200MiB': _chunk('lz4', lz4_stream(200 << 20), 200 << 20),
        'lz4_claims_16GiB': _chunk('lz4', lz4_stream(1 << 20), 16 << 30),
        'none_claims_8GiB': _chunk('', b'\0' * 64, 8 << 30),
    }
    cases = []
    for name, chunk in specs.items():
        p = out / f'bomb_{name}.mcap'
        p.write_bytes(_no_summary(data, chunk))
        cases.append(Case(f'bomb_{name}', 'bomb', p))
    return cases


def build_corpus(out: Path, seed: int = 16) -> tuple[list[Case], Base]:
    """Write every non-bomb case into ``out``; return them and the base streams."""
    rng = np.random.default_rng(seed)
    b = simulate_base()
    cases: list[Case] = []
    out.mkdir(parents=True, exist_ok=True)
    base = {c: write_mcap(out / f'base_{c}.mcap', b, compression=c)
            for c in ('zstd', 'lz4', 'none')}
    for c, p in base.items():
        cases.append(Case(f'intact_{c}', 'intact', p, b.inertia))
    raw = {c: p.read_bytes() for c, p in base.items()}

    # truncations: 40 cut points per compression, more near the start and end
    for c, data in raw.items():
        cuts = np.unique(np.concatenate([rng.integers(0, len(data), 34),
                                         [0, 7, 8, 20, len(data) - 8, len(data) - 1]]))
        for k, cut in enumerate(cuts.tolist()):
            p = out / f'trunc_{c}_{k}.mcap'
            p.write_bytes(data[:cut])
            cases.append(Case(f'trunc_{c}_{cut}', 'truncate', p, b.inertia))
    # byte flips: 1, 3, 16 or 200 random bytes set to random values
    for c, data in raw.items():
        for k in range(24):
            buf = np.frombuffer(data, dtype=np.uint8).copy()
            n = (1, 3, 16, 200)[k % 4]
            at = rng.integers(8, buf.size - 8, n)
            buf[at] = rng.integers(0, 256, n, dtype=np.uint8)
            p = out / f'flip_{c}_{k}.mcap'
            p.write_bytes(buf.tobytes())
            cases.append(Case(f'flip_{c}_{k}', 'flip', p, b.inertia))
    cases += metadata_cases(out, base['zstd'])
    cases += short_record_cases(out, b)
    cases += footer_cases(out, raw['zstd'], b)
    cases += clock_cases(out, b)
    cases += pause_cases(out, b)
    cases += garbage_cases(out, rng)
    return cases, b


def _bag(out: Path, name: str, files: dict[str, bytes], meta: bytes | None) -> Path:
    d = out / name
    d.mkdir()
    for f, data in files.items():
        (d / f).write_bytes(data)
    if meta is not None:
        (d / 'metadata.yaml').write_bytes(meta)
    return d


def metadata_cases(out: Path, mcap_file: Path) -> list[Case]:
    """rosbag2 directories whose metadata.yaml has every wrong type and encoding."""
    data = mcap_file.read_bytes()
    good = {'version': 9, 'storage_identifier': 'mcap', 'relative_file_paths': ['b_0.mcap'],
            'topics_with_message_count': [{'topic_metadata': {'name': GYRO}, 'message_count':
                                           2001}]}
    bad_values = [0, 1.5, -3, 'text', '', True, None, [], [None], [1], [[]], {}, {'a': 1},
                  ['../../etc/passwd'], ['\x00'], [''], 2 ** 80]
    docs: dict[str, bytes] = {}
    for k, v in enumerate(bad_values):
        docs[f'info_{k}'] = yaml.safe_dump({'rosbag2_bagfile_information': v}).encode()
        for key in ('relative_file_paths', 'storage_identifier', 'compression_format',
                    'compression_mode', 'topics_with_message_count', 'version'):
            d = dict(good)
            d[key] = v
            docs[f'{key}_{k}'] = yaml.safe_dump({'rosbag2_bagfile_information': d}).encode()
    for k, v in enumerate(bad_values):
        docs[f'top_{k}'] = yaml.safe_dump(v).encode()
    twmc = dict(good)
    twmc['topics_with_message_count'] = [{'topic_metadata': 5, 'message_count': 'x'}, None,
                                         {'message_count': -4}]
    docs['twmc_garbage'] = yaml.safe_dump({'rosbag2_bagfile_information': twmc}).encode()
    docs['not_utf8'] = b'rosbag2_bagfile_information:\n  storage_identifier: \xff\xfe mcap\n'
    docs['utf16'] = yaml.safe_dump({'rosbag2_bagfile_information': good}).encode('utf-16')
    docs['bad_yaml'] = b'rosbag2_bagfile_information: [unclosed\n  - {'
    docs['tabs'] = b'rosbag2_bagfile_information:\n\t- x: y\n'
    docs['laughs'] = (b'a: &a ["x","x","x","x","x","x","x","x","x"]\n'
                      + b''.join(f'{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)},*{chr(97 + i)},'
                                 f'*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)},'
                                 f'*{chr(97 + i)},*{chr(97 + i)},*{chr(97 + i)}]\n'.encode()
                                 for i in range(8)))
    docs['python_tag'] = b'!!python/object/apply:os.system ["echo pwned"]\n'
    docs['empty'] = b''
    docs['sqlite3_but_mcap'] = yaml.safe_dump({'rosbag2_bagfile_information': {
        **good, 'storage_identifier': 'sqlite3'}}).encode()
    docs['zstd_file_but_plain'] = yaml.safe_dump({'rosbag2_bagfile_information': {
        **good, 'compression_format': 'zstd', 'compression_mode': 'FILE'}}).encode()
    docs['huge'] = b'x: "' + b'a' * (17 << 20) + b'"\n'
    cases = []
    for name, meta in docs.items():
        d = _bag(out, f'meta_{name}', {'b_0.mcap': data}, meta)
        cases.append(Case(f'meta_{name}', 'metadata', d))
    return cases


def short_record_cases(out: Path, b: Base) -> list[Case]:
    """Unchunked logs with a message record shorter than its 22-byte header."""
    p = write_mcap(out / 'unchunked.mcap', b, chunked=False, compression='none')
    data = p.read_bytes()
    recs = records(data)
    first_msg = next(s for op, s, _ in recs if op == 0x05)
    cases = []
    for n in range(0, 22):
        body = struct.pack('<H', 1) + b'\x07' * 20
        bad = _rec(0x05, body[:n])
        q = out / f'short_{n}.mcap'
        q.write_bytes(data[:first_msg] + bad + data[first_msg:])
        cases.append(Case(f'short_record_{n}', 'short_record', q))
    # a short record as the very last record before the data end, and in a chunk
    q = out / 'short_last.mcap'
    end = next(s for op, s, _ in recs if op == 0x0F)
    q.write_bytes(data[:end] + _rec(0x05, b'\x01'))
    cases.append(Case('short_record_at_end', 'short_record', q))
    inner = _rec(0x05, b'\x01\x00\x02')
    q = out / 'short_in_chunk.mcap'
    q.write_bytes(_no_summary(data, _chunk('', inner, len(inner))))
    cases.append(Case('short_record_in_chunk', 'short_record', q))
    return cases


def footer_cases(out: Path, data: bytes, b: Base) -> list[Case]:
    """Intact data sections behind damaged footers and summaries."""
    foot = len(data) - 8 - 29
    assert data[foot] == 0x02
    s0, s1, crc = struct.unpack_from('<QQI', data, foot + 9)
    variants = {
        'summary_start_huge': struct.pack('<QQI', 2 ** 63, s1, crc),
        'summary_start_max': struct.pack('<QQI', 2 ** 64 - 1, 2 ** 64 - 1, 2 ** 32 - 1),
        'summary_start_in_data': struct.pack('<QQI', 100, s1, 0),
        'summary_start_4': struct.pack('<QQI', 4, s1, 0),
        'summary_start_footer': struct.pack('<QQI', foot, s1, 0),
        'summary_start_eof': struct.pack('<QQI', len(data), s1, crc),
        'summary_crc_wrong': struct.pack('<QQI', s0, s1, crc ^ 0xFFFF),
        'summary_offsets_wrong': struct.pack('<QQI', s0, 12345, 0),
        'all_zero': struct.pack('<QQI', 0, 0, 0),
        'all_ff': b'\xff' * 20,
    }
    cases = []
    for name, body in variants.items():
        q = out / f'footer_{name}.mcap'
        q.write_bytes(data[:foot + 9] + body + data[foot + 29:])
        cases.append(Case(f'footer_{name}', 'footer', q, b.inertia))
    for name, cut in (('opcode', lambda d: d[:foot] + b'\x09' + d[foot + 1:]),
                      ('length', lambda d: d[:foot + 1] + b'\xff' * 8 + d[foot + 9:]),
                      ('magic', lambda d: d[:-3] + b'\0\0\0'),
                      ('no_magic', lambda d: d[:-8]),
                      ('summary_garbage', lambda d: d[:s0] + bytes(range(256)) * (
                          (foot - s0) // 256) + d[s0 + (foot - s0) // 256 * 256:])):
        q = out / f'footer_{name}.mcap'
        q.write_bytes(cut(data))
        cases.append(Case(f'footer_{name}', 'footer', q, b.inertia))
    return cases


def clock_cases(out: Path, b: Base) -> list[Case]:
    """One stream's clock steps back (or both restart) under every storage order."""
    cases = []
    for k, (who, at, step) in enumerate([('gyro', 10.0, 10.0), ('gyro', 5.0, 10.0),
                                         ('gyro', 15.0, 3.0), ('gyro', 10.0, 10.0037),
                                         ('torque', 10.0, 10.0), ('gyro', 8.0, 86400.0)]):
        tg, tt = b.tg.copy(), b.tt.copy()
        st = int(round(step * 1e9))
        if who == 'gyro':
            tg[b.tg >= T0 + int(at * 1e9)] -= st
        else:
            tt[b.tt >= T0 + int(at * 1e9)] -= st
        f = Base(tg, b.w, tt, b.tau, b.inertia)
        # arrival order kept in the file (log time = receive time, the true time)
        cases.append(Case(f'clock_{who}_{at}_{step}_recv', 'clock',
                          write_mcap(out / f'clock{k}_recv.mcap', f, log_g=b.tg, log_t=b.tt),
                          b.inertia))
        # log time = header stamp: stored in stamp order, sequence numbers keep arrival
        cases.append(Case(f'clock_{who}_{at}_{step}_stamp', 'clock',
                          write_mcap(out / f'clock{k}_stamp.mcap', f), b.inertia))
        # stamp order and no sequence numbers: arrival order is lost
        cases.append(Case(f'clock_{who}_{at}_{step}_noseq', 'clock',
                          write_mcap(out / f'clock{k}_noseq.mcap', f, sequence=False),
                          b.inertia))
    # both clocks restart (a looped recording), stamps and log times
    tg, tt = b.tg.copy(), b.tt.copy()
    tg[b.tg >= T0 + 10 * 10 ** 9] -= 10 * 10 ** 9
    tt[b.tt >= T0 + 10 * 10 ** 9] -= 10 * 10 ** 9
    f = Base(tg, b.w, tt, b.tau, b.inertia)
    cases.append(Case('clock_both_restart_recv', 'clock',
                      write_mcap(out / 'restart_recv.mcap', f, log_g=b.tg, log_t=b.tt),
                      b.inertia))
    cases.append(Case('clock_both_restart_stamp', 'clock',
                      write_mcap(out / 'restart_stamp.mcap', f), b.inertia))
    return cases


def pause_cases(out: Path, b: Base) -> list[Case]:
    """Pauses of 100 s to 30 days inside the log (both streams, or the torque only)."""
    cases = []
    for k, (pause, at, who) in enumerate([(100.0, 10.0, 'both'), (3600.0, 10.0, 'both'),
                                          (86400.0, 10.0, 'both'), (86400.0, 3.0, 'both'),
                                          (30 * 86400.0, 17.0, 'both'),
                                          (86400.0, 10.0, 'torque'), (4.0, 10.0, 'both')]):
        p = int(round(pause * 1e9))
        cut = T0 + int(at * 1e9)
        tg = np.where(b.tg >= cut, b.tg + p, b.tg)
        tt = np.where(b.tt >= cut, b.tt + p, b.tt)
        w, tau, tgk = b.w, b.tau, tg
        if who == 'torque':  # gyro keeps running (its samples over the pause are dropped)
            tgk = b.tg
        f = Base(tgk, w, tt, tau, b.inertia)
        cases.append(Case(f'pause_{who}_{pause:g}s_at_{at:g}', 'pause',
                          write_mcap(out / f'pause{k}.mcap', f), b.inertia))
    return cases


def garbage_cases(out: Path, rng: np.random.Generator) -> list[Case]:
    """Files that are not MCAP logs at all, and empty directories."""
    items = {
        'empty': b'', 'magic_only': MAGIC, 'magic_twice': MAGIC + MAGIC,
        'random': rng.integers(0, 256, 5000, dtype=np.uint8).tobytes(),
        'magic_random': MAGIC + rng.integers(0, 256, 5000, dtype=np.uint8).tobytes(),
        'magic_zeros': MAGIC + b'\0' * 100000,
        'text': b'hello, this is not a log\n' * 10,
        'huge_record': MAGIC + _rec(0x05, b'')[:1] + struct.pack('<Q', 2 ** 63) + b'\0' * 40,
    }
    cases = []
    for name, data in items.items():
        p = out / f'garbage_{name}.mcap'
        p.write_bytes(data)
        cases.append(Case(f'garbage_{name}', 'garbage', p))
    d = out / 'garbage_empty_dir'
    d.mkdir()
    cases.append(Case('garbage_empty_dir', 'garbage', d))
    return cases


def digest(path: Path) -> str:
    """sha256 over a file, or over every file of a directory (names and bytes)."""
    h = hashlib.sha256()
    files = sorted(path.rglob('*')) if path.is_dir() else [path]
    for f in files:
        if f.is_file():
            h.update(str(f.relative_to(path.parent)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()
