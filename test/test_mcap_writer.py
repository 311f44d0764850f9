"""MCAP writing: CDR encoding, ros2msg schemas, rosbag2 conventions, independent read-back."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('mcap_ros2')  # optional test dependency
pytest.importorskip('rosbags')  # optional test dependency
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.rosbag2.metadata import parse_qos

from conftest import ROOT
from inertia_ros.cli import main
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io import cdr_encode, msgtypes
from inertia_ros.io.cdr_encode import IMU, INERTIA_STAMPED, WRENCH_STAMPED
from inertia_ros.io.mcap_writer import (
    DEFAULT_START_NS,
    McapWriter,
    McapWriterError,
    qos_yaml,
    seconds_to_ns,
    type_description_hash,
    write_simulation,
)
from inertia_ros.io.scene_file import load_scene

SCENE = {
    'name': 'writer_test', 'seed': 3, 'duration': 4.0,
    'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
    'initial_omega': [0.05, -0.03, 0.02],
    'torque': [{'type': 'multisine', 'amplitude': 0.1}],
    'gyro': {'rate': 200.0, 'noise_std': 0.002, 'frame_id': 'imu_link'},
    'torque_sensor': {'rate': 50.0, 'noise_rel': 0.02},
    'imperfections': {'timestamp_jitter': 0.0004, 'torque_delay': -0.01, 'drop_rate': 0.05},
    'inertia_change': {'time': 2.0, 'inertia': [0.8, 0.95, 0.75, 0.03, -0.02, 0.015]},
}


@pytest.fixture(scope='module')
def written(tmp_path_factory):
    """A simulated scene with every imperfection, written once for the read-back tests."""
    res = simulate(Scene.from_dict(SCENE))
    path = tmp_path_factory.mktemp('mcap') / 'sim.mcap'
    counts = write_simulation(path, res, start_ns=DEFAULT_START_NS + 123)
    return path, res, counts


def _expected_ns(t):
    return DEFAULT_START_NS + 123 + np.rint(np.asarray(t) * 1e9).astype(np.int64)


def _vec(v):
    return [v.x, v.y, v.z]


# --------------------------------------------------------------------------- CDR encoding
@pytest.mark.ros
def test_encoding_matches_rclpy_serialization():
    """Our CDR bytes equal rclpy's serialize_message except alignment padding, and decode."""
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu

    from inertia_ros.nodes.messages import imu_msg

    t = np.array([0, 1_700_000_000_123_456_789, -1_500_000_000], dtype=np.int64)
    w = np.random.default_rng(0).normal(size=(3, 3))
    ours = cdr_encode.encode_imu(t, w, 'base_link')
    for i in range(3):
        ref = serialize_message(imu_msg(int(t[i]), w[i], 'base_link'))
        assert len(ref) == len(ours[i]) == 324
        pad = slice(4 + 8 + 4 + 10, 4 + 24)            # after 'base_link\0', up to 8-alignment
        a, b = bytearray(ours[i]), bytearray(ref)
        a[pad] = b[pad] = b'\0' * (pad.stop - pad.start)
        assert a == b
        msg = deserialize_message(ours[i], Imu)
        assert _vec(msg.angular_velocity) == w[i].tolist()
        ns = int(t[i])
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(ns, 10**9)


@pytest.mark.ros
@pytest.mark.parametrize('frame', ['', 'a', 'base_link', 'seven77', 'frame_with_utf8_é'])
def test_alignment_for_every_frame_length(frame):
    """The float64 block is 8-aligned after the header for every frame_id length."""
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import deserialize_message

    tau = np.array([[1.5, -2.25, 3.125]])
    data = cdr_encode.encode_wrench_stamped(np.array([42]), tau, frame)[0]
    assert (len(data) - 4 - 48) % 8 == 0
    msg = deserialize_message(data, WrenchStamped)
    assert msg.header.frame_id == frame and _vec(msg.wrench.torque) == tau[0].tolist()
    assert _vec(msg.wrench.force) == [0.0, 0.0, 0.0]


@pytest.mark.ros
def test_inertia_stamped_field_order():
    """InertiaStamped carries ixx, ixy, ixz, iyy, iyz, izz as matrix elements."""
    from geometry_msgs.msg import InertiaStamped
    from rclpy.serialization import deserialize_message

    I = np.array([[1.0, 0.05, -0.03], [0.05, 1.2, 0.02], [-0.03, 0.02, 0.9]])
    data = cdr_encode.encode_inertia_stamped(np.array([5]), I, 'b', mass=3.0,
                                             com=[0.1, 0.2, 0.3])[0]
    m = deserialize_message(data, InertiaStamped).inertia
    assert (m.m, _vec(m.com)) == (3.0, [0.1, 0.2, 0.3])
    assert [m.ixx, m.ixy, m.ixz, m.iyy, m.iyz, m.izz] == [1.0, 0.05, -0.03, 1.2, 0.02, 0.9]


def test_split_stamp_negative_and_range():
    """Stamps split as floor seconds + nanoseconds in [0, 1e9); int32 overflow is refused."""
    sec, nsec = cdr_encode.split_stamp([-1_700_000_000, 2_500_000_001])
    assert sec.tolist() == [-2, 2] and nsec.tolist() == [300_000_000, 500_000_001]
    with pytest.raises(ValueError, match='int32'):
        cdr_encode.split_stamp([2**31 * 10**9])
    with pytest.raises(ValueError, match='integer nanoseconds'):
        cdr_encode.split_stamp([1.5])


@pytest.mark.parametrize(('call', 'pattern'), [
    (lambda: cdr_encode.encode_imu([1, 2], np.zeros((3, 3)), 'f'), r'omega: expected shape'),
    (lambda: cdr_encode.encode_imu([1], np.zeros((1, 3)), 'f',
                                   angular_velocity_covariance=[1, 2]), 'expected 9 values'),
    (lambda: cdr_encode.encode_wrench_stamped([1], np.zeros((1, 3)), None), 'frame_id'),
    (lambda: cdr_encode.encode_inertia_stamped([1], np.eye(2), 'f'), 'inertia: expected'),
    (lambda: cdr_encode.schema_text('std_msgs/msg/String'), 'no schema for'),
])
def test_encoders_validate_arguments(call, pattern):
    """Encoders raise ValueError naming the bad argument."""
    with pytest.raises(ValueError, match=pattern):
        call()


def test_schema_text_has_rosbag2_dependency_blocks():
    """Schemas list each dependency once after a line of 80 '=' and 'MSG: pkg/Type'."""
    text = cdr_encode.schema_text(cdr_encode.IMU)
    blocks = text.split('\n' + '=' * 80 + '\n')
    assert blocks[0].startswith('std_msgs/Header header\n')
    names = [b.splitlines()[0] for b in blocks[1:]]
    assert sorted(names) == ['MSG: builtin_interfaces/Time', 'MSG: geometry_msgs/Quaternion',
                             'MSG: geometry_msgs/Vector3', 'MSG: std_msgs/Header']
    wrench = cdr_encode.schema_text(cdr_encode.WRENCH_STAMPED)
    assert wrench.count('MSG: geometry_msgs/Vector3') == 1
    assert 'MSG: geometry_msgs/Wrench\n' in wrench


# --------------------------------------------------------------------------- read-back
def test_rosbags_reads_back_the_same_values(written):
    """rosbags (schemas parsed from the file) decodes every value and stamp exactly."""
    path, res, counts = written
    got: dict[str, list] = {'/imu': [], '/torque': [], '/truth/inertia': []}
    with AnyReader([path]) as rd:
        assert {c.topic: c.msgtype for c in rd.connections} == {
            '/imu': 'sensor_msgs/msg/Imu', '/torque': 'geometry_msgs/msg/WrenchStamped',
            '/truth/inertia': 'geometry_msgs/msg/InertiaStamped'}
        for conn, log_ns, raw in rd.messages():
            msg = rd.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            assert stamp == log_ns, 'log time equals header stamp'
            assert msg.header.frame_id == 'imu_link'
            got[conn.topic].append((stamp, msg))
    imu, tq, truth = got['/imu'], got['/torque'], got['/truth/inertia']
    assert {k: len(v) for k, v in got.items()} == counts
    np.testing.assert_array_equal([s for s, _ in imu], _expected_ns(res.t_gyro))
    np.testing.assert_array_equal([_vec(m.angular_velocity) for _, m in imu], res.omega)
    np.testing.assert_array_equal([s for s, _ in tq], _expected_ns(res.t_torque))
    np.testing.assert_array_equal([_vec(m.wrench.torque) for _, m in tq], res.torque)
    cov = imu[0][1].angular_velocity_covariance
    np.testing.assert_array_equal(cov, np.diag([0.002**2] * 3).ravel())
    assert imu[0][1].orientation_covariance[0] == -1.0
    mats = [[[i.ixx, i.ixy, i.ixz], [i.ixy, i.iyy, i.iyz], [i.ixz, i.iyz, i.izz]]
            for i in (m.inertia for _, m in truth)]
    np.testing.assert_array_equal(mats, [res.inertia, res.inertia_changes[0][1]])
    np.testing.assert_array_equal([s for s, _ in truth], _expected_ns([0.0, 2.0]))


def test_mcap_ros2_decoder_reads_back_the_same_values(written):
    """mcap_ros2's DecoderFactory decodes the same stamps and float64 values exactly."""
    path, res, _ = written
    imu, tq = [], []
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            assert message.log_time == message.publish_time
            if channel.topic == '/imu':
                imu.append((message.log_time, _vec(msg.angular_velocity)))
            elif channel.topic == '/torque':
                tq.append((message.log_time, _vec(msg.wrench.torque)))
    np.testing.assert_array_equal([t for t, _ in imu], _expected_ns(res.t_gyro))
    np.testing.assert_array_equal([v for _, v in imu], res.omega)
    np.testing.assert_array_equal([t for t, _ in tq], _expected_ns(res.t_torque))
    np.testing.assert_array_equal([v for _, v in tq], res.torque)


def test_rosbag2_conventions(written):
    """Profile ros2, QoS channel metadata, rosbag2 metadata record and summary statistics."""
    path, res, counts = written
    with open(path, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        stats = summary.statistics
        assert stats.message_count == sum(counts.values())
        assert stats.message_start_time == int(_expected_ns(min(res.t_gyro[0],
                                                                res.t_torque[0])))
        by_topic = {c.topic: c for c in summary.channels.values()}
        assert {by_topic[t].id: n for t, n in counts.items()} == stats.channel_message_counts
        imu_qos = parse_qos(by_topic['/imu'].metadata['offered_qos_profiles'])
        assert imu_qos[0].reliability.name == 'BEST_EFFORT' and imu_qos[0].depth == 5
        truth_qos = parse_qos(by_topic['/truth/inertia'].metadata['offered_qos_profiles'])
        assert truth_qos[0].durability.name == 'TRANSIENT_LOCAL'
        for sch in summary.schemas.values():
            assert sch.data.decode() == cdr_encode.schema_text(sch.name)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    bag = yaml.safe_load(meta['rosbag2']['serialized_metadata'])
    assert bag['version'] == 9 and bag['storage_identifier'] == 'mcap'
    assert bag['message_count'] == stats.message_count
    assert bag['starting_time']['nanoseconds_since_epoch'] == stats.message_start_time
    assert bag['duration']['nanoseconds'] == stats.message_end_time - stats.message_start_time
    assert {t['topic_metadata']['name']: t['message_count']
            for t in bag['topics_with_message_count']} == counts
    scene = meta['inertia_ros.scene']
    assert scene['scene_name'] == 'writer_test' and scene['seed'] == '3'
    assert Scene.from_dict(yaml.safe_load(scene['scene_json'])).to_dict() == SCENE


@pytest.mark.ros
def test_type_hashes_are_the_middlewares(written):
    """topic_type_hash / type_description_hash carry the RIHS01 hash rclpy's middleware reports
    for a publisher of each type (the ROS wheels' type support, not our lookup)."""
    rclpy = pytest.importorskip('rclpy')
    from geometry_msgs.msg import InertiaStamped, WrenchStamped
    from rclpy.node import Node
    from sensor_msgs.msg import Imu

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=230)        # a private domain: nothing is sent anyway
    try:
        node = Node('type_hash_probe', context=ctx, enable_rosout=False,
                    start_parameter_services=False)
        expected = {}
        for cls, name in ((Imu, IMU), (WrenchStamped, WRENCH_STAMPED),
                          (InertiaStamped, INERTIA_STAMPED)):
            topic = '/probe_' + cls.__name__.lower()
            node.create_publisher(cls, topic, 1)
            (info,) = node.get_publishers_info_by_topic(topic)
            expected[name] = str(info.topic_type_hash)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    assert all(h.startswith('RIHS01_') for h in expected.values()), expected
    assert {n: type_description_hash(n) for n in expected} == expected
    path, _, _ = written
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    types = {'/imu': IMU, '/torque': WRENCH_STAMPED, '/truth/inertia': INERTIA_STAMPED}
    for topic, name in types.items():
        assert channels[topic].metadata['topic_type_hash'] == expected[name]
    bag = yaml.safe_load(meta['rosbag2']['serialized_metadata'])
    assert {t['topic_metadata']['name']: t['topic_metadata']['type_description_hash']
            for t in bag['topics_with_message_count']} == {
        t: expected[n] for t, n in types.items()}
    assert type_description_hash('no_such_pkg/msg/Thing') == ''


def test_messages_are_in_log_time_order(written):
    """The data section is in log-time order across topics."""
    path, _, _ = written
    with open(path, 'rb') as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert times == sorted(times)


# --------------------------------------------------------------------------- writer API
def test_refuses_to_overwrite_unless_told(tmp_path):
    """An existing file is never replaced without overwrite=True; overwrite=True replaces it."""
    path = tmp_path / 'x.mcap'
    path.write_bytes(b'keep me')
    with pytest.raises(FileExistsError, match='overwrite=True'):
        McapWriter(path)
    assert path.read_bytes() == b'keep me'
    with McapWriter(path, overwrite=True) as w:
        w.add_topic('/t', cdr_encode.WRENCH_STAMPED)
        w.write('/t', 5, cdr_encode.encode_wrench_stamped([5], [[1.0, 2.0, 3.0]], 'f')[0])
    assert path.read_bytes()[:8] == b'\x89MCAP0\r\n'


def test_file_created_meanwhile_is_not_replaced(tmp_path):
    """A file that appears at the target while writing is kept, and the write fails."""
    path = tmp_path / 'race.mcap'
    with pytest.raises(FileExistsError, match='appeared while writing'), McapWriter(path) as w:
        w.add_topic('/t', cdr_encode.WRENCH_STAMPED)
        path.write_bytes(b'other')
    assert path.read_bytes() == b'other'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['race.mcap']


def test_error_inside_context_leaves_no_file(tmp_path):
    """An exception inside the with-block discards the partial output."""
    path = tmp_path / 'y.mcap'
    with pytest.raises(RuntimeError), McapWriter(path) as w:
        w.add_topic('/t', cdr_encode.WRENCH_STAMPED)
        raise RuntimeError('boom')
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(('action', 'pattern'), [
    (lambda w: w.add_topic('imu', cdr_encode.IMU), 'absolute name'),
    (lambda w: w.add_topic('/x', 'std_msgs/msg/String'), 'no schema for'),
    (lambda w: w.write('/nope', 1, b''), 'was not added'),
    (lambda w: (w.add_topic('/a', cdr_encode.IMU), w.add_topic('/a', cdr_encode.IMU)),
     'already added'),
    (lambda w: (w.add_topic('/a', cdr_encode.IMU), w.write_many('/a', [1.5], [b''])),
     'integer nanoseconds'),
    (lambda w: (w.add_topic('/a', cdr_encode.IMU), w.write_many('/a', [1, 2], [b''])),
     '1 messages for 2 log times'),
    (lambda w: (w.add_topic('/a', cdr_encode.IMU), w.write('/a', -1, b'')), '>= 0'),
    (lambda w: w.add_metadata('rosbag2', {}), 'written by close'),
    (lambda w: w.add_topic('/a', cdr_encode.IMU, qos='fast'), 'unknown preset'),
])
def test_writer_misuse_is_a_clear_error(tmp_path, action, pattern):
    """Misuse raises McapWriterError (a ValueError) naming the problem."""
    with McapWriter(tmp_path / 'z.mcap') as w, pytest.raises(McapWriterError, match=pattern):
        action(w)


def test_constructor_validation(tmp_path):
    """Bad compression, chunk size or a missing directory are refused up front."""
    with pytest.raises(McapWriterError, match='compression'):
        McapWriter(tmp_path / 'a.mcap', compression='gzip')
    with pytest.raises(McapWriterError, match='chunk_size'):
        McapWriter(tmp_path / 'a.mcap', chunk_size=0)
    with pytest.raises(McapWriterError, match='does not exist'):
        McapWriter(tmp_path / 'no' / 'a.mcap')


def test_qos_yaml_and_time_conversion():
    """QoS YAML is one rosbag2 v9 profile; seconds round to the nearest nanosecond."""
    q = yaml.safe_load(qos_yaml('sensor_data'))
    assert q[0]['reliability'] == 'best_effort' and q[0]['history'] == 'keep_last'
    assert seconds_to_ns([0.0, 0.005, 1e-10], 10).tolist() == [10, 5_000_010, 10]


# --------------------------------------------------------------------------- command line
def test_simulate_command(tmp_path, capsys):
    """simulate writes a readable log, refuses to overwrite, --force and --seed work."""
    text = (ROOT / 'config' / 'scenes' / 'single_axis.yaml').read_text()
    scene = tmp_path / 'short.yaml'
    scene.write_text(text.replace('duration: 60.0', 'duration: 5.0'))
    out = tmp_path / 'o.mcap'
    assert main(['simulate', str(scene), '-o', str(out)]) == 0
    assert 'wrote' in capsys.readouterr().out
    first = out.read_bytes()
    assert main(['simulate', str(scene), '-o', str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip().endswith('exists (use --force to overwrite it)')
    assert err.count('\n') == 1
    assert main(['simulate', str(scene), '-o', str(out), '--force', '-q']) == 0
    assert out.read_bytes() == first, 'same scene, same seed: the same bytes'
    assert main(['simulate', str(scene), '-o', str(out), '--force', '--seed', '99', '-q']) == 0
    assert out.read_bytes() != first
    with AnyReader([Path(out)]) as rd:
        assert sum(c.msgcount for c in rd.connections) == 1001 + 251 + 1


@pytest.mark.parametrize(('argv', 'pattern'), [
    (['{bad}', '-o', '{out}'], 'gyro.rate: must be a positive number'),
    (['{missing}', '-o', '{out}'], 'no such scene file'),
    (['{good}', '-o', '{tmp}/o.txt'], "without a suffix (not '.txt')"),
    (['{good}', '-o', '{tmp}', '--force'], 'a bag directory is never replaced'),
    (['{good}', '-o', '{tmp}/nodir/o.mcap'], 'does not exist'),
    (['{good}', '-o', '{out}', '--seed', '-4'], '--seed: must be >= 0'),
])
def test_simulate_command_bad_input_is_one_line(tmp_path, capsys, argv, pattern):
    """Bad input gives exit status 2 and one error line, no traceback."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text('body: {inertia: [1, 1, 1, 0, 0, 0]}\ngyro: {rate: 0}\n')
    fill = {'bad': bad, 'missing': tmp_path / 'none.yaml', 'out': tmp_path / 'o.mcap',
            'good': ROOT / 'config' / 'scenes' / 'default.yaml', 'tmp': tmp_path}
    assert main(['simulate'] + [a.format(**fill) for a in argv]) == 2
    err = capsys.readouterr().err
    assert pattern in err and err.count('\n') == 1 and 'Traceback' not in err


def test_simulate_writes_a_rosbag2_directory(tmp_path, capsys):
    """-o NAME (no .mcap suffix) writes NAME/metadata.yaml + NAME/NAME_0.mcap, as ros2 bag
    record does: rosbags' rosbag2 reader opens it, and our estimate command reads it."""
    from rosbags.rosbag2 import Reader

    text = (ROOT / 'config' / 'scenes' / 'default.yaml').read_text()
    scene = tmp_path / 'short.yaml'
    scene.write_text(text.replace('duration: 60.0', 'duration: 20.0'))
    bag = tmp_path / 'run1'
    assert main(['simulate', str(scene), '-o', str(bag), '-q']) == 0
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'run1_0.mcap']
    assert not (tmp_path / 'run1.partial').exists()
    with Reader(bag) as rd:                     # parses metadata.yaml, then reads the mcap
        assert rd.message_count == 4001 + 1001 + 1
        types = {c.topic: c.msgtype for c in rd.connections}
        assert types == {'/imu': IMU, '/torque': WRENCH_STAMPED,
                         '/truth/inertia': INERTIA_STAMPED}
        assert sum(1 for _ in rd.messages()) == rd.message_count
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == ['run1_0.mcap'] and info['version'] == 9
    assert main(['estimate', str(bag), '--format', 'json', '--no-progress']) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep['status'] == 'ok' and rep['diagnostics']['truth']['relative_error'] < 0.01
    # an existing directory is never replaced, --force or not; nothing in it is touched
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    for extra in ([], ['--force']):
        assert main(['simulate', str(scene), '-o', str(bag), '--seed', '5', *extra]) == 2
        assert 'never replaced' in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before


# --------------------------------------------------------------------------- sample logs
BAG_NAMES = ['default', 'torque_free', 'single_axis', 'disturbance']


@pytest.mark.parametrize('name', BAG_NAMES)
def test_sample_bag_sits_beside_the_scene_that_made_it(name):
    """bags/NAME.mcap is < 2 MB, bags/NAME.yaml equals the shipped scene and the log's record."""
    bag = ROOT / 'bags' / f'{name}.mcap'
    scene_file = ROOT / 'bags' / f'{name}.yaml'
    assert bag.stat().st_size < 2 * 1024 * 1024
    assert scene_file.read_text() == (ROOT / 'config' / 'scenes' / f'{name}.yaml').read_text()
    with open(bag, 'rb') as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        truth = [m for _, c, m in reader.iter_messages(topics=['/truth/inertia'])]
    scene = load_scene(scene_file)
    assert yaml.safe_load(meta['inertia_ros.scene']['scene_json']) == scene.to_dict()
    assert meta['inertia_ros.scene']['seed'] == str(scene.seed)
    assert truth and truth[0].data == cdr_encode.encode_inertia_stamped(
        [DEFAULT_START_NS], scene.inertia, scene.gyro.frame_id)[0]


def test_truth_carries_mass_and_com_of_composite_bodies(tmp_path):
    """/truth/inertia has m and com when the body (and the changed body) are built from parts."""
    box = {'shape': 'solid_box', 'mass': 2.0, 'size': [0.2, 0.3, 0.4]}
    ball = {'shape': 'solid_sphere', 'mass': 1.0, 'radius': 0.1, 'position': [0.3, 0, 0]}
    s = Scene.from_dict({'duration': 2.0, 'body': {'parts': [box, ball]},
                         'inertia_change': {'time': 1.0, 'parts': [box]}})
    path = tmp_path / 'c.mcap'
    write_simulation(path, simulate(s))
    with AnyReader([path]) as rd:
        msgs = [rd.deserialize(raw, c.msgtype).inertia
                for c, _, raw in rd.messages() if c.topic == '/truth/inertia']
    assert [m.m for m in msgs] == [3.0, 2.0]
    assert _vec(msgs[0].com) == pytest.approx([0.1, 0.0, 0.0], abs=1e-15)
    assert _vec(msgs[1].com) == [0.0, 0.0, 0.0]


@pytest.mark.ros
def test_explicit_schema_text_for_other_types(tmp_path):
    """A type cdr_encode does not know is written with a caller's schema and decodes back."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.serialization import serialize_message

    from inertia_ros.io.msgtypes import schema_text_from_share

    msg = DiagnosticArray()
    msg.header.stamp.sec, msg.header.frame_id = 7, 'base_link'
    msg.status = [DiagnosticStatus(level=DiagnosticStatus.WARN, name='inertia', message='m',
                                   values=[KeyValue(key='k', value='v')])]
    path = tmp_path / 'diag.mcap'
    with McapWriter(path) as w:
        w.add_topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                    schema_text=schema_text_from_share('diagnostic_msgs/msg/DiagnosticArray'))
        w.write_many('/diagnostics', np.array([7_000_000_000]), [serialize_message(msg)])
    with open(path, 'rb') as f:
        decoded = [m for _, _, _, m in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert len(decoded) == 1
    st = decoded[0].status[0]
    assert (decoded[0].header.stamp.sec, st.level, st.values[0].key) == (7, 1, 'k')  # WARN
    with McapWriter(tmp_path / 'bad.mcap') as w, pytest.raises(ValueError, match='schema_text'):
        w.add_topic('/x', 'diagnostic_msgs/msg/DiagnosticArray', schema_text='  ')


# --------------------------------------------------------------------------- message types
@pytest.mark.parametrize('name, full, short', [
    ('sensor_msgs/Imu', 'sensor_msgs/msg/Imu', 'sensor_msgs/Imu'),
    ('sensor_msgs/msg/Imu', 'sensor_msgs/msg/Imu', 'sensor_msgs/Imu'),
    ('std_srvs/srv/Trigger', 'std_srvs/srv/Trigger', 'std_srvs/srv/Trigger'),
    ('Imu', 'Imu', 'Imu'),                          # not a type name: left as it is
    ('a/b/c/d', 'a/b/c/d', 'a/b/c/d'),
])
def test_type_name_forms(name, full, short):
    """One parser: pkg/Type <-> pkg/msg/Type; anything else is returned unchanged."""
    assert msgtypes.normalise_type(name) == full
    assert msgtypes.short_type(name) == short


@pytest.mark.parametrize('bad', ['Imu', 'pkg//Type', 'pkg/foo/Type', '/a/b', 7])
def test_split_type_rejects_malformed_names(bad):
    """split_type names the expected forms."""
    with pytest.raises(ValueError, match="expected 'pkg/msg/Type' or 'pkg/Type'"):
        msgtypes.split_type(bad)


@pytest.mark.ros
def test_hand_written_schema_walk_matches_installed_files():
    """The hand-written schema and the installed .msg files give the same dependency order."""
    for name in ('sensor_msgs/msg/Imu', 'geometry_msgs/msg/WrenchStamped',
                 'geometry_msgs/msg/InertiaStamped'):
        ours = msgtypes.schema_text(name)
        share = msgtypes.schema_text_from_share(name)
        deps = [ln for ln in ours.splitlines() if ln.startswith('MSG: ')]
        assert deps == [ln for ln in share.splitlines() if ln.startswith('MSG: ')], name


def _fake_install(prefix: Path, pkg: str, fields: str, hash_string: str) -> None:
    """A share/ dir with one interface package: Thing.msg and its type description."""
    d = prefix / 'share' / pkg / 'msg'
    d.mkdir(parents=True)
    (d / 'Thing.msg').write_text(fields)
    (d / 'Thing.json').write_text(json.dumps({'type_hashes': [
        {'type_name': f'{pkg}/msg/Thing', 'hash_string': hash_string}]}))


def test_schema_text_and_hash_come_from_the_same_install(tmp_path, monkeypatch):
    """AMENT_PREFIX_PATH wins over sys.prefix for both the .msg text and the RIHS01 hash."""
    ws, wheels = tmp_path / 'ws', tmp_path / 'wheels'
    _fake_install(ws, 'fake_msgs', 'float64 from_workspace\n', 'RIHS01_ws')
    _fake_install(wheels, 'fake_msgs', 'float64 from_wheels\n', 'RIHS01_wheels')
    _fake_install(wheels, 'only_wheel_msgs', 'float64 w\n', 'RIHS01_only')
    monkeypatch.setattr('sys.prefix', str(wheels))
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(ws))
    assert msgtypes.share_prefixes() == [str(ws), str(wheels)]
    assert msgtypes.schema_text_from_share('fake_msgs/msg/Thing') == 'float64 from_workspace\n'
    assert msgtypes.type_description_hash('fake_msgs/msg/Thing') == 'RIHS01_ws'
    assert msgtypes.find_share_file('fake_msgs/Thing', '.json').parent.parent.parent.parent \
        == ws
    # a package only in the wheels is found there, text and hash alike
    assert msgtypes.schema_text_from_share('only_wheel_msgs/msg/Thing') == 'float64 w\n'
    assert msgtypes.type_description_hash('only_wheel_msgs/msg/Thing') == 'RIHS01_only'
    # without the workspace, the same type resolves to the wheels (the cache follows the env)
    monkeypatch.delenv('AMENT_PREFIX_PATH')
    assert msgtypes.schema_text_from_share('fake_msgs/msg/Thing') == 'float64 from_wheels\n'
    assert msgtypes.type_description_hash('fake_msgs/msg/Thing') == 'RIHS01_wheels'
