"""Every rosbag2 storage reads into the same arrays: sqlite3 and compressed bags via rosbags.

A bag written by rosbags from the very messages (same CDR payloads, same log times) of a
committed MCAP log must give the same cleaned arrays, bit for bit, and the same estimate.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import ROOT
from inertia_ros.io.logs import LogError, log_files, read_log
from inertia_ros.io.mcap_reader import McapReader
from inertia_ros.io.rosbag2 import read_bag_info

rosbag2 = pytest.importorskip('rosbags.rosbag2')
typesys = pytest.importorskip('rosbags.typesys')

BAG = ROOT / 'bags' / 'default.mcap'


def _messages(path: Path) -> tuple[dict[str, str], list[tuple[str, int, bytes]]]:
    with McapReader(path) as r:
        msgs = [(ch.topic, t, p) for _, ch, t, p in r.iter_messages()]
        types = {ch.topic: r.schemas[ch.schema_id].name for ch in r.channels.values()}
    return types, msgs


def write_twin(src: Path, out: Path, *, storage: str = 'sqlite3', mode: str | None = None
               ) -> Path:
    """Write the messages of MCAP log ``src`` into a rosbags bag directory ``out``."""
    types, msgs = _messages(src)
    store = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
    plugin = {'sqlite3': rosbag2.StoragePlugin.SQLITE3, 'mcap': rosbag2.StoragePlugin.MCAP}
    w = rosbag2.Writer(out, version=9, storage_plugin=plugin[storage])
    if mode is not None:
        w.set_compression(getattr(rosbag2.CompressionMode, mode), rosbag2.CompressionFormat.ZSTD)
    with w:
        conns = {t: w.add_connection(t, ty, typestore=store) for t, ty in types.items()}
        for topic, t, payload in msgs:
            w.write(conns[topic], t, payload)
    return out


def _same(a, b) -> None:
    for s in ('omega', 'torque'):
        sa, sb = getattr(a, s), getattr(b, s)
        np.testing.assert_array_equal(sa.t, sb.t)
        np.testing.assert_array_equal(sa.values, sb.values)
        assert sa.counts.as_dict() == sb.counts.as_dict()
        assert (sa.topic, sa.msg_type, sa.frame_id) == (sb.topic, sb.msg_type, sb.frame_id)
    assert a.epoch_ns == b.epoch_ns
    assert a.windows == b.windows
    assert len(a.truth) == len(b.truth)


@pytest.mark.parametrize('storage,mode', [('sqlite3', None), ('sqlite3', 'MESSAGE'),
                                          ('mcap', 'FILE'), ('mcap', 'MESSAGE')])
def test_rosbags_bag_gives_the_arrays_of_its_mcap_twin(tmp_path: Path, storage: str,
                                                       mode: str | None) -> None:
    bag = write_twin(BAG, tmp_path / 'twin', storage=storage, mode=mode)
    info = read_bag_info(bag)
    assert info is not None and not info.own_mcap_path
    _same(read_log(bag), read_log(BAG))


def test_db3_bag_estimates_the_tensor_of_its_mcap_twin(tmp_path: Path, capsys) -> None:
    import json

    from inertia_ros.cli import main

    bag = write_twin(BAG, tmp_path / 'twin')
    reports = []
    for src in (BAG, bag):
        assert main(['estimate', str(src), '--format', 'json', '--no-progress']) == 0
        reports.append(json.loads(capsys.readouterr().out))
    a, b = reports
    assert a['status'] == b['status'] == 'ok'
    np.testing.assert_allclose(b['inertia'], a['inertia'], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b['inertia_std'], a['inertia_std'], rtol=0, atol=1e-12)


def test_db3_file_alone_names_its_bag(tmp_path: Path) -> None:
    bag = write_twin(BAG, tmp_path / 'twin')
    db3 = next(bag.glob('*.db3'))
    with pytest.raises(LogError, match=f'pass the bag directory {bag}'):
        log_files(db3)


def test_missing_rosbags_is_one_line_naming_the_package(tmp_path: Path, monkeypatch) -> None:
    bag = write_twin(BAG, tmp_path / 'twin')
    monkeypatch.setitem(sys.modules, 'rosbags', None)  # import rosbags -> ImportError
    with pytest.raises(LogError, match=r"needs the Python package 'rosbags'.*pip install "
                                       r'rosbags==') as exc:
        read_log(bag)
    assert '\n' not in str(exc.value)


def test_missing_codec_is_one_line_naming_the_package(tmp_path: Path, monkeypatch) -> None:
    """A zstd MCAP without the zstandard package: the package named, not "empty stream"."""
    monkeypatch.setitem(sys.modules, 'zstandard', None)
    with pytest.raises(LogError, match=r"zstd-compressed chunks need the Python package "
                                       r"'zstandard': pip install zstandard") as exc:
        read_log(BAG)
    assert '\n' not in str(exc.value)


def test_bag_files_missing_is_one_line(tmp_path: Path) -> None:
    bag = write_twin(BAG, tmp_path / 'twin')
    for f in bag.glob('*.db3'):
        f.unlink()
    with pytest.raises(LogError, match='none of the files metadata.yaml lists'):
        read_log(bag)


def test_rosbags_damage_is_one_line(tmp_path: Path) -> None:
    bag = write_twin(BAG, tmp_path / 'twin')
    db3 = next(bag.glob('*.db3'))
    db3.write_bytes(db3.read_bytes()[:3000])
    with pytest.raises(LogError) as exc:
        read_log(bag)
    assert '\n' not in str(exc.value) and str(bag) in str(exc.value)


def test_metadata_is_parsed_once_into_types(tmp_path: Path) -> None:
    bag = write_twin(BAG, tmp_path / 'twin')
    info = read_bag_info(bag)
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info.storage == 'sqlite3'
    assert [f.name for f in info.files] == meta['relative_file_paths']
    assert info.message_counts == {t['topic_metadata']['name']: t['message_count']
                                   for t in meta['topics_with_message_count']}
    assert read_bag_info(tmp_path) is None


_RSS_RUNNER = r'''
import resource, sys
from inertia_ros.io.logs import LogError, read_log
try:
    read_log(sys.argv[1])
    print('read')
except LogError as exc:
    print('error', exc)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
'''


def test_message_compressed_bomb_is_one_line_and_bounded(tmp_path: Path) -> None:
    """A 1 GiB zstd bomb in a message-compressed .db3: one line, peak memory < 1 GiB."""
    import sqlite3
    import subprocess

    from fuzz_corpus import zstd_stream

    bag = write_twin(BAG, tmp_path / 'twin', mode='MESSAGE')
    db3 = next(bag.glob('*.db3'))
    con = sqlite3.connect(db3)
    with con:
        con.execute('UPDATE messages SET data = ? WHERE id = 5', (zstd_stream(1 << 30),))
    con.close()
    proc = subprocess.run([sys.executable, '-c', _RSS_RUNNER, str(bag)], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    first, rss = proc.stdout.strip().splitlines()
    assert first.startswith('error ') and 'decompression bomb' in first, first
    assert int(rss) < 1 << 30, f'peak {int(rss) / 2 ** 20:.0f} MiB'
