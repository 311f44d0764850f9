"""What the live estimator says while it waits, and a bad ``--params-file`` (issue 29 item 11).

With ``torque_topic none`` and wheels, the JointState speeds are the only known torque: an
``insufficient_data`` estimate names the input it waits for, never "gyro samples covered by
torque".  A ``--params-file`` that is missing, not YAML or not a parameters file is refused
with one stderr line naming the file, exit 2, before rcl reads it.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np
import pytest

from inertia_ros.nodes.params_file import params_file_problem

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from test_node_actuators import joint_payloads, wheels_file  # noqa: E402
from test_wheels import scene_dict  # noqa: E402

from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.nodes import estimator as en  # noqa: E402
from inertia_ros.nodes import messages  # noqa: E402

pytestmark = pytest.mark.ros

DOMAIN_ID = 1 + (os.getpid() + 57) % 110
EPOCH_NS = 1_700_000_000_000_000_000


@pytest.fixture(scope='module')
def context():
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def _gyro(n, t_ns, omega):
    n._accept(n._gyro, [serialize_message(messages.imu_msg(int(t), w, 'base_link'))
                        for t, w in zip(t_ns, omega, strict=True)])


def _reason(n):
    n._update(time.monotonic())
    est = n._last_estimate
    assert est.status == 'insufficient_data'
    return est.diagnostics['reason']


def test_wheels_only_node_says_what_it_waits_for(context, tmp_path):
    """torque_topic none + wheels: before any JointState, with JointStates lacking the file's
    joints, and with too few covered samples, the reason names the JointState stream."""
    sc = Scene.from_dict(scene_dict(duration=2.0, gyro_rate=100.0))
    sim = simulate(sc, seed=3)
    names = [w.joint for w in sc.wheels.wheels]
    n = en.InertiaEstimatorNode(context=context, parameter_overrides=[
        Parameter('wheels_file', value=str(wheels_file(tmp_path, sc))),
        Parameter('torque_topic', value='none')])
    try:
        tg = EPOCH_NS + np.round(sim.t_gyro * 1e9).astype(np.int64)
        tw = EPOCH_NS + np.round(sim.t_wheel * 1e9).astype(np.int64)
        _gyro(n, tg[:10], sim.omega[:10])
        reasons = [_reason(n)]
        assert reasons[0].startswith('waiting for JointState messages on /joint_states')
        n._accept_joints(joint_payloads(tw[:5], ['other'], [[1.0]] * 5))
        reasons.append(_reason(n))
        assert 'with a velocity for every joint' in reasons[1] and 'rw1, rw2, rw3' in reasons[1]
        w = tw <= tg[12]
        n._accept_joints(joint_payloads(tw[w], names, sim.wheel_speed[w]))
        _gyro(n, tg[10:15], sim.omega[10:15])
        reasons.append(_reason(n))
        assert "covered by the wheels' speeds on /joint_states" in reasons[2]
        assert not any('covered by torque' in r for r in reasons), reasons
        # the full record: the same node reaches an estimate (the reasons were only waiting)
        _gyro(n, tg[15:], sim.omega[15:])
        w = tw > tg[12]
        n._accept_joints(joint_payloads(tw[w], names, sim.wheel_speed[w]))
        n._update(time.monotonic())
        assert n._last_estimate.status != 'insufficient_data'
    finally:
        n.destroy_node()


def _run(args):
    return subprocess.run([sys.executable, '-m', 'inertia_ros.inertia_estimator_node',
                           '--ros-args', *args], capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN_ID + 110)),
                          check=False)


@pytest.mark.parametrize('content, expected', [
    (None, 'the file does not exist'),
    ('a: [1, 2\n', 'cannot be parsed as YAML'),
    ('- 1\n', 'not a ROS 2 parameters file'),
    ('inertia_estimator:\n  ros__parameters:\n', 'not a ROS 2 parameters file'),
])
def test_bad_params_file_is_named_in_one_line(tmp_path, content, expected):
    """The node exits 2 with one stderr line naming the file and what is wrong with it."""
    path = tmp_path / 'params.yaml'
    if content is not None:
        path.write_text(content)
    proc = _run(['--params-file', str(path)])
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert lines[0].startswith(f'inertia_estimator: error: --params-file {path}: ')
    assert expected in lines[0] and "Couldn't parse" not in lines[0]


def test_params_file_check_accepts_what_rcl_accepts(tmp_path):
    """Empty files, empty mappings, wildcards and namespaces pass the check (rcl reads them);
    only the --ros-args section counts."""
    texts = ['', '{}\n', 'node: {}\n', '/**:\n  ros__parameters:\n    a: 1\n',
             'ns:\n  node:\n    ros__parameters:\n      a: [1, 2]\n']
    for k, text in enumerate(texts):
        p = tmp_path / f'p{k}.yaml'
        p.write_text(text)
        assert params_file_problem(['--ros-args', '--params-file', str(p)]) == '', text
    assert params_file_problem(['--params-file', '/no/such', '--ros-args', '--', 'x']) == ''
    assert 'not a regular file' in params_file_problem(['--ros-args', '--params-file',
                                                        str(tmp_path)])
