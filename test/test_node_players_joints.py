"""The players publish wheel and rotor speeds on ``joint_states`` (issue 14 item 1 follow-up).

``scene_simulator`` (a wheels scene, the quadrotor scene) and ``bag_player`` (bags/wheels.mcap)
run in process with the estimator and a counting listener on one executor in their own DDS
domain: the JointState messages arrive complete (received = sent, same stamps), a torque-free
actuator scene has no ``torque`` topic, and the estimator with ``wheels_file`` reaches the true
tensor.
"""
from __future__ import annotations

import os
import time

import numpy as np
import pytest
import yaml

from conftest import ROOT

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from test_wheels import THETA_IDX, scene_dict  # noqa: E402

from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.io.joint_state import read_wheel_speeds  # noqa: E402
from inertia_ros.io.logs import read_log  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402
from inertia_ros.nodes import estimator as en  # noqa: E402
from inertia_ros.nodes import messages  # noqa: E402
from inertia_ros.nodes._ros import sensor_qos  # noqa: E402
from inertia_ros.nodes.bag_player import BagPlayerNode, read_joint_speeds  # noqa: E402
from inertia_ros.nodes.scene_simulator import SceneSimulatorNode  # noqa: E402

pytestmark = pytest.mark.ros

DOMAIN_ID = 1 + (os.getpid() + 53) % 110
WHEELS_BAG = ROOT / 'bags' / 'wheels.mcap'


@pytest.fixture(scope='module')
def context():
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


class Listener:
    """Counts the JointState messages on ``topic`` and keeps their stamps [ns] and speeds;
    also subscribes to ``/imu`` and ``/torque`` so that it counts as a second subscriber of
    every stream (``wait_for_subscribers: 2`` then waits for it too)."""

    def __init__(self, context, topic='/joint_states'):
        self.node = Node('joint_listener', context=context)
        self.stamps: list[int] = []
        self.speeds: list[list[float]] = []
        self.names: set[tuple[str, ...]] = set()
        self.node.create_subscription(JointState, topic, self._on, sensor_qos(10000))
        self.node.create_subscription(Imu, '/imu', lambda m: None, sensor_qos(10))
        self.node.create_subscription(WrenchStamped, '/torque', lambda m: None, sensor_qos(10))

    def _on(self, msg: JointState) -> None:
        self.stamps.append(messages.stamp_to_ns(msg.header.stamp))
        self.speeds.append(list(msg.velocity))
        self.names.add(tuple(msg.name))


def play(context, player, estimator, listener, limit=60.0):
    """Spin the three nodes until the player reports the end (+1 s), then a final update."""
    exe = SingleThreadedExecutor(context=context)
    for n in (player, estimator, listener.node):
        exe.add_node(n)
    end = time.monotonic() + limit
    try:
        while not player.done and time.monotonic() < end:
            exe.spin_once(timeout_sec=0.02)
        assert player.done, 'playback did not end in time'
        linger = time.monotonic() + 1.0
        while time.monotonic() < linger:
            exe.spin_once(timeout_sec=0.02)
    finally:
        exe.shutdown()
    estimator._update(time.monotonic())
    return estimator._last_estimate


def test_joint_state_msg():
    """Names and velocities as given, position/effort empty; a wrong length is refused."""
    m = messages.joint_state_msg(1_700_000_000_123_456_789, ['rw1', 'rw2'], [1.5, -2.0])
    assert messages.stamp_to_ns(m.header.stamp) == 1_700_000_000_123_456_789
    assert list(m.name) == ['rw1', 'rw2'] and list(m.velocity) == [1.5, -2.0]
    assert len(m.position) == 0 and len(m.effort) == 0 and m.header.frame_id == ''
    with pytest.raises(ValueError, match=r'velocity must have shape \(2,\)'):
        messages.joint_state_msg(0, ['rw1', 'rw2'], [1.0, 2.0, 3.0])


def test_read_joint_speeds_of_the_wheels_log():
    """The log's JointState stream as the batch CLI reads it (same stamps and speeds)."""
    topic, names, t_ns, speed = read_joint_speeds(WHEELS_BAG)
    assert topic == '/joint_states' and names == ['rw1', 'rw2', 'rw3']
    _t, t_ref, v_ref = read_wheel_speeds(WHEELS_BAG, names, topic)
    np.testing.assert_array_equal(t_ns, t_ref)
    np.testing.assert_array_equal(speed, v_ref)
    assert read_joint_speeds(ROOT / 'bags' / 'default.mcap') is None


def test_scene_simulator_wheels_live(context, tmp_path):
    """A 4 s wheels scene at rate 1 into the estimator (wheels_file, torque_topic none): every
    JointState message sent is received by the listener and the estimator (none lost, same
    stamps and speeds as simulated), no torque topic exists, and the estimate is within 3
    sigma of the truth per element and 3 % (Frobenius) overall."""
    scene_path = tmp_path / 'wheels.yaml'
    scene_path.write_text(yaml.safe_dump(scene_dict(duration=4.0, gyro_rate=100.0)))
    sc = Scene.from_dict(scene_dict(duration=4.0, gyro_rate=100.0))
    wheels = tmp_path / 'wheels_file.yaml'
    wheels.write_text(yaml.safe_dump({'wheels': [
        {'joint': w.joint, 'axis': w.axis.tolist(), 'inertia': float(w.inertia),
         'inertia_std': 0.01 * w.inertia} for w in sc.wheels.wheels]}))
    listener = Listener(context)
    est_node = en.InertiaEstimatorNode(context=context, parameter_overrides=overrides(
        wheels_file=str(wheels), torque_topic='none', torque_bias='auto'))
    sim_node = SceneSimulatorNode(context=context, parameter_overrides=overrides(
        scene=str(scene_path), seed=5, wait_for_subscribers=2, exit_on_end=True))
    try:
        player = sim_node.player
        assert player.torque_publisher is None and player.joint_publisher is not None
        sim = sim_node.sim
        est = play(context, sim_node, est_node, listener)
        assert sim_node.count_publishers('/torque') == 0      # the listener subscribes
        assert sim_node.count_publishers('/joint_states') == 1
        sent = sim.t_wheel.size
        assert player.published_joints == sent and player.published[1] == 0
        assert len(listener.stamps) == sent, (len(listener.stamps), sent)
        assert listener.names == {('rw1', 'rw2', 'rw3')}
        stamps = np.array(listener.stamps) - player.epoch_ns
        np.testing.assert_array_equal(stamps, np.round(sim.t_wheel * 1e9).astype(np.int64))
        np.testing.assert_allclose(listener.speeds, sim.wheel_speed, rtol=0, atol=0)
        counts = est_node.counts()
        assert counts['joints_received'] == sent and counts['joints_malformed'] == 0
        assert est.status == 'ok', est.diagnostics.get('reason')
        z = (est.theta - sim.inertia[THETA_IDX]) / est.theta_std
        err = np.linalg.norm(est.inertia - sim.inertia) / np.linalg.norm(sim.inertia)
        print(f'scene_simulator wheels: {sent} JointState sent, {len(listener.stamps)} '
              f'received; error {err:.4f}, max |z| {np.max(np.abs(z)):.2f}')
        assert np.all(np.abs(z) < 3) and err < 0.03, (z, err)
    finally:
        for n in (sim_node, est_node, listener.node):
            n.destroy_node()


def test_scene_simulator_quadrotor_publishes_rotor_speeds(context):
    """The rotors scene: JointState with the four rotor joints, no torque topic; the start
    waits for a subscriber on joint_states (not only on imu)."""
    sim_node = SceneSimulatorNode(context=context, parameter_overrides=overrides(
        scene=str(ROOT / 'config' / 'scenes' / 'quadrotor.yaml'), wait_for_subscribers=1,
        wait_timeout=0.0))
    try:
        p = sim_node.player
        assert p.torque_publisher is None and p.joint_names == [
            w.joint for w in load_scene(ROOT / 'config' / 'scenes' / 'quadrotor.yaml')
            .wheels.wheels]
        assert [q.topic_name for q in p.publishers] == ['/imu', '/joint_states']
        imu_only = Node('imu_only', context=context)
        imu_only.create_subscription(Imu, '/imu', lambda m: None, sensor_qos(10))
        exe = SingleThreadedExecutor(context=context)
        exe.add_node(sim_node)
        exe.add_node(imu_only)
        end = time.monotonic() + 1.5
        while time.monotonic() < end:
            exe.spin_once(timeout_sec=0.02)
        assert p.published == [0, 0] and p.published_joints == 0  # joint_states unmatched: waits
        exe.shutdown()
        imu_only.destroy_node()
    finally:
        sim_node.destroy_node()


def test_bag_player_wheels_log_live(context):
    """bags/wheels.mcap (20 s) at rate 2 into the estimator with bags/wheels_wheels.yaml: all
    JointState messages of the log arrive with their recorded stamps, the recorded torque
    topic is replayed too, and the estimate is within 3 sigma per element and 2 % overall."""
    listener = Listener(context, '/joint_states')
    est_node = en.InertiaEstimatorNode(context=context, parameter_overrides=overrides(
        wheels_file=str(ROOT / 'bags' / 'wheels_wheels.yaml'), torque_bias='off'))
    bag_node = BagPlayerNode(context=context, parameter_overrides=overrides(
        path=str(WHEELS_BAG), rate=2.0, wait_for_subscribers=2, exit_on_end=True))
    try:
        _topic, names, t_ns, speed = read_joint_speeds(WHEELS_BAG)
        est = play(context, bag_node, est_node, listener)
        assert bag_node.player.published_joints == t_ns.size
        assert listener.stamps == t_ns.tolist()             # original_stamps: as recorded
        np.testing.assert_array_equal(listener.speeds, speed)
        counts = est_node.counts()
        assert counts['joints_received'] == t_ns.size and counts['torque_received'] > 0
        truth = read_log(WHEELS_BAG).truth[0][1]
        assert est.status == 'ok', est.diagnostics.get('reason')
        z = (est.theta - truth[THETA_IDX]) / est.theta_std
        err = np.linalg.norm(est.inertia - truth) / np.linalg.norm(truth)
        print(f'bag_player wheels.mcap: {t_ns.size} JointState sent, {len(listener.stamps)} '
              f'received; error {err:.4f}, max |z| {np.max(np.abs(z)):.2f}')
        assert np.all(np.abs(z) < 3) and err < 0.02, (z, err)
    finally:
        for n in (bag_node, est_node, listener.node):
            n.destroy_node()


def test_launch_actuator_arguments_default_to_the_parameter_file():
    """wheels_file, rotors_file and torque_topic are launch arguments of all three launch
    files, passed down to the estimator; their defaults are config/inertia_estimator.yaml's,
    so a launch without them behaves as before."""
    import xml.etree.ElementTree as ET
    cfg = yaml.safe_load((ROOT / 'config' / 'inertia_estimator.yaml').read_text())
    defaults = cfg['inertia_estimator']['ros__parameters']
    for name in ('estimator', 'sim', 'replay'):
        root = ET.parse(ROOT / 'launch' / f'{name}.launch.xml').getroot()
        args = {a.get('name'): a.get('default') for a in root.findall('arg')}
        for key in ('wheels_file', 'rotors_file', 'torque_topic'):
            assert args[key] == defaults[key], (name, key)
        if name != 'estimator':
            passed = {a.get('name'): a.get('value') for a in root.find('include').iter('arg')}
            assert passed['wheels_file'] == '$(var wheels_file)', name
