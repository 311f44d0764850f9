"""The live estimator with wheels or rotors on ``joint_states`` (issue 14 items 1-2).

The node class is fed in process (its own DDS domain), as in ``test_node_live``: serialised
Imu, JointState (and WrenchStamped) messages go through the polled-subscription path
(``_accept`` / ``_accept_joints``) and the update (``_update``) every 0.1 s of data.
"""
from __future__ import annotations

import os
import time

import numpy as np
import pytest
import yaml

from conftest import ROOT

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from test_wheels import THETA_IDX, scene_dict  # noqa: E402

from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402
from inertia_ros.nodes import estimator as en  # noqa: E402
from inertia_ros.nodes import messages  # noqa: E402

pytestmark = pytest.mark.ros

DOMAIN_ID = 1 + (os.getpid() + 91) % 110
EPOCH_NS = 1_700_000_000_000_000_000
ROTORS_FILE = ROOT / 'config' / 'rotors' / 'quadrotor.yaml'


@pytest.fixture(scope='module')
def context():
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def node(context):
    made = []

    def make(cli_args=None, **overrides):
        n = en.InertiaEstimatorNode(context=context, cli_args=cli_args, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items()])
        made.append(n)
        return n
    yield make
    for n in made:
        n.destroy_node()


def wheels_file(tmp_path, sc, rel_std=0.01, scale=None):
    """A wheels YAML for the scene's wheels (inertias times ``scale``, ``rel_std`` sigma)."""
    scale = np.ones(len(sc.wheels.wheels)) if scale is None else scale
    d = {'wheels': [{'joint': w.joint, 'axis': w.axis.tolist(),
                     'inertia': float(w.inertia * s), 'inertia_std': rel_std * w.inertia}
                    for w, s in zip(sc.wheels.wheels, scale, strict=True)]}
    p = tmp_path / f'wheels_{abs(hash(tuple(scale))) % 10**8}.yaml'
    p.write_text(yaml.safe_dump(d))
    return p


def joint_payloads(t_ns, names, speed):
    out = []
    for t, v in zip(t_ns, speed, strict=True):
        m = JointState()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t), 10**9)
        m.name = list(names)
        m.velocity = [float(x) for x in v]
        out.append(serialize_message(m))
    return out


def feed(n, sim, names, torque=False, chunk=0.1):
    """Feed gyro, JointState (and torque) in ``chunk``-second batches, updating each second."""

    def ns(t):
        return EPOCH_NS + np.round(t * 1e9).astype(np.int64)
    tg, tw, tt = ns(sim.t_gyro), ns(sim.t_wheel), ns(sim.t_torque)
    kg = np.floor(sim.t_gyro / chunk + 1e-9).astype(int)
    kw = np.floor(sim.t_wheel / chunk + 1e-9).astype(int)
    kt = np.floor(sim.t_torque / chunk + 1e-9).astype(int)
    for b in range(int(kg[-1]) + 1):
        g, w, q = kg == b, kw == b, kt == b
        if g.any():
            n._accept(n._gyro, [serialize_message(messages.imu_msg(int(t), v, 'base_link'))
                                for t, v in zip(tg[g], sim.omega[g], strict=True)])
        if w.any():
            n._accept_joints(joint_payloads(tw[w], names, sim.wheel_speed[w]))
        if torque and q.any():
            n._accept(n._torque, [serialize_message(messages.wrench_msg(int(t), v, 'base_link'))
                                  for t, v in zip(tt[q], sim.torque[q], strict=True)])
        if b % 10 == 9:
            n._update(time.monotonic())
    n._update(time.monotonic())
    return n._last_estimate


def test_node_wheels_calibrated_over_seeds(node, tmp_path):
    """Imu + JointState wheel speeds + wheels_file (torque_topic none), 10 seeds of 4 s, the
    file's inertias off by their stated 1 % sigma: every estimate ok, RMS z of the six
    elements in [0.7, 1.5], median error below 2 %; the diagnostics count the joints."""
    zs, errs = [], []
    for seed in range(10):
        sc = Scene.from_dict(scene_dict(duration=4.0, gyro_rate=100.0))
        sim = simulate(sc, seed)
        rng = np.random.default_rng(2000 + seed)
        f = wheels_file(tmp_path, sc, scale=1 + 0.01 * rng.standard_normal(3))
        n = node(wheels_file=str(f), torque_topic='none', torque_bias='auto')
        est = feed(n, sim, [w.joint for w in sc.wheels.wheels])
        assert est.status == 'ok', est.diagnostics.get('reason')
        assert est.diagnostics['input_uncertainty']['theta_std_added'].shape == (6,)
        zs.append((est.theta - sim.inertia[THETA_IDX]) / est.theta_std)
        errs.append(np.linalg.norm(est.inertia - sim.inertia) / np.linalg.norm(sim.inertia))
        c = n.counts()
        assert c['joints_received'] == len(sim.t_wheel) and c['joints_malformed'] == 0
        n.destroy_node()
    rms = float(np.sqrt(np.mean(np.square(zs))))
    assert 0.7 <= rms <= 1.5, rms
    assert np.median(errs) < 0.02, errs
    per_element = np.sqrt(np.mean(np.square(zs), axis=0))     # 10 seeds: a wide band
    assert np.all((per_element >= 0.4) & (per_element <= 2.0)), per_element


def test_node_wheels_with_a_torque_topic(node, tmp_path):
    """Wheels plus the scene's torque on the torque topic: within 3 sigma; before the first
    torque message the reason says the wheel input waits for it."""
    d = scene_dict(duration=6.0, gyro_rate=100.0)
    d['torque'] = [{'type': 'multisine', 'amplitude': [0.01, 0.01, 0.01],
                    'f_min': 0.2, 'f_max': 2.0}]
    d['torque_sensor'] = {'rate': 50.0, 'noise_std': 1e-4}
    sc = Scene.from_dict(d)
    sim = simulate(sc, 4)
    names = [w.joint for w in sc.wheels.wheels]
    n = node(wheels_file=str(wheels_file(tmp_path, sc, rel_std=0.0)), torque_bias='off')
    waiting = feed(n, sim, names, torque=False)
    assert waiting.status == 'insufficient_data'
    assert 'torque_topic:=none' in waiting.diagnostics['reason']
    n2 = node(wheels_file=str(wheels_file(tmp_path, sc, rel_std=0.0)), torque_bias='off')
    est = feed(n2, sim, names, torque=True)
    z = (est.theta - sim.inertia[THETA_IDX]) / est.theta_std
    assert est.status == 'ok' and np.all(np.abs(z) < 3), z


def test_node_rotors(node):
    """A quadrotor log (6 s, JointState rotor speeds) with rotors_file: ok, every element
    within 3 sigma (the file's coefficients are the true ones, their sigma propagated)."""
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'quadrotor.yaml').source, duration=6.0)
    sc = Scene.from_dict(d)
    sim = simulate(sc, 3)
    n = node(rotors_file=str(ROTORS_FILE), torque_topic='none', torque_bias='auto')
    est = feed(n, sim, [w.joint for w in sc.wheels.wheels])
    assert est.status == 'ok', est.diagnostics.get('reason')
    z = (est.theta - sim.inertia[THETA_IDX]) / est.theta_std
    assert np.all(np.abs(z) < 3), z
    assert len(est.diagnostics['input_uncertainty']['inputs']) == 12


def test_node_joint_states_topic_is_remappable_and_checked(node, tmp_path):
    """``joint_states`` follows a remap; messages without the file's joints raise a WARN."""
    sc = Scene.from_dict(scene_dict(duration=1.0, gyro_rate=100.0))
    n = node(cli_args=['--ros-args', '-r', 'joint_states:=/robot/joint_states'],
             wheels_file=str(wheels_file(tmp_path, sc)), torque_topic='none')
    assert n._joints.topic == '/robot/joint_states'
    n._accept(n._gyro, [serialize_message(messages.imu_msg(EPOCH_NS, [0.0, 0.0, 0.0],
                                                           'base_link'))])
    n._accept_joints(joint_payloads([EPOCH_NS + 10**7], ['other'], [[1.0]]))
    problems = ' '.join(text for _, text in n._problems(time.monotonic()))
    assert 'none with a velocity for every joint' in problems and 'rw1' in problems


def test_node_actuator_parameter_errors(node, tmp_path):
    """A missing or invalid file or both files: one line naming the cause."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text('rotors:\n  - {joint: a, position: [0, 0], spin: 1, k_f: 1, k_m: 0}\n')
    cases = [({'wheels_file': str(tmp_path / 'missing.yaml')}, "'wheels_file'"),
             ({'rotors_file': str(bad)}, 'position: must be a list of 3 numbers'),
             ({'wheels_file': str(ROOT / 'config' / 'wheels' / 'wheels.yaml'),
               'rotors_file': str(ROTORS_FILE)}, 'use one of them')]
    for overrides, match in cases:
        with pytest.raises(ValueError) as err:
            node(**overrides)
        assert match in str(err.value) and '\n' not in str(err.value), str(err.value)


@pytest.mark.parametrize('method', ['batch', 'tracking'])
def test_node_rotors_with_method_batch(node, method):
    """Issue 26: the same quadrotor log with ``method: batch`` (a 30 s window re-solved by the
    batch momentum estimator) or ``tracking`` (the Kalman tracker on the same reduction):
    ok, every element within 3 sigma.  On f0eb6ad (tracking: d5ad26d) refused."""
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'quadrotor.yaml').source, duration=6.0)
    sc = Scene.from_dict(d)
    sim = simulate(sc, 3)
    n = node(rotors_file=str(ROTORS_FILE), torque_topic='none',
             torque_bias='auto' if method == 'batch' else 'off', method=method)
    est = feed(n, sim, [w.joint for w in sc.wheels.wheels])
    z = (est.theta - sim.inertia[THETA_IDX]) / est.theta_std
    assert est.status == 'ok' and np.all(np.abs(z) < 3), (est.status, z)
    assert est.method == ('integral' if method == 'batch' else 'tracking')
    assert 'input_uncertainty' in est.diagnostics
