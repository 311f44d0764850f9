"""Message objects at the ROS boundary: builders, diagnostics, markers (no rclpy.init needed).

The nodes read their inputs with :mod:`inertia_ros.io.cdr_decode`; the small readers below
(``_imu_sample`` ...) only check what the builders put into a message.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.ros
pytest.importorskip('builtin_interfaces')  # ROS message packages (skipped without ROS)

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402

from inertia_ros.core.inertia import THETA_NAMES  # noqa: E402
from inertia_ros.io import cdr_decode  # noqa: E402
from inertia_ros.io.msgtypes import schema_text_from_share  # noqa: E402
from inertia_ros.nodes import diagnostics as dg  # noqa: E402
from inertia_ros.nodes import markers as mk  # noqa: E402
from inertia_ros.nodes import messages as rm  # noqa: E402

I_NOM = np.array([[1.0, 0.05, -0.03], [0.05, 1.2, 0.02], [-0.03, 0.02, 0.9]])


def _values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _xyz(v) -> np.ndarray:
    return np.array((v.x, v.y, v.z), dtype=float)


def _imu_sample(msg):
    """(t_ns, angular_velocity (3,)) of a sensor_msgs/Imu."""
    return rm.stamp_to_ns(msg.header.stamp), _xyz(msg.angular_velocity)


def _vector3_sample(msg):
    """(t_ns, vector (3,)) of a geometry_msgs/Vector3Stamped."""
    return rm.stamp_to_ns(msg.header.stamp), _xyz(msg.vector)


def _wrench_sample(msg):
    """(t_ns, torque (3,)) of a geometry_msgs/WrenchStamped."""
    return rm.stamp_to_ns(msg.header.stamp), _xyz(msg.wrench.torque)


def _quaternion_to_axes(msg: QuaternionStamped) -> np.ndarray:
    q = msg.quaternion
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()


@pytest.mark.parametrize('t_ns', [0, 1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789,
                                  -1, -1_500_000_000])
def test_stamp_roundtrip(t_ns):
    """ns -> Time -> ns is exact and nanosec stays in [0, 1e9)."""
    stamp = rm.ns_to_stamp(t_ns)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert rm.stamp_to_ns(stamp) == t_ns


@pytest.mark.parametrize('bad, match', [(1.5, 'integer'), (2**31 * 10**9, 'int32'),
                                        (True, 'integer')])
def test_ns_to_stamp_rejects(bad, match):
    """Non-integer or out-of-range times are refused with a message naming t_ns."""
    with pytest.raises(ValueError, match=match):
        rm.ns_to_stamp(bad)


def test_stamp_to_ns_reads_message_time():
    """A Time(sec, nanosec) gives sec*1e9 + nanosec."""
    assert rm.stamp_to_ns(Time(sec=3, nanosec=5)) == 3_000_000_005


@pytest.mark.parametrize('build, read, vec', [
    (rm.imu_msg, _imu_sample, [0.1, -0.2, 0.3]),
    (rm.vector3_stamped, _vector3_sample, [1e-9, 2.5, -7.0]),
    (rm.wrench_msg, _wrench_sample, [0.01, 0.0, -0.02]),
])
def test_input_roundtrip(build, read, vec):
    """Each input message type round-trips (t_ns, vector) exactly (atol=0)."""
    msg = build(1_234_567_890_123, vec, 'base_link')
    assert msg.header.frame_id == 'base_link'
    t_ns, v = read(msg)
    assert t_ns == 1_234_567_890_123
    np.testing.assert_allclose(v, vec, rtol=0, atol=0)


@pytest.mark.parametrize('build, msgtype, field', [
    (rm.imu_msg, 'sensor_msgs/msg/Imu', 'angular_velocity'),
    (rm.vector3_stamped, 'geometry_msgs/msg/Vector3Stamped', 'vector'),
    (rm.wrench_msg, 'geometry_msgs/msg/WrenchStamped', 'torque'),
])
def test_built_inputs_decode_in_the_node_path(build, msgtype, field):
    """What the players publish, the estimator's batch decoder reads back exactly."""
    from rclpy.serialization import serialize_message

    vecs = np.array([[0.1, -0.2, 0.3], [np.nan, 2.5, -7.0]])
    data = [serialize_message(build(1_700_000_000_000_000_000 + k, v, 'base_link'))
            for k, v in enumerate(vecs)]
    batch = cdr_decode.decode_payloads(msgtype, data, fields=(field,))
    assert batch.ok.all() and tuple(batch.frame_ids) == ('base_link',)
    np.testing.assert_array_equal(batch.stamp_ns, 1_700_000_000_000_000_000 + np.arange(2))
    np.testing.assert_array_equal(batch.fields[field], vecs)


def test_imu_marks_orientation_and_acceleration_absent():
    """The Imu we publish flags orientation and linear acceleration as absent (REP 145)."""
    msg = rm.imu_msg(0, [0, 0, 1], 'imu')
    assert msg.orientation_covariance[0] == -1.0
    assert msg.linear_acceleration_covariance[0] == -1.0


def test_nan_passes_through_input():
    """NaN in an input message is returned as NaN (the node counts and drops it)."""
    _, w = _imu_sample(rm.imu_msg(0, [np.nan, 0, 0], 'imu'))
    assert np.isnan(w[0])


@pytest.mark.parametrize('fn, args, match', [
    (rm.imu_msg, (0, [1, 2], 'f'), 'omega must have shape'),
    (rm.wrench_msg, (0, np.zeros((3, 1)), 'f'), 'tau must have shape'),
    (rm.inertia_stamped, (np.eye(2), 0, 'f'), r'inertia must have shape \(3, 3\)'),
    (rm.principal_axes_msg, (np.diag([1.0, 1.0, -1.0]), 0, 'f'), 'reflection'),
    (rm.principal_axes_msg, (np.full((3, 3), np.nan), 0, 'f'), 'finite'),
    (rm.principal_axes_msg, (np.eye(3) * 1.01, 0, 'f'), 'not orthonormal'),
])
def test_builders_reject_bad_shapes(fn, args, match):
    """Builders refuse wrongly shaped arrays or improper rotations with a specific message."""
    with pytest.raises(ValueError, match=match):
        fn(*args)


def test_inertia_stamped_roundtrip_uses_matrix_elements():
    """InertiaStamped carries the matrix entries (ixy = I[0,1], not its negative), exactly."""
    msg = rm.inertia_stamped(I_NOM, 42, 'body')
    assert msg.inertia.ixy == I_NOM[0, 1]
    assert msg.inertia.ixz == I_NOM[0, 2]
    assert msg.inertia.iyz == I_NOM[1, 2]
    assert msg.inertia.m == 0.0
    t_ns, mat = rm.inertia_from_msg(msg)
    assert t_ns == 42
    np.testing.assert_allclose(mat, I_NOM, rtol=0, atol=0)


def test_principal_moments_msg():
    """Principal moments go into x, y, z in the given (ascending) order."""
    msg = rm.principal_moments_msg([0.8, 1.0, 1.3], 7, 'body')
    assert isinstance(msg, Vector3Stamped)
    assert (msg.vector.x, msg.vector.y, msg.vector.z) == (0.8, 1.0, 1.3)


@pytest.mark.parametrize('seed', range(5))
def test_principal_axes_quaternion_roundtrip(seed):
    """Axes -> quaternion (w >= 0, unit) -> axes reproduces the rotation to 1e-12."""
    rot = Rotation.random(random_state=np.random.default_rng(seed)).as_matrix()
    msg = rm.principal_axes_msg(rot, 0, 'body')
    q = msg.quaternion
    assert q.w >= 0
    np.testing.assert_allclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(_quaternion_to_axes(msg), rot, rtol=0, atol=1e-12)


def _result(status='ok', **kw):
    d = {
        'status': status,
        'inertia': I_NOM.tolist(),
        'inertia_std': (I_NOM * 0.001).tolist(),
        'model': 'full', 'method': 'recursive',
        'samples': {'used': 1000, 'dropped': 3},
        'torque_bias': None,
        'identifiable': {n: True for n in THETA_NAMES},
        'diagnostics': {'condition_number': 12.5, 'residual_rms': 0.01},
    }
    d.update(kw)
    return d


@pytest.mark.parametrize('status, level', [
    ('ok', DiagnosticStatus.OK),
    ('insufficient_data', DiagnosticStatus.WARN),
    ('partially_identifiable', DiagnosticStatus.WARN),
    ('model_mismatch', DiagnosticStatus.WARN),
    ('scale_unobservable', DiagnosticStatus.WARN),
    ('insufficient_excitation', DiagnosticStatus.WARN),
])
def test_diagnostic_level_per_status(status, level):
    """Each estimate status maps to its documented DiagnosticStatus level."""
    st = dg.diagnostic_status(_result(status), name='est')
    assert st.level == level
    assert st.message.startswith(status)
    assert _values(st)['status'] == status


def test_diagnostic_values_carry_contract_fields():
    """Values include model, condition number, std errors per element and sample counts."""
    st = dg.diagnostic_status(_result(), name='est', hardware_id='body',
                              extra={'gyro_received': 10, 'nan_dropped': 2})
    v = _values(st)
    assert st.name == 'est' and st.hardware_id == 'body'
    assert v['model'] == 'full'
    assert float(v['condition_number']) == pytest.approx(12.5, rel=1e-6)
    assert float(v['std_ixy']) == pytest.approx(I_NOM[0, 1] * 0.001, rel=1e-5)
    assert v['samples_used'] == '1000' and v['samples_dropped'] == '3'
    assert v['residual_rms'] == '0.01'
    assert v['gyro_received'] == '10' and v['nan_dropped'] == '2'


def test_diagnostic_values_carry_principal_uncertainty():
    """The principal moments' std [kg m^2] and the axes' angular std, in degrees, are shown."""
    res = _result(diagnostics={'principal_moments_std': [0.001, 0.002, 0.003],
                               'principal_axes_std': [math.radians(0.5), math.radians(1.0),
                                                      float('inf')]})
    v = _values(dg.diagnostic_status(res, name='est'))
    assert 'principal_moments_std' in v and '0.002' in v['principal_moments_std']
    shown = v['principal_axes_std_deg']
    assert '0.5' in shown and '1' in shown, shown


def test_diagnostic_null_std_and_reason():
    """Null standard errors render as 'null'; the reason is in the message when not ok."""
    res = _result('scale_unobservable', inertia=None, inertia_std=None,
                  diagnostics={'reason': 'no torque: only ratios observable'})
    st = dg.diagnostic_status(res, name='est')
    v = _values(st)
    assert v['std_ixx'] == 'null'
    assert 'no torque' in st.message and v['reason'] == 'no torque: only ratios observable'


def test_diagnostic_problems_raise_level():
    """A node-level problem (stream timeout) raises an ok estimate to WARN and is reported."""
    st = dg.diagnostic_status(_result(), name='est',
                              problems=[(DiagnosticStatus.WARN, 'torque stream timed out')])
    assert st.level == DiagnosticStatus.WARN
    assert st.message.startswith('torque stream timed out')


def test_every_estimate_status_has_a_level():
    """The level table covers exactly the core's statuses (options.STATUSES)."""
    from inertia_ros.core.estimation.options import STATUSES

    assert set(dg.DIAGNOSTIC_LEVELS) == set(STATUSES)


def test_status_name_follows_diagnostic_updater():
    """Status names are '<node name>: <task>' (diagnostic_updater)."""
    assert dg.status_name('inertia_estimator', 'inertia estimate') == \
        'inertia_estimator: inertia estimate'
    assert dg.DIAGNOSTIC_PERIOD == 1.0


def test_diagnostic_none_result_is_warming_up():
    """Before any estimate the status is insufficient_data at WARN level."""
    st = dg.diagnostic_status(None, name='est')
    assert st.level == DiagnosticStatus.WARN
    assert _values(st)['status'] == 'insufficient_data'


def test_diagnostic_rejects_unknown_status():
    """An unknown status string is refused, naming the allowed ones."""
    with pytest.raises(ValueError, match='result status'):
        dg.diagnostic_status({'status': 'great'}, name='est')


def test_diagnostic_array_stamp():
    """The array carries the statuses and the stamp."""
    arr = dg.diagnostic_array([dg.diagnostic_status(None, name='a')], 5_000_000_001)
    assert rm.stamp_to_ns(arr.header.stamp) == 5_000_000_001
    assert len(arr.status) == 1


def _by_id(ma):
    return {m.id: m for m in ma.markers if m.action == Marker.ADD}


def test_markers_ellipsoid_axes_and_arrows():
    """Ellipsoid semi-axes are 1/sqrt(I_k) scaled, oriented by the axes; L differs from omega."""
    moments, axes = np.linalg.eigh(I_NOM)
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    omega = np.array([0.3, 0.1, -0.2])
    ma = mk.inertia_markers(9, 'body', inertia=I_NOM, moments=moments, axes=axes, omega=omega,
                            scale=0.5, label='ok')
    assert ma.markers[0].action == Marker.DELETEALL
    by_id = _by_id(ma)
    ell = by_id[mk.MARKER_IDS['ellipsoid']]
    semi = np.array([ell.scale.x, ell.scale.y, ell.scale.z]) / 2
    expected = 1 / np.sqrt(moments)
    np.testing.assert_allclose(semi, expected * 0.5 / expected.max(), rtol=1e-12)
    q = ell.pose.orientation
    np.testing.assert_allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), axes,
                               atol=1e-12)
    for k in range(3):
        tip = by_id[mk.MARKER_IDS[f'axis{k + 1}']].points[1]
        np.testing.assert_allclose([tip.x, tip.y, tip.z], axes[:, k] * 0.65, atol=1e-12)

    def direction(mid):
        p = by_id[mid].points[1]
        v = np.array([p.x, p.y, p.z])
        return v / np.linalg.norm(v)
    np.testing.assert_allclose(direction(mk.MARKER_IDS['omega']),
                               omega / np.linalg.norm(omega), atol=1e-12)
    L = I_NOM @ omega
    np.testing.assert_allclose(direction(mk.MARKER_IDS['momentum']), L / np.linalg.norm(L),
                               atol=1e-12)
    assert by_id[mk.MARKER_IDS['label']].text == 'ok'


def test_markers_without_estimate_keep_only_omega():
    """With no valid estimate only DELETEALL and the omega arrow are published."""
    ma = mk.inertia_markers(0, 'body', omega=[0, 0, 1.0])
    assert [m.id for m in ma.markers if m.action == Marker.ADD] == [mk.MARKER_IDS['omega']]
    assert len(mk.inertia_markers(0, 'body').markers) == 1


@pytest.mark.parametrize('scale', [0.0, -1.0, float('nan')])
def test_markers_reject_bad_scale(scale):
    """A non-positive or NaN display scale is refused."""
    with pytest.raises(ValueError, match='scale must be'):
        mk.inertia_markers(0, 'body', scale=scale)


@pytest.mark.parametrize('msgtype', ['visualization_msgs/msg/MarkerArray',
                                     'diagnostic_msgs/msg/DiagnosticArray',
                                     'geometry_msgs/msg/QuaternionStamped',
                                     'geometry_msgs/msg/Vector3Stamped'])
def test_schema_from_share_decodes_with_independent_readers(msgtype):
    """Schema text from the installed .msg files lets mcap_ros2 and rosbags decode our CDR."""
    pytest.importorskip('mcap_ros2')  # optional test dependencies
    pytest.importorskip('rosbags')
    from mcap.records import Schema
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.serialization import serialize_message
    from rosbags.typesys import get_types_from_msg, get_typestore
    from rosbags.typesys.stores import Stores

    moments, axes = np.linalg.eigh(I_NOM)
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    msgs = {
        'visualization_msgs/msg/MarkerArray': mk.inertia_markers(
            5, 'body', inertia=I_NOM, moments=moments, axes=axes, omega=[0.1, 0.2, 0.3],
            label='ok'),
        'diagnostic_msgs/msg/DiagnosticArray': dg.diagnostic_array(
            [dg.diagnostic_status(_result(), name='est', extra={'n': 3})], 7),
        'geometry_msgs/msg/QuaternionStamped': rm.principal_axes_msg(axes, 9, 'body'),
        'geometry_msgs/msg/Vector3Stamped': rm.principal_moments_msg(moments, 9, 'body'),
    }
    msg = msgs[msgtype]
    data = serialize_message(msg)
    text = schema_text_from_share(msgtype)
    decoder = DecoderFactory().decoder_for(
        'cdr', Schema(id=1, name=msgtype, encoding='ros2msg', data=text.encode()))
    a = decoder(data)
    store = get_typestore(Stores.EMPTY)
    types = {}
    for block in text.split('=' * 80 + '\n'):
        if block.startswith('MSG: '):
            head, body = block.split('\n', 1)
            types.update(get_types_from_msg(body, head[5:].replace('/', '/msg/')))
        else:
            types.update(get_types_from_msg(block, msgtype))
    store.register(types)
    b = store.deserialize_cdr(data, msgtype)
    if msgtype.endswith('MarkerArray'):
        assert [m.id for m in a.markers] == [m.id for m in b.markers] \
            == [m.id for m in msg.markers]
        assert a.markers[1].scale.x == b.markers[1].scale.x == msg.markers[1].scale.x
        assert b.markers[-1].text == 'ok'
    elif msgtype.endswith('DiagnosticArray'):
        assert [kv.key for kv in a.status[0].values] == [kv.key for kv in b.status[0].values] \
            == [kv.key for kv in msg.status[0].values]
        assert b.status[0].level == 0 and a.status[0].name == 'est'
    elif msgtype.endswith('QuaternionStamped'):
        assert (a.quaternion.w, b.quaternion.w) == (msg.quaternion.w, msg.quaternion.w)
    else:
        assert (a.vector.z, b.vector.z) == (msg.vector.z, msg.vector.z)
    if hasattr(msg, 'header'):
        assert a.header.frame_id == b.header.frame_id == msg.header.frame_id


@pytest.mark.parametrize('bad, match', [
    ('MarkerArray', 'expected'),
    ('nosuch_msgs/msg/Thing', r'no nosuch_msgs/msg/Thing\.msg'),
])
def test_schema_from_share_rejects(bad, match):
    """A malformed type name or a type with no installed .msg file is refused."""
    with pytest.raises(ValueError, match=match):
        schema_text_from_share(bad)
