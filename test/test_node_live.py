"""The live estimator as a robot team runs it (issue 15 items 3-4, issue 16 item 5).

Most tests feed the node class in process: serialised messages go through the same path as
the polled subscriptions (``_accept``: decode, frame/NaN/stamp checks) and the update
(``_update``: estimator, publishers), without DDS, so that 20 seeds stay fast.  Published
messages are read back by a listener node where the topic itself is under test.
"""
from __future__ import annotations

import os
import time
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import ROOT

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from inertia_ros.core.inertia import THETA_NAMES  # noqa: E402
from inertia_ros.core.scene import Scene  # noqa: E402
from inertia_ros.core.simulation import simulate  # noqa: E402
from inertia_ros.io.scene_file import load_scene  # noqa: E402
from inertia_ros.nodes import diagnostics, messages  # noqa: E402
from inertia_ros.nodes import estimator as en  # noqa: E402

pytestmark = pytest.mark.ros

DOMAIN_ID = 1 + (os.getpid() + 73) % 110
EPOCH_NS = 1_700_000_000_000_000_000


@pytest.fixture(scope='module')
def context():
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN_ID)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def node(context):
    made = []

    def make(**overrides):
        n = en.InertiaEstimatorNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items()])
        made.append(n)
        return n
    yield make
    for n in made:
        n.destroy_node()


def scene(name: str, duration: float, **changes) -> Scene:
    d = dict(load_scene(ROOT / 'config' / 'scenes' / name).source, duration=duration)
    d.update(changes)
    return Scene.from_dict(d)


def gyro_payloads(t_ns, omega, frame='base_link'):
    return [serialize_message(messages.imu_msg(int(t), w, frame))
            for t, w in zip(t_ns, omega, strict=True)]


def torque_payloads(t_ns, tau, frame='base_link'):
    return [serialize_message(messages.wrench_msg(int(t), v, frame))
            for t, v in zip(t_ns, tau, strict=True)]


def feed(n, sim, torque=True, chunk=0.05):
    """Feed a SimResult to the node in ``chunk``-second batches, as the poll timer would."""
    tg = EPOCH_NS + np.round(sim.t_gyro * 1e9).astype(np.int64)
    tt = EPOCH_NS + np.round(sim.t_torque * 1e9).astype(np.int64)
    end = float(max(sim.t_gyro[-1], sim.t_torque[-1] if sim.t_torque.size else 0.0))
    for t0 in np.arange(0.0, end + chunk, chunk):
        g = (sim.t_gyro >= t0) & (sim.t_gyro < t0 + chunk)
        if g.any():
            n._accept(n._gyro, gyro_payloads(tg[g], sim.omega[g]))
        if torque:
            k = (sim.t_torque >= t0) & (sim.t_torque < t0 + chunk)
            if k.any():
                n._accept(n._torque, torque_payloads(tt[k], sim.torque[k]))
    n._update(time.monotonic())
    return n._last_estimate


# --------------------------------------------------------------------------- torque-free
def test_torque_free_ratios_within_3_sigma_in_19_of_20_seeds(node):
    """``torque_topic: none``: scale_unobservable with principal ratios inside 3 sigma."""
    inside = 0
    for seed in range(20):
        sim = simulate(scene('torque_free.yaml', 20.0), seed=seed)
        n = node(torque_topic='none')
        est = feed(n, sim, torque=False)
        assert est.status == 'scale_unobservable', est.diagnostics.get('reason')
        assert est.principal_axes is not None
        truth = np.linalg.eigvalsh(sim.inertia) / np.trace(sim.inertia)
        r = np.asarray(est.diagnostics['principal_ratios'])
        sd = np.asarray(est.diagnostics['principal_ratios_std'])
        assert np.all(sd > 0) and np.all(sd < 0.05), sd
        inside += bool(np.all(np.abs(r - truth) <= 3 * sd))
        n.destroy_node()
    assert inside >= 19, inside


def test_torque_free_without_none_until_torque_arrives(node):
    """A torque topic that stays silent: ratios and axes from the gyro alone, with the reason;
    the first torque message switches back to the full estimate."""
    sim = simulate(scene('torque_free.yaml', 15.0), seed=3)
    n = node()
    est = feed(n, sim, torque=False)
    assert est.status == 'scale_unobservable'
    assert 'no torque message on /torque yet' in est.diagnostics['reason']
    n._accept(n._torque, torque_payloads([EPOCH_NS + 10**9], [[0.0, 0.0, 0.0]]))
    n._accept(n._gyro, gyro_payloads([EPOCH_NS + 16 * 10**9], [sim.omega[-1]]))
    n._update(time.monotonic())
    assert n._shadow is None


def test_torque_free_publishes_ratios_axes_and_sigmas(node, context):
    """The ratios, their sigmas and the axes reach a subscriber; ~/inertia stays silent."""
    got: dict[str, list] = {'ratios': [], 'ratios_std': [], 'inertia': []}
    listener = Node('ratio_listener', context=context)
    for key in ('ratios', 'ratios_std'):
        listener.create_subscription(Vector3Stamped, f'/inertia_estimator/principal_{key}',
                                     got[key].append, 10)
    n = node(torque_topic='none')
    exe = SingleThreadedExecutor(context=context)
    exe.add_node(listener)
    exe.add_node(n)
    end = time.monotonic() + 5.0
    while time.monotonic() < end and listener.count_publishers(
            '/inertia_estimator/principal_ratios') == 0:
        exe.spin_once(timeout_sec=0.01)
    sim = simulate(scene('torque_free.yaml', 15.0), seed=1)
    est = feed(n, sim, torque=False)
    end = time.monotonic() + 5.0
    while time.monotonic() < end and not (got['ratios'] and got['ratios_std']):
        exe.spin_once(timeout_sec=0.01)
    exe.shutdown()
    listener.destroy_node()
    r = got['ratios'][-1].vector
    np.testing.assert_allclose([r.x, r.y, r.z], est.diagnostics['principal_ratios'])
    s = got['ratios_std'][-1].vector
    np.testing.assert_allclose([s.x, s.y, s.z], est.diagnostics['principal_ratios_std'])
    status = n.counts()
    assert status['torque_received'] == 0
    st = diagnostics.diagnostic_status(est.to_dict(), name='x')
    assert st.level == DiagnosticStatus.WARN and 'scale_unobservable' in st.message


# --------------------------------------------------------------------------- uncertainty
def test_covariance_and_principal_std_messages(node, context):
    """~/inertia_covariance: 6x6, labelled, matches the estimate; principal moment sigmas."""
    got: dict[str, list] = {'cov': [], 'std': []}
    listener = Node('cov_listener', context=context)
    listener.create_subscription(Float64MultiArray, '/inertia_estimator/inertia_covariance',
                                 got['cov'].append, 10)
    listener.create_subscription(Vector3Stamped, '/inertia_estimator/principal_moments_std',
                                 got['std'].append, 10)
    n = node()
    exe = SingleThreadedExecutor(context=context)
    exe.add_node(listener)
    exe.add_node(n)
    end = time.monotonic() + 5.0
    while time.monotonic() < end and listener.count_publishers(
            '/inertia_estimator/inertia_covariance') == 0:
        exe.spin_once(timeout_sec=0.01)
    sim = simulate(scene('default.yaml', 20.0), seed=2)
    est = feed(n, sim)
    assert est.status == 'ok'
    end = time.monotonic() + 5.0
    while time.monotonic() < end and not (got['cov'] and got['std']):
        exe.spin_once(timeout_sec=0.01)
    exe.shutdown()
    listener.destroy_node()
    msg = got['cov'][-1]
    labels = [d.label for d in msg.layout.dim]
    assert [d.size for d in msg.layout.dim] == [6, 6]
    assert all(' '.join(THETA_NAMES) in lb and '[kg^2 m^4]' in lb for lb in labels)
    cov, full = messages.covariance_from_msg(msg)
    expected, expected_full = messages.estimate_covariance(est)
    assert full == expected_full
    np.testing.assert_allclose(cov, expected)
    np.testing.assert_allclose(cov, cov.T)
    std = np.asarray(est.inertia_std)
    theta_std = np.array([std[0, 0], std[1, 1], std[2, 2], std[0, 1], std[0, 2], std[1, 2]])
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), theta_std, rtol=1e-9)
    v = got['std'][-1].vector
    np.testing.assert_allclose([v.x, v.y, v.z], est.diagnostics['principal_moments_std'])


def test_estimate_covariance_prefers_the_full_matrix():
    """est.covariance first, then diagnostics['covariance'], else the diagonal (labelled)."""
    from inertia_ros.core.estimation.result import InertiaEstimate

    std = np.diag([0.1, 0.2, 0.3])
    est = InertiaEstimate('ok', inertia=np.eye(3), inertia_std=std)
    cov, full = messages.estimate_covariance(est)
    assert not full and np.allclose(np.diag(cov)[:3], [0.01, 0.04, 0.09])
    assert messages.covariance_msg(cov, full).layout.dim[0].label.startswith('diagonal only')
    c = np.eye(6) * 2.0
    est.diagnostics['covariance'] = c
    assert messages.estimate_covariance(est)[1] and messages.estimate_covariance(est)[0][0, 0] == 2
    # the core's own field, when it has one
    core = SimpleNamespace(covariance=np.eye(6) * 3.0, diagnostics=est.diagnostics,
                           inertia_std=std)
    assert messages.estimate_covariance(core)[0][0, 0] == 3
    with pytest.raises(ValueError, match='shape'):
        messages.covariance_msg(np.eye(3))


def test_status_changes_are_logged_once_each(node, monkeypatch):
    """One console line per status change, none while it stays the same."""
    n = node()
    lines: list[str] = []
    logger = n.get_logger()
    monkeypatch.setattr(type(logger), 'info', lambda self, msg, **kw: lines.append(msg))
    sim = simulate(scene('default.yaml', 6.0), seed=4)
    feed(n, sim)
    feed(n, simulate(scene('default.yaml', 6.0), seed=4))   # same data again: out of order
    changes = [ln for ln in lines if ln.startswith('status ')]
    assert len(changes) == 1 and changes[0].startswith('status start -> ok'), lines


def test_no_error_level_at_start_or_reset(node):
    """A start and a reset are insufficient_data at WARN with the reason, never ERROR."""
    for status in ('insufficient_data', 'scale_unobservable', 'insufficient_excitation',
                   'partially_identifiable', 'model_mismatch'):
        assert diagnostics.DIAGNOSTIC_LEVELS[status] == DiagnosticStatus.WARN
    n = node()
    st = diagnostics.diagnostic_status(None, name='x', problems=n._problems(time.monotonic()))
    assert st.level == DiagnosticStatus.WARN and 'no samples yet' in st.message
    n._reset('~/reset service')
    assert n._problems(time.monotonic()) == []


# --------------------------------------------------------------------------- bad stamps
def test_zero_and_far_stamps_are_refused_not_a_reset(node):
    """One zero stamp, one a day ahead and one a day behind: refused, counted, no reset."""
    sim = simulate(scene('default.yaml', 10.0), seed=5)
    n = node()
    feed(n, sim)
    before = n._last_estimate
    assert before.status == 'ok'
    last = int(EPOCH_NS + sim.t_gyro[-1] * 1e9)
    day = 86_400 * 10**9
    w = sim.omega[-1]
    n._accept(n._gyro, gyro_payloads([0, last + day, last - day], [w, w, w]))
    n._accept(n._gyro, gyro_payloads([last + 5 * 10**6, last + 10 * 10**6], [w, w]))
    c = n.counts()
    assert c['resets'] == 0 and c['gyro_bad_stamp_refused'] == 3, c
    assert n._gyro.last_ns == last + 10 * 10**6
    n._update(time.monotonic())
    assert n._last_estimate.status == 'ok'
    assert n._last_estimate.samples_used >= before.samples_used


def test_a_confirmed_forward_jump_is_a_gap(node):
    n = node()
    w = [0.1, 0.2, 0.3]
    first = [EPOCH_NS + k * 5 * 10**6 for k in range(10)]
    later = [EPOCH_NS + 10 * 10**9 + k * 5 * 10**6 for k in range(en.STAMP_CONFIRM + 2)]
    n._accept(n._gyro, gyro_payloads(first, [w] * len(first)))
    for t in later:   # one message per poll, as at 200 Hz
        n._accept(n._gyro, gyro_payloads([t], [w]))
    c = n.counts()
    assert c['resets'] == 0 and c['gyro_bad_stamp_refused'] == 0
    assert n._gyro.last_ns == later[-1]
    kept = np.concatenate(n._gyro.t_ns)
    assert kept.size == len(first) + len(later)


def test_high_refused_fraction_warns_with_the_reason(node):
    """A 50 % NaN stream: WARN naming the stream, the fraction and the causes."""
    n = node()
    t = EPOCH_NS + np.arange(200) * 5 * 10**6
    w = np.tile([0.1, 0.2, 0.3], (200, 1))
    w[::2] = np.nan
    for k in range(0, 200, 10):
        n._accept(n._gyro, gyro_payloads(t[k:k + 10], w[k:k + 10]))
    problems = n._problems(time.monotonic())
    warn = [m for lvl, m in problems if lvl == DiagnosticStatus.WARN and 'refused' in m]
    assert len(warn) == 1 and warn[0].startswith('gyro: 50 % of 200 samples refused'), problems
    assert '100 NaN/Inf' in warn[0]
    # a clean stream stays quiet
    m = node()
    m._accept(m._gyro, gyro_payloads(t[:50], np.tile([0.1, 0.2, 0.3], (50, 1))))
    assert not [p for p in m._problems(time.monotonic()) if 'refused' in p[1]]


def test_clean_streams_stay_on_the_fast_path(node, monkeypatch):
    """Ordinary stamps never reach the per-sample stamp check (the node's speed)."""
    n = node()
    calls = []
    monkeypatch.setattr(n._admission, '_check_stamps', lambda *a: calls.append(a))
    sim = simulate(scene('default.yaml', 3.0), seed=6)
    feed(n, sim)
    assert calls == []



# --------------------------------------------------------------------------- start order
def _start_order_run(tmp_path, estimator_first: bool, delay: float) -> tuple[dict, str]:
    """Simulator and estimator as processes, one started ``delay`` s after the other, with
    the defaults (the simulator waits for matched subscriptions).  Returns the estimator's
    final counts (from /diagnostics) and the simulator's log."""
    import subprocess
    import sys

    import yaml
    from diagnostic_msgs.msg import DiagnosticArray

    from inertia_ros.cli.demo import stop_processes

    sc = tmp_path / 'short.yaml'
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'default.yaml').source, duration=4.0)
    sc.write_text(yaml.safe_dump(d))
    domain = DOMAIN_ID + 110
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED='1',
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''))
    est_cmd = [sys.executable, '-m', 'inertia_ros.inertia_estimator_node']
    sim_cmd = [sys.executable, '-m', 'inertia_ros.scene_simulator_node', '--ros-args',
               '-p', f'scene:={sc}', '-p', 'rate:=2.0', '-p', 'exit_on_end:=true']
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain)
    latest: dict = {}
    procs, logs = [], []
    try:
        listener = Node('order_listener', context=ctx)
        listener.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda m: latest.update({kv.key: kv.value for s in m.status
                                     if s.name.startswith('inertia_estimator')
                                     for kv in s.values}),
            10)
        exe = SingleThreadedExecutor(context=ctx)
        exe.add_node(listener)
        first, second = (est_cmd, sim_cmd) if estimator_first else (sim_cmd, est_cmd)
        names = ('est', 'sim') if estimator_first else ('sim', 'est')
        for k, (cmd, name) in enumerate(((first, names[0]), (second, names[1]))):
            logs.append(open(tmp_path / f'{name}.log', 'w'))
            procs.append(subprocess.Popen(cmd, env=env, stdout=logs[-1],
                                          stderr=subprocess.STDOUT))
            if k == 0:
                end = time.monotonic() + delay
                while time.monotonic() < end:
                    exe.spin_once(timeout_sec=0.05)
        sim = procs[names.index('sim')]
        end = time.monotonic() + 60.0
        while time.monotonic() < end and sim.poll() is None:
            exe.spin_once(timeout_sec=0.05)
        latest.clear()
        end = time.monotonic() + 5.0        # the estimator's next diagnostics (1 Hz)
        while time.monotonic() < end and not latest:
            exe.spin_once(timeout_sec=0.05)
        exe.shutdown()
        listener.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        stop_processes(procs)
        for log in logs:
            log.close()
    return latest, (tmp_path / 'sim.log').read_text() + (tmp_path / 'est.log').read_text()


@pytest.mark.slow
@pytest.mark.parametrize('estimator_first, delay', [(True, 1.0), (False, 3.0), (False, 0.0)])
def test_no_sample_lost_in_either_start_order(tmp_path, estimator_first, delay):
    """Either process first: 0 samples lost after the first 100 ms of data.

    4 s of the default scene at rate 2: 801 gyro (200 Hz) and 201 torque (50 Hz) messages;
    the first 100 ms hold 20 gyro and 5 torque samples, the only ones allowed to be lost
    (the bound by counts: at most that many fewer received than published).
    """
    import re

    counts, log = _start_order_run(tmp_path, estimator_first, delay)
    m = re.search(r'published (\d+) gyro and (\d+) torque messages', log)
    assert m and counts, log[-3000:]
    sent = (int(m.group(1)), int(m.group(2)))
    got = (int(counts['gyro_received']), int(counts['torque_received']))
    assert sent[0] - got[0] <= 20 and sent[1] - got[1] <= 5, (sent, got, log[-3000:])
    assert 'Traceback' not in log
