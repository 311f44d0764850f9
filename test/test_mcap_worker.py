"""The MCAP reader's chunk worker thread (``McapReader.THREADS``) and its lookahead.

With the worker, chunks are loaded (file read, decompression, CRC) up to
``McapReader.LOOKAHEAD`` bytes ahead of the chunk being checked, while the caller decodes
earlier groups.  Whatever the chunk layout, the lookahead and the damage, the batches, the
damage counts and notes (in order) and the errors must be those of the sequential reader, and
the thread must be gone once reading ends, however it ends.
"""
from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from inertia_ros.bench.offline import build_log
from inertia_ros.io.logs import LogError, read_log
from inertia_ros.io.mcap_chunks import ChunkFiller
from inertia_ros.io.mcap_reader import McapReader


def _workers() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == 'mcap-chunks']


@pytest.fixture(scope='module')
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Quarter-minute benchmark logs: zstd in 16 KiB chunks, uncompressed in 64 KiB ones."""
    out = {}
    for name, comp, size in (('zstd', 'zstd', 16 << 10), ('none', 'none', 64 << 10)):
        path = tmp_path_factory.mktemp(name) / 'bag_0.mcap'
        assert build_log(path, 0.25, comp, chunk_size=size) == 5000
        out[name] = path
    return out


def _reading(path: Path) -> tuple:
    """Everything a reading gives: per batch its topic, payloads, times, ordinals, sequence
    numbers; then the message count and the damage (counts and notes in order)."""
    batches = []
    with McapReader(path) as r:
        for b in r.iter_batches():
            batches.append((b.channel.topic, b''.join(b.payload(k) for k in range(len(b))),
                            b.log_time.tolist(), b.ordinal.tolist(), b.sequence.tolist()))
        d = r.damage
        return (batches, r.messages_read, d.truncated, d.corrupt_chunks, d.messages_lost,
                d.bytes_lost, list(d.notes))


def _both(path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[tuple, tuple]:
    """(threaded, sequential) readings of ``path``."""
    out = []
    for threads in (True, False):
        monkeypatch.setattr(McapReader, 'THREADS', threads)
        out.append(_reading(path))
    assert not _workers()
    return out[0], out[1]


@pytest.mark.parametrize('layout', ['zstd', 'none'])
@pytest.mark.parametrize(('group', 'ahead'), [(0, 0), (0, 1 << 20), (64 << 10, 32 << 10),
                                              (256 << 10, 8 << 20), (8 << 20, 8 << 20)])
def test_worker_reads_what_the_sequential_reader_reads(
        logs: dict[str, Path], monkeypatch: pytest.MonkeyPatch, layout: str, group: int,
        ahead: int) -> None:
    """Groups of one chunk or many, lookahead of nothing, part of a group or the whole file:
    the same batches, in the same order."""
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', group)
    monkeypatch.setattr(McapReader, 'LOOKAHEAD', ahead)
    threaded, sequential = _both(logs[layout], monkeypatch)
    assert threaded == sequential
    assert sum(len(b[3]) for b in threaded[0]) == threaded[1] == 5000


def _damaged(src: Path, dst: Path, how: str) -> Path:
    """A copy of ``src`` with chunks' records flipped, garbage between chunks, or cut off."""
    data = bytearray(src.read_bytes())
    with McapReader(src) as r:
        idx = sorted(r.chunk_indexes, key=lambda ci: ci.chunk_start_offset)
    if how == 'records':
        for k in (1, 7, 8, len(idx) - 2):
            data[idx[k].chunk_start_offset + idx[k].chunk_length // 2] ^= 0xFF
    elif how == 'between':
        # a chunk's opcode zeroed (an invalid record): read on from the next indexed chunk
        data[idx[len(idx) // 2].chunk_start_offset] = 0
        data[idx[3].chunk_start_offset + 1:idx[3].chunk_start_offset + 9] = b'\xff' * 8
        for k in (2, len(idx) // 2 + 1):         # and corrupt chunks near them
            data[idx[k].chunk_start_offset + idx[k].chunk_length // 2] ^= 0xFF
    elif how == 'cut':
        del data[idx[len(idx) // 2].chunk_start_offset + 100:]
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize('layout', ['zstd', 'none'])
@pytest.mark.parametrize('how', ['records', 'between', 'cut'])
@pytest.mark.parametrize('ahead', [64 << 10, 8 << 20])
def test_damage_is_counted_the_same_in_the_same_order(
        logs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, layout: str,
        how: str, ahead: int) -> None:
    """Corrupt chunks mid-file, damage between chunks (met while later chunks are loading)
    and a cut-off file: same messages, damage counts and notes, in order."""
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', 128 << 10)
    monkeypatch.setattr(McapReader, 'LOOKAHEAD', ahead)
    bad = _damaged(logs[layout], tmp_path / 'bad.mcap', how)
    threaded, sequential = _both(bad, monkeypatch)
    assert threaded == sequential
    assert threaded[-1] and threaded[4] > 0        # notes, messages lost
    assert threaded[3] == {'records': 4, 'between': 2, 'cut': 0}[how]
    a = read_log(bad)
    monkeypatch.setattr(McapReader, 'THREADS', False)
    b = read_log(bad)
    for sa, sb in ((a.omega, b.omega), (a.torque, b.torque)):
        np.testing.assert_array_equal(sa.t, sb.t)
        np.testing.assert_array_equal(sa.values, sb.values)
    assert a.warnings == b.warnings


def test_read_log_arrays_are_identical(logs: dict[str, Path],
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """read_log with and without the worker: bit-identical streams and windows."""
    for path in logs.values():
        got = []
        for threads in (True, False):
            monkeypatch.setattr(McapReader, 'THREADS', threads)
            got.append(read_log(path))
        a, b = got
        for sa, sb in ((a.omega, b.omega), (a.torque, b.torque)):
            assert sa.t.tobytes() == sb.t.tobytes()
            assert sa.values.tobytes() == sb.values.tobytes()
        assert a.windows == b.windows and a.warnings == b.warnings


def test_an_error_in_the_worker_is_raised_in_the_reader(
        logs: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """An unexpected failure while a chunk loads on the worker (here a read error on the
    fifth chunk) is raised by iter_batches as it is without the worker, and the thread
    stops."""
    fill = ChunkFiller.__call__
    calls = []

    def failing(self: ChunkFiller, *job: object) -> tuple:
        calls.append(threading.current_thread().name)
        if len(calls) == 5:
            raise OSError('disk on fire')
        return fill(self, *job)

    monkeypatch.setattr(ChunkFiller, '__call__', failing)
    for threads in (True, False):
        calls.clear()
        monkeypatch.setattr(McapReader, 'THREADS', threads)
        with McapReader(logs['zstd']) as r, pytest.raises(OSError, match='disk on fire'):
            for _ in r.iter_batches():
                pass
        assert not _workers()
        assert ('mcap-chunks' in calls) == threads


def test_missing_codec_is_the_same_one_line_error(
        logs: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """A codec missing (found out on the worker): read_log's one-line LogError, as without."""
    import sys

    monkeypatch.setitem(sys.modules, 'zstandard', None)
    msgs = []
    for threads in (True, False):
        monkeypatch.setattr(McapReader, 'THREADS', threads)
        with pytest.raises(LogError, match="need the Python package 'zstandard'") as exc:
            read_log(logs['zstd'])
        msgs.append(str(exc.value))
        assert not _workers()
    assert msgs[0] == msgs[1] and '\n' not in msgs[0]


def test_worker_stops_when_the_caller_stops_early(
        logs: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    """A caller that stops reading (an error of its own, Ctrl-C) leaves no thread behind."""
    monkeypatch.setattr(McapReader, 'THREADS', True)
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', 64 << 10)
    with McapReader(logs['none']) as r:
        it = r.iter_batches()
        next(it)
        assert len(_workers()) == (1 if McapReader.THREADS and _cpus_ok() else 0)
        with pytest.raises(KeyboardInterrupt):
            it.throw(KeyboardInterrupt)
    assert not _workers()


def _cpus_ok() -> bool:
    from inertia_ros.io.mcap_reader import _cpus

    return _cpus() > 1
