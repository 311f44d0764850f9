"""The ROS 2 nodes: in-process rclpy tests over DDS, parameters, and nodes as processes.

Every test process uses its own ROS_DOMAIN_ID (derived from the pid) so parallel runs do not
cross-talk.  Synthetic streams come from the core simulator, published message by message.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import ROOT

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import InertiaStamped, Vector3Stamped, WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import Imu  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402
from inertia_ros.nodes import estimator as en  # noqa: E402
from inertia_ros.nodes import messages  # noqa: E402
from inertia_ros.nodes._ros import sensor_qos  # noqa: E402

pytestmark = pytest.mark.ros

DOMAIN_ID = 1 + os.getpid() % 110  # 1..110; process tests use DOMAIN_ID + 110 (<= 220)
EPOCH_NS = 1_700_000_000_000_000_000
STATUS_NAME = 'inertia_estimator: inertia estimate'  # diagnostic_updater: '<node>: <task>'


@pytest.fixture(scope='module')
def context():
    """An rclpy context on this process's private domain."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


class Harness:
    """An estimator node plus a test node publishing inputs and collecting outputs."""

    def __init__(self, ctx, overrides=None, omega_type=Imu):
        params = [Parameter(k, value=v) for k, v in (overrides or {}).items()]
        self.est = en.InertiaEstimatorNode(context=ctx, parameter_overrides=params)
        self.node = Node('test_harness', context=ctx)
        self.exe = SingleThreadedExecutor(context=ctx)
        self.exe.add_node(self.est)
        self.exe.add_node(self.node)
        topic = 'imu' if omega_type is Imu else 'omega'
        self.pub_gyro = self.node.create_publisher(omega_type, topic, sensor_qos(1000))
        self.pub_torque = self.node.create_publisher(WrenchStamped, 'torque', sensor_qos(1000))
        self.inertia: list[InertiaStamped] = []
        self.moments: list[Vector3Stamped] = []
        self.diag: list[DiagnosticStatus] = []
        self.node.create_subscription(InertiaStamped, '/inertia_estimator/inertia',
                                      self.inertia.append, 100)
        self.node.create_subscription(Vector3Stamped, '/inertia_estimator/principal_moments',
                                      self.moments.append, 100)
        self.node.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda m: self.diag.extend(s for s in m.status if s.name == STATUS_NAME),
            100)
        self.spin_until(lambda: self.pub_gyro.get_subscription_count() > 0
                        and self.pub_torque.get_subscription_count() > 0, 10.0)

    def spin_until(self, cond, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():
                return True
            self.exe.spin_once(timeout_sec=0.01)
        return cond()

    def spin_for(self, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.exe.spin_once(timeout_sec=0.01)

    def received(self):
        c = self.est.counts()
        return c['gyro_received'] + c['torque_received']

    def play(self, sim, frame='base_link', gyro_frame=None, chunk=200):
        """Publish a SimResult's streams in stamp order, spinning so nothing overflows."""
        t = np.concatenate([sim.t_gyro, sim.t_torque])
        kind = np.concatenate([np.zeros(sim.t_gyro.size, int), np.ones(sim.t_torque.size, int)])
        idx = np.concatenate([np.arange(sim.t_gyro.size), np.arange(sim.t_torque.size)])
        order = np.lexsort((kind, t))
        sent = self.received()
        for n, k in enumerate(order):
            stamp = EPOCH_NS + int(round(t[k] * 1e9))
            if kind[k] == 0:
                self.pub_gyro.publish(messages.imu_msg(stamp, sim.omega[idx[k]],
                                                       gyro_frame or frame))
            else:
                self.pub_torque.publish(messages.wrench_msg(stamp, sim.torque[idx[k]], frame))
            sent += 1
            if n % chunk == chunk - 1:
                self.spin_until(lambda s=sent: self.received() >= s, 10.0)
        assert self.spin_until(lambda: self.received() >= sent, 10.0), 'messages were lost'

    def latest_diag(self):
        """Diagnostics published now (as the 1 Hz timer would), once received."""
        n = len(self.diag)
        self.spin_for(0.1)
        self.est.force_update()
        assert self.spin_until(lambda: len(self.diag) > n, 10.0), 'no diagnostics received'
        return self.diag[-1]

    def close(self):
        self.exe.shutdown()
        self.est.destroy_node()
        self.node.destroy_node()


@pytest.fixture
def harness(context):
    made = []

    def make(**kw):
        h = Harness(context, **kw)
        made.append(h)
        return h
    yield make
    for h in made:
        h.close()


def _values(status):
    return {kv.key: kv.value for kv in status.values}


def _short_scene(name='default.yaml', duration=None, **changes):
    scene = load_scene(ROOT / 'config' / 'scenes' / name)
    d = dict(scene.source)
    if duration is not None:
        d['duration'] = duration
    d.update(changes)
    return Scene.from_dict(d)


# --------------------------------------------------------------------------- parameters
def test_parameter_file_documents_every_parameter():
    """config/inertia_estimator.yaml lists exactly the declared parameters, at their defaults."""
    text = (ROOT / 'config' / 'inertia_estimator.yaml').read_text()
    params = yaml.safe_load(text)['inertia_estimator']['ros__parameters']
    params.pop('use_sim_time')
    assert set(params) == set(en.PARAMETERS)
    for name, p in en.PARAMETERS.items():
        assert params[name] == p.default, name
        assert f'\n    {name}:' in text and 'Default' in text


@pytest.mark.parametrize('node_file', ['scene_simulator', 'bag_player'])
def test_player_parameter_files_are_node_scoped(node_file):
    """Each player's parameter file is '<node>: ros__parameters:' with a comment per entry."""
    text = (ROOT / 'config' / f'{node_file}.yaml').read_text()
    params = yaml.safe_load(text)[node_file]['ros__parameters']
    lines = text.splitlines()
    for name in params:
        i = next(k for k, ln in enumerate(lines) if ln.strip().startswith(f'{name}:'))
        assert lines[i - 1].strip().startswith('#'), f'{name} has no comment'


def test_every_parameter_has_description_and_range(harness):
    """Declared parameters carry a description; numeric ones a range, choices a constraint."""
    est = harness().est
    for name, p in en.PARAMETERS.items():
        d = est.describe_parameter(name)
        assert d.description, name
        if p.lo is not None and not isinstance(p.default, bool):
            assert d.floating_point_range or d.integer_range, name
        if p.choices:
            assert d.additional_constraints.startswith('one of'), name


@pytest.mark.parametrize('name, value, reason', [
    ('method', 'magic', "parameter 'method' must be one of"),
    ('hold', 'cubic', "parameter 'hold' must be one of"),
    ('batch_method', 'guess', "parameter 'batch_method' must be one of"),
    ('model', 'octagonal', "parameter 'model' must be one of"),
    ('model', 'axisymmetric', 'symmetry_axis'),
    ('torque_bias', 'maybe', "parameter 'torque_bias' must be one of"),
    ('inertial_torque', 'maybe', "parameter 'inertial_torque' must be one of"),
    ('forgetting', 1.5, ''),
    ('publish_rate', 0.0, ''),
    ('qos_depth', 5, ''),
    ('omega_msg_type', 'vector3', ''),
])
def test_invalid_parameter_changes_are_rejected(harness, name, value, reason):
    """Out-of-range, unknown or read-only values are refused and the old value stays."""
    est = harness().est
    before = est.get_parameter(name).value
    result = est.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful
    assert reason in result.reason
    assert est.get_parameter(name).value == before


def test_valid_parameter_change_resets(harness):
    """A valid estimator setting is accepted and resets the estimate."""
    h = harness()
    resets = h.est.counts()['resets']
    assert h.est.set_parameters([Parameter('forgetting', value=0.99)])[0].successful
    assert h.est.counts()['resets'] == resets + 1
    assert h.est.set_parameters([Parameter('marker_scale', value=1.0)])[0].successful
    assert h.est.counts()['resets'] == resets + 1
    # a new publish rate keeps the estimate; model selection still runs about once a second
    assert h.est.set_parameters([Parameter('publish_rate', value=5.0)])[0].successful
    assert h.est.counts()['resets'] == resets + 1
    assert h.est._estimator.reselect_every == 5


def test_inertial_torque_parameter_rebuilds_the_recursive_estimator(harness):
    """``inertial_torque`` (default 'auto'): 'on' rebuilds the recursive estimator with it;
    switching to the tracking method while it is 'on' is refused with the one-line reason
    ('auto' runs without the term there)."""
    h = harness()
    assert h.est._estimator.policy.inertial_torque == 'auto'
    resets = h.est.counts()['resets']
    assert h.est.set_parameters([Parameter('inertial_torque', value='on')])[0].successful
    assert h.est.counts()['resets'] == resets + 1
    assert h.est._estimator.policy.inertial_torque == 'on'
    result = h.est.set_parameters([Parameter('method', value='tracking')])[0]
    assert not result.successful and "'inertial_torque' must be 'off'" in result.reason
    assert '\n' not in result.reason and h.est.get_parameter('method').value == 'recursive'


def test_invalid_startup_parameters_raise(context):
    """A node started with an invalid choice fails at construction with the reason."""
    with pytest.raises(ValueError, match="parameter 'method' must be one of"):
        en.InertiaEstimatorNode(context=context,
                                parameter_overrides=[Parameter('method', value='magic')])


# --------------------------------------------------------------------------- estimation
def test_nominal_scene_converges_within_one_percent(harness):
    """On the nominal scene the published ~/inertia is within 1% (max|dI|/I3) of the truth."""
    scene = _short_scene()
    sim = simulate(scene, seed=3)
    h = harness(overrides={'publish_rate': 2.0})
    h.play(sim)
    h.spin_until(lambda: h.inertia and messages.stamp_to_ns(h.inertia[-1].header.stamp)
                 >= EPOCH_NS + int(sim.t_gyro[-1] * 1e9) - 10**9, 10.0)
    h.est.set_parameters([Parameter('publish_rate', value=1000.0)])
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + int(sim.t_gyro[-1] * 1e9) + 1,
                                        sim.omega[-1], 'base_link'))
    h.spin_for(0.3)
    assert h.inertia, f'no estimate published; last diagnostics {h.diag[-1].message}'
    _, est = messages.inertia_from_msg(h.inertia[-1])
    err = np.max(np.abs(est - sim.inertia)) / np.linalg.eigvalsh(sim.inertia)[-1]
    assert err < 0.01, f'error {err:.4f}\n{est}\n{sim.inertia}'
    st = h.latest_diag()
    assert st.level == DiagnosticStatus.OK
    v = _values(st)
    assert v['status'] == 'ok'
    assert int(v['gyro_received']) == sim.t_gyro.size + 1
    assert int(v['torque_received']) == sim.t_torque.size
    assert h.moments, 'principal moments not published'
    # ~/inertia is latched: a subscriber joining now gets the last estimate, and only it.
    late: list[InertiaStamped] = []
    h.node.create_subscription(InertiaStamped, '/inertia_estimator/inertia', late.append,
                               QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert h.spin_until(lambda: late, 10.0), 'a late subscriber got no estimate'
    h.spin_for(0.2)
    assert len(late) == 1 and late[0] == h.inertia[-1]


@pytest.mark.parametrize('method, statuses', [
    # The recursive core reports the rank loss as insufficient_excitation, the batch core
    # identifies the homogeneous problem (scale_unobservable); both are WARN with the reason.
    ('recursive', ('scale_unobservable', 'insufficient_excitation')),
    ('batch', ('scale_unobservable',)),
])
def test_torque_free_input_reports_failure(harness, method, statuses):
    """Torque-free data: diagnostics at WARN (scale not observable), no ~/inertia."""
    sim = simulate(_short_scene('torque_free.yaml', duration=20.0), seed=1)
    h = harness(overrides={'publish_rate': 2.0, 'method': method})
    h.play(sim)
    h.est.set_parameters([Parameter('publish_rate', value=1000.0)])
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + int(sim.t_gyro[-1] * 1e9) + 1,
                                        sim.omega[-1], 'base_link'))
    h.spin_for(0.3)
    st = h.latest_diag()
    assert _values(st)['status'] in statuses, st.message
    assert st.level == DiagnosticStatus.WARN and _values(st)['reason'], st.message
    assert h.inertia == []


@pytest.mark.parametrize('partial', [False, True])
def test_publish_partial(harness, partial):
    """Partially identifiable: an update publishes ~/inertia (NaN elements) only if allowed."""
    sim = simulate(_short_scene('single_axis.yaml', duration=20.0), seed=1)
    # Frequent updates, as a live node at 1 kHz sees them (small blocks into the core).
    h = harness(overrides={'publish_rate': 1000.0, 'publish_partial': partial})
    h.play(sim, chunk=50)
    h.spin_for(0.3)
    n_before = len(h.inertia)
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + int(sim.t_gyro[-1] * 1e9) + 10**6,
                                        sim.omega[-1], 'base_link'))
    h.spin_for(0.3)
    st = h.latest_diag()
    assert _values(st)['status'] == 'partially_identifiable', st.message
    assert st.level == DiagnosticStatus.WARN
    assert len(h.inertia) == n_before + (1 if partial else 0)
    if partial:
        _, mat = messages.inertia_from_msg(h.inertia[-1])
        assert np.isnan(mat[0, 0]) and np.isfinite(mat[2, 2])
        np.testing.assert_allclose(mat[2, 2], sim.inertia[2, 2], rtol=0.02)


def test_nan_samples_are_dropped_and_counted(harness):
    """NaN gyro and torque samples are dropped, counted and reported in the diagnostics."""
    h = harness(overrides={'publish_rate': 100.0})
    for k in range(20):
        w = [np.nan, 0.0, 0.0] if k % 5 == 0 else [0.1, 0.2, 0.3]
        h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + k * 5_000_000, w, 'base_link'))
    h.pub_torque.publish(messages.wrench_msg(EPOCH_NS, [np.inf, 0, 0], 'base_link'))
    assert h.spin_until(lambda: h.received() == 21, 10.0)
    c = h.est.counts()
    assert (c['gyro_nan_dropped'], c['torque_nan_dropped']) == (4, 1)
    assert _values(h.latest_diag())['gyro_nan_dropped'] == '4'


def test_mismatched_frames_are_refused(harness):
    """Torque in another frame than the gyro is refused, counted and raises an ERROR."""
    h = harness(overrides={'publish_rate': 100.0})
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS, [0.1, 0.2, 0.3], 'base_link'))
    h.spin_until(lambda: h.received() == 1, 10.0)
    for k in range(3):
        h.pub_torque.publish(messages.wrench_msg(EPOCH_NS + k, [0.1, 0, 0], 'tool0'))
    assert h.spin_until(lambda: h.received() == 4, 10.0)
    assert h.est.counts()['torque_frame_refused'] == 3
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + 10**8, [0.1, 0.2, 0.3], 'base_link'))
    h.spin_until(lambda: h.diag and 'tool0' in h.diag[-1].message, 10.0)
    assert h.diag[-1].level == DiagnosticStatus.ERROR
    assert "'tool0'" in h.diag[-1].message and "'base_link'" in h.diag[-1].message


def test_torque_before_first_gyro_is_not_a_frame_error(harness):
    """Torque arriving before any gyro message is dropped and counted, not refused."""
    h = harness(overrides={'publish_rate': 100.0})
    h.pub_torque.publish(messages.wrench_msg(EPOCH_NS, [0.1, 0, 0], 'base_link'))
    assert h.spin_until(lambda: h.received() == 1, 10.0)
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + 10**6, [0.1, 0.2, 0.3], 'base_link'))
    h.pub_torque.publish(messages.wrench_msg(EPOCH_NS + 2 * 10**6, [0.1, 0, 0], 'base_link'))
    assert h.spin_until(lambda: h.received() == 3, 10.0)
    c = h.est.counts()
    assert (c['torque_before_gyro_dropped'], c['torque_frame_refused']) == (1, 0)
    h.latest_diag()
    assert all("differs from the estimation frame" not in st.message for st in h.diag)


def test_backward_stamp_jump_resets_and_reset_service(harness):
    """A bag-loop jump back in stamps (confirmed by the next samples) resets; a small step
    back is dropped; ~/reset works."""
    h = harness(overrides={'publish_rate': 100.0, 'clock_jump_threshold': 0.5})
    back = [EPOCH_NS + 10**7 * k for k in range(1, en.STAMP_CONFIRM + 1)]
    stamps = [EPOCH_NS, EPOCH_NS + 10**9, EPOCH_NS + 10**9 - 10**6, *back]
    for t_ns in stamps:
        h.pub_gyro.publish(messages.imu_msg(t_ns, [0.1, 0.2, 0.3], 'base_link'))
        h.spin_until(lambda: False, 0.05)
    h.spin_until(lambda: h.received() == len(stamps), 10.0)
    c = h.est.counts()
    assert c['gyro_out_of_order_dropped'] == 1 and c['gyro_bad_stamp_refused'] == 0
    assert c['resets'] == 1 and 'jumped back' in c['last_reset_reason']
    assert h.est._gyro.last_ns == back[-1]
    client = h.node.create_client(Trigger, '/inertia_estimator/reset')
    assert client.wait_for_service(timeout_sec=2.0)
    future = client.call_async(Trigger.Request())
    h.spin_until(future.done, 10.0)
    assert future.result().success
    assert h.est.counts()['resets'] == 2


def test_stream_timeout_warns(harness):
    """A stream silent for longer than stream_timeout raises a WARN naming the stream."""
    h = harness(overrides={'stream_timeout': 0.2})
    h.pub_gyro.publish(messages.imu_msg(EPOCH_NS, [0.1, 0.2, 0.3], 'base_link'))
    assert h.spin_until(lambda: any('gyro stream' in s.message and 'silent' in s.message
                                    for s in h.diag), 10.0)
    st = next(s for s in reversed(h.diag) if 'silent' in s.message)
    assert st.level >= DiagnosticStatus.WARN


def test_vector3_gyro_input(harness):
    """With omega_msg_type vector3 the node listens on 'omega' (Vector3Stamped)."""
    h = harness(overrides={'omega_msg_type': 'vector3'}, omega_type=Vector3Stamped)
    assert h.est._gyro.topic == '/omega'
    h.pub_gyro.publish(messages.vector3_stamped(EPOCH_NS, [0.1, 0.2, 0.3], 'base_link'))
    assert h.spin_until(lambda: h.est.counts()['gyro_received'] == 1, 10.0)


def test_remaps_resolve_for_the_polled_inputs(context):
    """Topic remaps and a __node rename apply to the polled input subscriptions."""
    node = en.InertiaEstimatorNode(context=context, cli_args=[
        '--ros-args', '-r', 'imu:=/robot/imu', '-r', '__node:=est_b', '-r', '__ns:=/r2'])
    try:
        assert node._gyro.topic == '/robot/imu'
        assert node._torque.topic == '/r2/torque'
        assert (node.get_name(), node.get_namespace()) == ('est_b', '/r2')
    finally:
        node.destroy_node()


def test_node_graph_shows_the_estimator_with_its_subscriptions(harness):
    """No helper node: the graph lists imu and torque under inertia_estimator itself."""
    h = harness()
    names = h.node.get_node_names_and_namespaces()
    assert ('inertia_estimator', '/') in names
    assert not any('input' in n for n, _ in names), names
    subs = dict(h.node.get_subscriber_names_and_types_by_node('inertia_estimator', '/'))
    assert subs['/imu'] == ['sensor_msgs/msg/Imu']
    assert subs['/torque'] == ['geometry_msgs/msg/WrenchStamped']
    pubs = dict(h.node.get_publisher_names_and_types_by_node('inertia_estimator', '/'))
    assert {'/inertia_estimator/inertia', '/diagnostics'} <= set(pubs)
    info = h.node.get_publishers_info_by_topic('/inertia_estimator/inertia')
    assert [i.qos_profile.durability for i in info] == [DurabilityPolicy.TRANSIENT_LOCAL]
    assert h.est._outputs.inertia.qos_profile.depth == 1  # (discovery does not carry the depth)


def test_diagnostics_follow_diagnostic_updater_convention(harness):
    """One status '<node>: <task>', hardware_id the node name, about once a second."""
    h = harness(overrides={'publish_rate': 100.0})
    h.spin_until(lambda: h.diag, 3.0)
    n0, t0 = len(h.diag), time.monotonic()
    # inputs flowing at 100 updates/s do not add diagnostics
    for k in range(300):
        h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + k * 10**7, [0.1, 0.2, 0.3],
                                            'base_link'))
        h.spin_for(0.01)
    h.spin_until(lambda: time.monotonic() - t0 >= 3.5, 10.0)
    rate = (len(h.diag) - n0) / (time.monotonic() - t0)
    assert 0.5 <= rate <= 1.5, f'{rate:.2f} diagnostics per second'
    st = h.diag[-1]
    assert (st.name, st.hardware_id) == (STATUS_NAME, 'inertia_estimator')


def test_sim_time_clock_jump_resets(harness):
    """With use_sim_time, /clock jumping back resets; input polling does not need /clock."""
    from rosgraph_msgs.msg import Clock

    h = harness(overrides={'use_sim_time': True})
    pub = h.node.create_publisher(Clock, '/clock', 10)
    h.spin_until(lambda: pub.get_subscription_count() > 0, 10.0)
    for sec in (100, 101, 50):
        pub.publish(Clock(clock=messages.ns_to_stamp(sec * 10**9)))
        h.spin_for(0.1)
    assert h.spin_until(lambda: 'ROS clock jumped back 51.000 s'
                        in h.est.counts()['last_reset_reason'], 10.0)
    # Polling runs on the steady clock: input is taken while /clock stands still.
    for k in range(3):
        h.pub_gyro.publish(messages.imu_msg(EPOCH_NS + k * 10**7, [0.1, 0.2, 0.3], 'base_link'))
    assert h.spin_until(lambda: h.est.counts()['gyro_received'] == 3, 10.0)


def _player_harness(harness, tmp_path, kind, est_overrides=None, **params):
    """An estimator harness plus a scene_simulator or bag_player node in its executor."""
    from inertia_ros.io.mcap_writer import write_simulation
    from inertia_ros.nodes.bag_player import BagPlayerNode
    from inertia_ros.nodes.scene_simulator import SceneSimulatorNode

    scene = tmp_path / 'short.yaml'
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'default.yaml').source, duration=4.0)
    scene.write_text(yaml.safe_dump(d))
    h = harness(overrides={'publish_rate': 50.0, **(est_overrides or {})})
    base = {'rate': 20.0, 'wait_for_subscribers': 1, **params}
    if kind == 'simulator':
        base['scene'] = str(scene)
        player = SceneSimulatorNode(context=h.est.context, parameter_overrides=[
            Parameter(k, value=v) for k, v in base.items()])
    else:
        log = tmp_path / 'short.mcap'
        write_simulation(log, simulate(Scene.from_dict(d)))
        base['path'] = str(log)
        player = BagPlayerNode(context=h.est.context, parameter_overrides=[
            Parameter(k, value=v) for k, v in base.items()])
    h.exe.add_node(player)
    truth = []
    h.node.create_subscription(InertiaStamped, f'/{player.get_name()}/truth', truth.append,
                               QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    return h, player, truth


@pytest.mark.parametrize('kind', ['simulator', 'bag_player'])
def test_player_publishes_streams_and_truth(harness, tmp_path, kind):
    """The players publish every sample (no drop into the estimator) and the truth."""
    h, player, truth = _player_harness(harness, tmp_path, kind, exit_on_end=True)
    try:
        assert h.spin_until(lambda: player.done, 10.0)
        n_g, n_q = player.player.published
        assert h.spin_until(lambda: h.received() == n_g + n_q, 10.0)
        assert (n_g, n_q) == (801, 201)
        assert truth, 'no truth published'
        _, mat = messages.inertia_from_msg(truth[0])
        np.testing.assert_allclose(mat[0, 1], 0.05, rtol=0, atol=1e-12)
    finally:
        player.destroy_node()


def test_bag_player_loop_resets_the_estimator(harness, tmp_path):
    """A looping bag_player replays the same stamps; the estimator resets on the jump back."""
    h, player, _ = _player_harness(harness, tmp_path, 'bag_player', loop=True, rate=40.0)
    try:
        assert h.spin_until(lambda: player.player.loops >= 1
                            and h.est.counts()['resets'] >= 1, 10.0)
        assert 'stamps jumped back' in h.est.counts()['last_reset_reason']
    finally:
        player.destroy_node()


@pytest.mark.parametrize('kind', ['simulator', 'bag_player'])
def test_publish_clock_drives_a_sim_time_estimator(harness, tmp_path, kind):
    """publish_clock: /clock advances with the published stamps; an estimator run with
    use_sim_time follows it and still estimates, its outputs stamped from the input."""
    from rosgraph_msgs.msg import Clock

    from inertia_ros.nodes._ros import clock_qos

    h, player, _ = _player_harness(harness, tmp_path, kind, exit_on_end=True,
                                   publish_clock=True, est_overrides={'use_sim_time': True})
    clock: list[int] = []
    stamps: list[int] = []
    # the clock QoS (best effort) with a deep history: every message is counted
    h.node.create_subscription(Clock, '/clock', lambda m: clock.append(
        messages.stamp_to_ns(m.clock)), sensor_qos(1000))
    assert clock_qos().reliability == sensor_qos().reliability
    for msg_type, topic in ((Imu, 'imu'), (WrenchStamped, 'torque')):
        h.node.create_subscription(msg_type, topic, lambda m: stamps.append(
            messages.stamp_to_ns(m.header.stamp)), sensor_qos(1000))
    try:
        assert h.spin_until(lambda: player.done, 10.0)
        n_g, n_q = player.player.published
        assert h.spin_until(lambda: h.received() == len(stamps) == n_g + n_q, 10.0)
        h.spin_for(0.2)
        epoch = player.player.epoch_ns
        # one message per playback step (~0.2 s of wall time at rate 20)
        assert len(clock) >= 5, f'only {len(clock)} /clock messages'
        assert np.all(np.diff(clock) > 0), '/clock went back or repeated'
        # the clock carries the data time: published stamps, from the first to the last
        assert set(clock) <= set(stamps)
        assert clock[0] - epoch <= 50_000_000
        assert clock[-1] == epoch + 4 * 10**9 == max(stamps)
        assert player.player.clock_ns == clock[-1]
        # the estimator's ROS clock is the data time, not the wall time
        assert h.est.get_clock().ros_time_is_active
        assert h.est.get_clock().now().nanoseconds == clock[-1]
        # and it still estimates, stamped with input stamps, not with either clock's now
        assert h.spin_until(lambda: bool(h.inertia), 5.0)
        assert h.est.counts()['resets'] == 0, h.est.counts()['last_reset_reason']
        out = messages.stamp_to_ns(h.inertia[-1].header.stamp)
        assert out in set(stamps) and out > epoch
        _, mat = messages.inertia_from_msg(h.inertia[-1])
        np.testing.assert_allclose(mat[0, 1], 0.05, rtol=0, atol=0.01)
    finally:
        player.destroy_node()


@pytest.mark.parametrize('kwargs, match', [
    ({'t_gyro': [0.0, 2.0, 1.0]}, 't_gyro must be non-decreasing'),
    ({'omega': np.zeros((2, 3))}, r'omega must have shape \(3, 3\)'),
    ({'rate': 0.0}, 'rate must be a positive'),
    ({'omega_msg_type': 'twist'}, 'omega_msg_type must be'),
])
def test_stream_player_rejects_bad_input(context, kwargs, match):
    """StreamPlayer refuses unsorted stamps, wrong shapes, bad rates and unknown types."""
    from inertia_ros.nodes.playback import StreamPlayer

    node = Node('player_args', context=context)
    args = {'t_gyro': [0.0, 1.0, 2.0], 'omega': np.zeros((3, 3)), 't_torque': [0.0],
            'torque': np.zeros((1, 3))}
    args.update(kwargs)
    try:
        with pytest.raises(ValueError, match=match):
            StreamPlayer(node, args.pop('t_gyro'), args.pop('omega'), args.pop('t_torque'),
                         args.pop('torque'), 'base_link', **args)
    finally:
        node.destroy_node()


# --------------------------------------------------------------------------- processes
def _env():
    return dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN_ID + 110),
                PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''))


def run_pair(node, ctx, est_cmd, sim_cmd, env, tmp_path: Path, timeout: float,
             procs: list, logs: list):
    """Run the estimator and simulator processes; collect ~/inertia and ~/truth on ``node``.

    The simulator starts only once ``node`` has discovered the estimator's ~/inertia
    publisher (as ``make demo`` does), so that no estimate is lost to slow discovery.
    Collection ends 1 s after the simulator exits, or at ``timeout`` [s].
    The processes and their logs are appended to ``procs`` and ``logs`` (for ``stop_all``,
    also when this fails).  Returns (estimates, truths).
    """
    from inertia_ros.cli.demo import wait_until_matched

    got, truth = [], []
    sub = node.create_subscription(InertiaStamped, '/inertia_estimator/inertia', got.append,
                                   100)
    node.create_subscription(InertiaStamped, '/scene_simulator/truth', truth.append,
                             QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    exe = SingleThreadedExecutor(context=ctx)
    exe.add_node(node)
    logs += [open(tmp_path / n, 'w') for n in ('est.log', 'sim.log')]
    procs.append(subprocess.Popen(est_cmd, env=env, stdout=logs[0], stderr=subprocess.STDOUT))
    try:
        problem = wait_until_matched(lambda: exe.spin_once(timeout_sec=0.05), [sub], procs[0],
                                     30.0)
        assert not problem, problem + '\n' + (tmp_path / 'est.log').read_text()[-3000:]
        procs.append(subprocess.Popen(sim_cmd, env=env, stdout=logs[1],
                                      stderr=subprocess.STDOUT))
        end = time.monotonic() + timeout
        finished = None
        while time.monotonic() < end:
            exe.spin_once(timeout_sec=0.05)
            if finished is None and procs[1].poll() is not None:
                finished = time.monotonic()
            if finished is not None and time.monotonic() - finished > 1.0:
                break
    finally:
        exe.shutdown()
    return got, truth


def stop_all(procs, logs):
    """SIGINT, then kill, every process; close the logs."""
    from inertia_ros.cli.demo import stop_processes
    stop_processes(procs)
    for log in logs:
        log.close()


@pytest.mark.slow
def test_nodes_as_processes_over_dds(tmp_path):
    """Simulator and estimator as separate processes: an estimate reaches a third process."""
    scene = tmp_path / 'short.yaml'
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'default.yaml').source, duration=20.0)
    scene.write_text(yaml.safe_dump(d))
    env = _env()
    est_cmd = [sys.executable, '-m', 'inertia_ros.inertia_estimator_node', '--ros-args',
               '--params-file', str(ROOT / 'config' / 'inertia_estimator.yaml')]
    sim_cmd = [sys.executable, '-m', 'inertia_ros.scene_simulator_node', '--ros-args',
               '-p', f'scene:={scene}', '-p', 'rate:=8.0', '-p', 'wait_for_subscribers:=1',
               '-p', 'exit_on_end:=true']
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID + 110)
    procs, logs = [], []
    try:
        node = Node('test_listener', context=ctx)
        got, truth = run_pair(node, ctx, est_cmd, sim_cmd, env, tmp_path, 40.0, procs, logs)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        stop_all(procs, logs)
    log_text = (tmp_path / 'est.log').read_text() + (tmp_path / 'sim.log').read_text()
    assert got, 'no estimate published by the estimator process\n' + log_text[-3000:]
    assert truth, 'no truth from the simulator process'
    _, est = messages.inertia_from_msg(got[-1])
    _, true = messages.inertia_from_msg(truth[-1])
    # 20 s of the nominal scene: the last estimate is within 2% of I3 (atol 0.024 kg m^2).
    np.testing.assert_allclose(est, true, rtol=0, atol=0.02 * np.linalg.eigvalsh(true)[-1])


# --------------------------------------------------------------------------- demo
def test_demo_never_overwrites(tmp_path):
    """The demo's output names get a numeric suffix instead of replacing a file."""
    from inertia_ros.cli.demo import _unique

    first = tmp_path / 'demo_x.png'
    assert _unique(first) == first
    first.write_text('user file')
    second = _unique(first)
    assert second == tmp_path / 'demo_x-1.png'
    second.write_text('x')
    assert _unique(first) == tmp_path / 'demo_x-2.png'
    assert first.read_text() == 'user file'


def test_wait_until_matched_reports_why_it_gave_up():
    """The discovery wait ends with a one-line reason: a dead publisher, or the timeout."""
    from types import SimpleNamespace

    from inertia_ros.cli.demo import wait_until_matched

    count = {'n': 0}
    sub = SimpleNamespace(topic_name='/inertia_estimator/inertia',
                          get_publisher_count=lambda: count['n'])
    dead = subprocess.Popen([sys.executable, '-c', 'pass'])
    dead.wait()
    assert 'exited (status 0)' in wait_until_matched(lambda: None, [sub], dead, 5.0)
    alive = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(30)'])
    try:
        msg = wait_until_matched(lambda: time.sleep(0.01), [sub], alive, 0.1)
        assert msg == 'no publisher discovered on /inertia_estimator/inertia within 0.1 s'

        def spin():
            count['n'] = 1            # discovery completes during the first spin
        assert wait_until_matched(spin, [sub], alive, 5.0) == ''
    finally:
        alive.kill()
        alive.wait()


def test_demo_plot_without_estimates(tmp_path):
    """A run that got no estimate still gets a readable PNG, without matplotlib warnings."""
    import warnings

    from inertia_ros.cli.demo import _plot, _Run

    png = tmp_path / 'empty.png'
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        _plot(png, _Run(), 'nominal')
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('argv, match', [
    (['--rate', '0'], '--rate: must be in'),
    (['--scene', 'no/such.yaml'], '--scene: no such file'),
    (['--domain-id', '300'], '--domain-id: must be in'),
])
def test_demo_rejects_bad_arguments(argv, match, capsys):
    """Bad demo arguments give exit status 2 and a one-line error, no traceback."""
    from inertia_ros.cli import main

    assert main(['demo', *argv]) == 2
    err = capsys.readouterr().err
    assert match in err and 'Traceback' not in err


@pytest.mark.slow
def test_demo_runs_end_to_end(tmp_path):
    """`python -m inertia_ros demo` on a short scene: exit 0, MCAP + PNG written, small error."""
    from inertia_ros.io.logs import read_log

    scene = tmp_path / 'short.yaml'
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'default.yaml').source, duration=15.0)
    scene.write_text(yaml.safe_dump(d))
    out = tmp_path / 'out'
    proc = subprocess.run(
        [sys.executable, '-m', 'inertia_ros', 'demo', '--scene', str(scene), '--rate', '10',
         '--out', str(out), '--domain-id', str(DOMAIN_ID + 110), '--quiet'],
        env=_env(), capture_output=True, text=True, timeout=90, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    mcaps, pngs = list(out.glob('*.mcap')), list(out.glob('*.png'))
    assert len(mcaps) == 1 and len(pngs) == 1 and pngs[0].stat().st_size > 10_000
    log = read_log(mcaps[0])
    assert log.omega.t.size > 2000 and log.torque.t.size > 500
    err = float(proc.stdout.split('final error max|I_est - I_true| / (trace/3 of the truth) = '
                                  )[1].split('%')[0])
    assert err < 2.0, proc.stdout
    # The demo reports what the estimator received against what it recorded itself.  Sensor
    # streams are best effort, so on a loaded 2-core machine running the whole suite a few
    # messages may be lost at 10x real time (the no-drop target is measured at 1 kHz by
    # scripts/bench_node.py, not here): at least 95% must arrive.
    m = re.search(r'gyro (\d+), torque (\d+)(?: \(recorded here: (\d+), (\d+)\))?',
                  proc.stdout)
    assert m, proc.stdout
    got = np.array([int(m.group(1)), int(m.group(2))])
    recorded = np.array([log.omega.counts.received, log.torque.counts.received])
    if m.group(3) is not None:
        np.testing.assert_array_equal([int(m.group(3)), int(m.group(4))], recorded)
    assert np.all(got <= recorded) and np.all(got >= 0.95 * recorded), proc.stdout


def test_urdf_service(harness):
    """~/urdf: refuses without a complete tensor, then returns the tensor as a URDF document
    (urdf_mass, urdf_link) that round-trips exactly through urdf_parser_py."""
    urdf = pytest.importorskip('urdf_parser_py.urdf')
    from inertia_ros.core.estimation import InertiaEstimate
    h = harness(overrides={'urdf_mass': 12.5, 'urdf_link': 'payload'})
    client = h.node.create_client(Trigger, '/inertia_estimator/urdf')
    assert client.wait_for_service(timeout_sec=2.0)

    def call():
        future = client.call_async(Trigger.Request())
        h.spin_until(future.done, 10.0)
        return future.result()

    first = call()
    assert not first.success and 'no complete tensor' in first.message
    I = np.array([[1.0, 0.05, -0.03], [0.05, 1.2, 0.02], [-0.03, 0.02, 0.9]])
    h.est._last_estimate = InertiaEstimate('ok', inertia=I, model='full')
    res = call()
    assert res.success
    robot = urdf.URDF.from_xml_string(res.message)
    (link,) = robot.links
    assert link.name == 'payload' and link.inertial.mass == 12.5
    np.testing.assert_array_equal(np.array(link.inertial.inertia.to_matrix()), I)


def test_recursive_node_estimate_equals_the_core_on_the_same_samples(harness):
    """The node hands samples over at every poll, merges them before each update and tests
    adequacy after publishing: its last ~/inertia equals a RecursiveEstimator fed the same
    samples (stamps up to the estimate's, same time origin) in one block (rtol 1e-9)."""
    from inertia_ros.core.estimation import RecursiveEstimator

    sim = simulate(_short_scene(duration=12.0), seed=5)
    h = harness(overrides={'publish_rate': 20.0, 'torque_bias': 'off'})
    h.play(sim, chunk=50)
    h.spin_for(0.3)
    assert h.inertia, 'no estimate published'
    stamp, published = messages.inertia_from_msg(h.inertia[-1])
    g_ns = EPOCH_NS + np.round(sim.t_gyro * 1e9).astype(np.int64)
    q_ns = EPOCH_NS + np.round(sim.t_torque * 1e9).astype(np.int64)
    epoch = int(g_ns[0])                          # the node's time origin: the first sample
    core = RecursiveEstimator(model='full', torque_bias='off', reselect_every=20)
    g, q = g_ns <= stamp, (q_ns <= stamp) & (q_ns >= epoch)
    core.add_gyro((g_ns[g] - epoch) * 1e-9, sim.omega[g])
    core.add_torque((q_ns[q] - epoch) * 1e-9, sim.torque[q])
    ref = core.estimate()
    assert ref.status == 'ok'
    np.testing.assert_allclose(published, ref.inertia, rtol=1e-9, atol=0)
