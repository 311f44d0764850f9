"""The vectorised CDR decoder against mcap_ros2's decoder, bit for bit, on many messages."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('mcap_ros2')  # optional test dependency
pytest.importorskip('rosbags')  # optional test dependency
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from rosbags.typesys import Stores, get_typestore

from inertia_ros.io import cdr_decode as cd

TS = get_typestore(Stores.ROS2_JAZZY)
TYPES = tuple(cd.LAYOUTS)


def _frame(rng: np.random.Generator) -> str:
    """A frame id of random length 0..23 (every alignment case), mostly ASCII, some UTF-8."""
    n = int(rng.integers(0, 24))
    alphabet = list('abcdefghijklmnopqrstuvwxyz_/0123456789') + ['é', 'ß']
    return ''.join(rng.choice(alphabet, size=n))


def _floats(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random float64 with the awkward values mixed in (NaN, inf, -0.0, subnormal, huge)."""
    x = rng.normal(scale=10.0 ** rng.integers(-6, 6), size=n)
    special = np.array([np.nan, np.inf, -np.inf, -0.0, 5e-324, 1.7e308])
    mask = rng.random(n) < 0.1
    x[mask] = rng.choice(special, size=int(mask.sum()))
    return x


def _message(msg_type: str, rng: np.random.Generator) -> object:
    """A random rosbags message of ``msg_type``."""
    T = TS.types
    sec = int(rng.integers(-2**31, 2**31))
    nsec = int(rng.integers(0, 10**9))
    header = T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=sec,
                                                                             nanosec=nsec),
                                      frame_id=_frame(rng))
    v3 = T['geometry_msgs/msg/Vector3']

    def vec() -> object:
        return v3(*_floats(rng, 3))

    if msg_type == 'sensor_msgs/msg/Imu':
        return T[msg_type](header=header,
                           orientation=T['geometry_msgs/msg/Quaternion'](*_floats(rng, 4)),
                           orientation_covariance=_floats(rng, 9), angular_velocity=vec(),
                           angular_velocity_covariance=_floats(rng, 9),
                           linear_acceleration=vec(),
                           linear_acceleration_covariance=_floats(rng, 9))
    if msg_type == 'geometry_msgs/msg/WrenchStamped':
        return T[msg_type](header=header,
                           wrench=T['geometry_msgs/msg/Wrench'](force=vec(), torque=vec()))
    if msg_type == 'geometry_msgs/msg/Vector3Stamped':
        return T[msg_type](header=header, vector=vec())
    if msg_type == 'geometry_msgs/msg/TwistStamped':
        return T[msg_type](header=header,
                           twist=T['geometry_msgs/msg/Twist'](linear=vec(), angular=vec()))
    f = _floats(rng, 10)
    inertia = T['geometry_msgs/msg/Inertia'](m=f[0], com=v3(*f[1:4]), ixx=f[4], ixy=f[5],
                                              ixz=f[6], iyy=f[7], iyz=f[8], izz=f[9])
    return T[msg_type](header=header, inertia=inertia)


def _reference_decoder(msg_type: str):
    """mcap_ros2's decoder for ``msg_type`` (schema text from rosbags' message definitions)."""
    text, _ = TS.generate_msgdef(msg_type, ros_version=2)
    schema = Schema(id=1, name=msg_type, encoding='ros2msg', data=text.encode())
    return DecoderFactory().decoder_for('cdr', schema)


def _reference_fields(msg_type: str, m: object) -> dict[str, list[float]]:
    """The float fields of a decoded mcap_ros2 message in our field order."""
    if msg_type == 'sensor_msgs/msg/Imu':
        q = m.orientation
        return {'orientation': [q.x, q.y, q.z, q.w],
                'orientation_covariance': list(m.orientation_covariance),
                'angular_velocity': [m.angular_velocity.x, m.angular_velocity.y,
                                     m.angular_velocity.z],
                'angular_velocity_covariance': list(m.angular_velocity_covariance),
                'linear_acceleration': [m.linear_acceleration.x, m.linear_acceleration.y,
                                        m.linear_acceleration.z],
                'linear_acceleration_covariance': list(m.linear_acceleration_covariance)}
    if msg_type == 'geometry_msgs/msg/WrenchStamped':
        w = m.wrench
        return {'force': [w.force.x, w.force.y, w.force.z],
                'torque': [w.torque.x, w.torque.y, w.torque.z]}
    if msg_type == 'geometry_msgs/msg/Vector3Stamped':
        return {'vector': [m.vector.x, m.vector.y, m.vector.z]}
    if msg_type == 'geometry_msgs/msg/TwistStamped':
        t = m.twist
        return {'linear': [t.linear.x, t.linear.y, t.linear.z],
                'angular': [t.angular.x, t.angular.y, t.angular.z]}
    i = m.inertia
    return {'m': [i.m], 'com': [i.com.x, i.com.y, i.com.z], 'ixx': [i.ixx], 'ixy': [i.ixy],
            'ixz': [i.ixz], 'iyy': [i.iyy], 'iyz': [i.iyz], 'izz': [i.izz]}


def _bits(x: np.ndarray | list[float]) -> np.ndarray:
    return np.asarray(x, dtype=np.float64).view(np.uint64)


@pytest.mark.parametrize('little_endian', [True, False], ids=['le', 'be'])
@pytest.mark.parametrize('msg_type', TYPES)
def test_fast_path_equals_mcap_ros2_bit_for_bit(msg_type: str, little_endian: bool) -> None:
    """decode_batch on 400 random messages (all frame_id lengths) equals mcap_ros2 bitwise."""
    rng = np.random.default_rng(abs(hash((msg_type, little_endian))) % 2**32)
    msgs = [_message(msg_type, rng) for _ in range(400)]
    payloads = [bytes(TS.serialize_cdr(m, msg_type, little_endian=little_endian)) for m in msgs]
    ref = _reference_decoder(msg_type)
    refs = [ref(p) for p in payloads]
    got = cd.decode_payloads(msg_type, payloads)
    assert got.ok.all()
    want_stamp = [r.header.stamp.sec * 10**9 + r.header.stamp.nanosec for r in refs]
    np.testing.assert_array_equal(got.stamp_ns, np.array(want_stamp, dtype=np.int64))
    assert [got.frame_ids[k] for k in got.frame_index] == [r.header.frame_id for r in refs]
    for field, _ in cd.LAYOUTS[msg_type]:
        want = np.array([_reference_fields(msg_type, r)[field] for r in refs])
        np.testing.assert_array_equal(_bits(got.fields[field]), _bits(want))


@pytest.mark.parametrize('msg_type', TYPES)
def test_scalar_decoder_equals_mcap_ros2(msg_type: str) -> None:
    """decode_message gives mcap_ros2's values (bitwise) for both endiannesses."""
    rng = np.random.default_rng(7)
    ref = _reference_decoder(msg_type)
    for little in (True, False):
        for _ in range(30):
            data = bytes(TS.serialize_cdr(_message(msg_type, rng), msg_type,
                                          little_endian=little))
            r = ref(data)
            d = cd.decode_message(msg_type, data)
            assert d['header']['frame_id'] == r.header.frame_id
            assert d['header']['stamp'] == {'sec': r.header.stamp.sec,
                                            'nanosec': r.header.stamp.nanosec}
            for field, want in _reference_fields(msg_type, r).items():
                v = d[field]
                have = list(v.values()) if isinstance(v, dict) else (
                    v if isinstance(v, list) else [v])
                np.testing.assert_array_equal(_bits(have), _bits(want))


def test_malformed_payloads_are_flagged_not_fatal() -> None:
    """Short, non-CDR and bad-UTF-8 payloads get ok=False and NaN; good neighbours decode."""
    rng = np.random.default_rng(3)
    t = 'geometry_msgs/msg/WrenchStamped'
    good = [bytes(TS.serialize_cdr(_message(t, rng), t)) for _ in range(4)]
    bad_utf8 = bytearray(good[0])
    bad_utf8[12:16] = (3).to_bytes(4, 'little')
    bad_utf8[16:18] = b'\xff\xfe'
    payloads = [good[0], good[1][:30], b'\x00\x03' + good[2][2:], bytes(bad_utf8), good[3],
                b'']
    got = cd.decode_payloads(t, payloads)
    np.testing.assert_array_equal(got.ok, [True, False, False, False, True, False])
    assert np.isnan(got.fields['torque'][~got.ok]).all()
    np.testing.assert_array_equal(got.frame_index[~got.ok], -1)
    ref = cd.decode_payloads(t, [good[0], good[3]])
    np.testing.assert_array_equal(_bits(got.fields['torque'][got.ok]),
                                  _bits(ref.fields['torque']))


def test_frame_ids_of_equal_length_are_told_apart() -> None:
    """Messages whose frame ids share a length but differ in content get distinct indexes."""
    t = 'geometry_msgs/msg/Vector3Stamped'
    T = TS.types
    frames = ['imu_a', 'imu_b', 'imu_a', 'base_', 'imu_b']
    msgs = [T[t](header=T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=k, nanosec=0), frame_id=f),
        vector=T['geometry_msgs/msg/Vector3'](x=k, y=0.0, z=0.0)) for k, f in enumerate(frames)]
    got = cd.decode_payloads(t, [bytes(TS.serialize_cdr(m, t)) for m in msgs])
    assert [got.frame_ids[i] for i in got.frame_index] == frames
    np.testing.assert_array_equal(got.fields['vector'][:, 0], np.arange(5.0))


def test_subset_of_fields_and_bad_arguments() -> None:
    """Only the requested fields are returned; unknown types/fields raise ValueError."""
    rng = np.random.default_rng(5)
    t = 'sensor_msgs/msg/Imu'
    payloads = [bytes(TS.serialize_cdr(_message(t, rng), t)) for _ in range(5)]
    got = cd.decode_payloads('sensor_msgs/Imu', payloads, fields=('angular_velocity',))
    assert set(got.fields) == {'angular_velocity'}
    assert got.fields['angular_velocity'].shape == (5, 3)
    with pytest.raises(ValueError, match='msg_type: .*not supported'):
        cd.decode_payloads('std_msgs/msg/String', payloads)
    with pytest.raises(ValueError, match="fields: .*no field 'torque'"):
        cd.decode_payloads(t, payloads, fields=('torque',))
    with pytest.raises(ValueError, match='outside buf'):
        cd.decode_batch(t, np.zeros(10, np.uint8), np.array([0]), np.array([20]))


@pytest.mark.parametrize('frame_len, offset', [(0, 20), (1, 20), (4, 20), (5, 28), (12, 28),
                                               (13, 36)])
def test_body_offset_table(frame_len: int, offset: int) -> None:
    """The first float64 sits at 4 + align8(12 + L) for serialised string length L."""
    assert cd.body_offset(frame_len) == offset
