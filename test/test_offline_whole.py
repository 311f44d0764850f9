"""``bench offline --whole`` and the reader's chunk grouping (issue 18 item 6).

The whole-process benchmark is run on a half-minute log (its figures are not asserted: a
benchmark, not a timed test); the reader must give the same messages, in the same order,
whether consecutive chunks are decoded one by one or joined into groups.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from inertia_ros.bench.offline import build_log
from inertia_ros.cli import main
from inertia_ros.io.logs import read_log
from inertia_ros.io.mcap_reader import McapReader


@pytest.fixture(scope='module')
def small_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A one-minute benchmark log in 64 KiB zstd chunks (~150 chunks)."""
    path = tmp_path_factory.mktemp('bag') / 'bag_0.mcap'
    assert build_log(path, 1.0, 'zstd', chunk_size=64 << 10) == 15000
    return path


def _batches(path: Path) -> dict[str, tuple[np.ndarray, ...]]:
    """Per topic: (payload bytes joined, log times, ordinals, sequence numbers)."""
    out: dict[str, list[list]] = {}
    with McapReader(path) as r:
        for b in r.iter_batches():
            parts = out.setdefault(b.channel.topic, [[], [], [], []])
            parts[0].extend(b.payload(k) for k in range(len(b)))
            parts[1].append(b.log_time)
            parts[2].append(b.ordinal)
            parts[3].append(b.sequence)
    return {t: (b''.join(p[0]), *(np.concatenate(x) for x in p[1:])) for t, p in out.items()}


def _assert_same_batches(a: dict, b: dict) -> None:
    """Two readings (:func:`_batches`) hold the same fields per topic, exactly."""
    for topic in b:
        for x, y in zip(a[topic], b[topic], strict=True):
            if isinstance(x, bytes):
                assert x == y
            else:
                np.testing.assert_array_equal(x, y)


def test_chunk_groups_read_the_same_messages(small_log: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """Chunk by chunk (GROUP_BYTES 0) and in groups: identical payloads, times, ordinals."""
    grouped = _batches(small_log)
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', 0)
    single = _batches(small_log)
    assert set(grouped) == set(single) == {'/imu', '/torque'}
    _assert_same_batches(grouped, single)
    assert grouped['/imu'][2].size == 12000 and grouped['/torque'][2].size == 3000
    assert np.all(np.diff(grouped['/imu'][2]) > 0)           # ordinals in file order


def test_read_log_is_the_same_with_and_without_groups(small_log: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The assembled streams do not depend on the grouping (exact equality)."""
    a = read_log(small_log)
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', 0)
    b = read_log(small_log)
    for sa, sb in ((a.omega, b.omega), (a.torque, b.torque)):
        np.testing.assert_array_equal(sa.t, sb.t)
        np.testing.assert_array_equal(sa.values, sb.values)
    assert a.omega.counts.received == 12000 and a.torque.counts.received == 3000


@pytest.mark.parametrize('layout', ['zstd', 'none'])
def test_worker_thread_reads_the_same_messages_and_damage(
        small_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, layout: str) -> None:
    """Chunks loaded on the worker thread or inline: identical batches, and on a file with
    damaged chunks (CRC, decompression) the same damage notes in the same order."""
    path = small_log
    if layout == 'none':
        path = tmp_path / 'plain' / 'bag_0.mcap'
        path.parent.mkdir()
        build_log(path, 0.25, 'none', chunk_size=64 << 10)
    monkeypatch.setattr(McapReader, 'GROUP_BYTES', 256 << 10)   # several groups
    monkeypatch.setattr(McapReader, 'THREADS', True)
    threaded = _batches(path)
    monkeypatch.setattr(McapReader, 'THREADS', False)
    inline = _batches(path)
    _assert_same_batches(threaded, inline)
    # damage three chunks' records: the readers must skip and count the same chunks
    data = bytearray(path.read_bytes())
    with McapReader(path) as r:
        starts = sorted(ci.chunk_start_offset + ci.chunk_length // 2 for ci in r.chunk_indexes)
    for k in (1, 5, 6):
        data[starts[k]] ^= 0xFF
    bad = tmp_path / 'damaged.mcap'
    bad.write_bytes(bytes(data))
    notes = {}
    for threads in (True, False):
        monkeypatch.setattr(McapReader, 'THREADS', threads)
        with McapReader(bad) as r:
            n = sum(len(b) for b in r.iter_batches())
            notes[threads] = (n, r.damage.corrupt_chunks, r.damage.messages_lost,
                              list(r.damage.notes))
    assert notes[True] == notes[False]
    assert notes[True][1] == 3


def test_build_log_writes_a_rosbag2_bag(small_log: Path) -> None:
    """The benchmark log's directory is a bag: metadata.yaml names the file and counts."""
    import yaml

    meta = yaml.safe_load((small_log.parent / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == [small_log.name]
    assert info['message_count'] == 15000
    log = read_log(small_log.parent)                 # and our reader opens it as a bag
    assert log.omega.counts.received == 12000


def test_bench_offline_whole_small(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``--whole`` on a half-minute log: both layouts, every phase, the peers decode every
    message (or are skipped with a note), and the Markdown section has a row per layout."""
    out, md = tmp_path / 'r.json', tmp_path / 'offline.md'
    assert main(['bench', 'offline', '--whole', '--minutes', '0.5', '--repeat', '1',
                 '--peer-repeat', '1', '--json', str(out), '--md', str(md)]) == 0
    res = json.loads(out.read_text())['results']
    assert set(res) == {'uncompressed', 'zstd'}
    for r in res.values():
        assert r['messages'] == 7500 and r['status'] == 'ok'
        assert set(r['phases']) == {'interpreter', 'imports', 'read', 'estimate', 'report'}
        assert all(v >= 0 for v in r['phases'].values())
        assert set(r['peers']) | {n.split(':')[0] for n in r['notes']} == {'mcap_ros2',
                                                                              'rosbags'}
    text = md.read_text()
    assert '## Offline single log: whole process' in text
    assert '| uncompressed |' in text and '| zstd |' in text
    assert 'bench offline --whole --minutes 0.5' in text
    assert 'whole process' in capsys.readouterr().out
