"""Simulation: rigid-body dynamics accuracy, conservation laws, sensors, imperfections, seeds."""
from __future__ import annotations

import copy

import numpy as np
import pytest

pytest.importorskip('hypothesis')  # optional test dependency
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from conftest import ROOT
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import SimResult, command_grid, integrate_rigid_body, simulate
from inertia_ros.io.scene_file import load_scene

NOMINAL = {
    'name': 'nominal', 'seed': 7, 'duration': 60.0,
    'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
    'initial_omega': [0.05, -0.03, 0.02],
    'torque': [{'type': 'multisine', 'amplitude': 0.1}],
    'gyro': {'rate': 200.0, 'noise_std': 0.002},
    'torque_sensor': {'rate': 50.0, 'noise_rel': 0.02},
}


def _scene(**changes) -> Scene:
    d = copy.deepcopy(NOMINAL)
    d.update(changes)
    return Scene.from_dict(d)


def _clean(**changes) -> Scene:
    """Nominal scene without any sensor noise."""
    return _scene(gyro={'rate': 200.0}, torque_sensor={'rate': 50.0}, **changes)


def _inertial_momentum(res: SimResult, inertia: np.ndarray) -> np.ndarray:
    R = Rotation.from_quat(res.attitude_true).as_matrix()        # [x, y, z, w], body->inertial
    return np.einsum('nij,jk,nk->ni', R, inertia, res.omega_true)


def _theta_matrix(th):
    return np.array([[th[0], th[3], th[4]], [th[3], th[1], th[5]], [th[4], th[5], th[2]]])


# --------------------------------------------------------------------------- dynamics
@pytest.mark.parametrize(('theta', 'omega0'), [
    ([1.0, 1.2, 0.9, 0.05, -0.03, 0.02], [0.5, -0.3, 0.8]),
    ([0.02, 0.023, 0.015, 4e-4, -3e-4, 2e-4], [2.0, -1.0, 1.5]),   # fast tumble
])
def test_torque_free_energy_and_inertial_momentum_conserved(theta, omega0):
    """Torque-free for 60 s: energy and the inertial angular momentum vector to 1e-9 rel."""
    s = Scene.from_dict({'duration': 60.0, 'body': {'inertia': theta},
                         'initial_omega': omega0, 'gyro': {'rate': 200.0}})
    r = simulate(s)
    I = r.inertia
    energy = 0.5 * np.einsum('ni,ij,nj->n', r.omega_true, I, r.omega_true)
    np.testing.assert_allclose(energy, energy[0], rtol=1e-9, atol=0)
    L = _inertial_momentum(r, I)
    err = np.linalg.norm(L - L[0], axis=1).max() / np.linalg.norm(L[0])
    assert err < 1e-9
    assert np.abs(r.omega_true - r.omega_true[0]).max() > 0.1 * np.abs(omega0).max(), \
        'the spin must actually wander (not a principal-axis spin)'


@pytest.mark.parametrize(('axis', 'flips'), [(0, False), (1, True), (2, False)])
def test_intermediate_axis_instability(axis, flips):
    """A spin about the intermediate axis flips over; about the minor or major axis it stays."""
    omega0 = np.full(3, 1e-3)
    omega0[axis] = 1.0
    s = Scene.from_dict({'duration': 60.0, 'body': {'inertia': [1.0, 2.0, 2.5, 0, 0, 0]},
                         'initial_omega': omega0.tolist(), 'gyro': {'rate': 100.0}})
    w = simulate(s).omega_true[:, axis]
    if flips:
        assert w.min() < -0.9, 'the intermediate-axis spin reverses'
    else:
        assert w.min() > 0.99, 'a spin about a minor or major axis is stable'


def test_matches_independent_high_order_integrator():
    """Piecewise ZOH torque: omega matches scipy DOP853 (rtol 1e-12) to 1e-11 rad/s."""
    s = _clean(duration=4.0, disturbance=[0.01, -0.02, 0.005])
    r = simulate(s)
    I = r.inertia
    Ii = np.linalg.inv(I)
    cmd = r.torque_command                      # torque sensor at the command rate
    np.testing.assert_allclose(r.t_torque, command_grid(s), rtol=0, atol=1e-12)

    def f(_t, x, tau):
        w = x[:3]
        return Ii @ (tau - np.cross(w, I @ w))

    x = np.array(s.initial_omega, dtype=float)
    out = [x]
    t_g = np.arange(0, 801) / 200.0
    for k in range(t_g.size - 1):
        j = int(np.floor(t_g[k] * 50.0 + 1e-6))
        tau = cmd[j] + s.disturbance
        sol = solve_ivp(f, (t_g[k], t_g[k + 1]), x, method='DOP853', rtol=1e-12,
                        atol=1e-15, args=(tau,))
        x = sol.y[:, -1]
        out.append(x)
    np.testing.assert_allclose(r.omega_true, np.array(out), rtol=0, atol=1e-11)


def test_data_satisfy_the_integral_form_of_eulers_equations():
    """Noise-free streams satisfy I dw + int(w x Iw) = int(tau + d), disturbance included."""
    d = np.array([0.006, -0.008, 0.007])
    s = _clean(disturbance=d.tolist())
    r = simulate(s)
    I, w, t = r.inertia, r.omega_true, r.t_gyro
    k = np.searchsorted(r.t_torque, t, side='right') - 1
    tau = r.torque[k] + d                       # ZOH: exact between samples
    c = np.cross(w, w @ I)
    # Simpson over pairs of 5 ms steps (the torque changes only every 20 ms)
    for a in range(0, 11000, 1000):
        b = a + 1000
        integ_c = (t[1] - t[0]) / 3 * (c[a] + 4 * c[a + 1:b:2].sum(0) + 2 * c[a + 2:b:2].sum(0)
                                       + c[b])
        lhs = I @ (w[b] - w[a]) + integ_c
        rhs = tau[a:b].sum(0) * (t[1] - t[0])
        np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-9)


def test_nominal_result_shapes_and_times():
    """SimResult arrays have the documented shapes; times start at 0 s."""
    r = simulate(_scene())
    assert r.t_gyro.shape == (12001,) and r.omega.shape == (12001, 3)
    assert r.omega_true.shape == (12001, 3) and r.attitude_true.shape == (12001, 4)
    assert r.t_torque.shape == (3001,) and r.torque.shape == (3001, 3)
    assert r.torque_command.shape == (3001, 3)
    assert r.t_gyro[0] == 0.0 and r.t_torque[0] == 0.0
    assert r.t_gyro[-1] == pytest.approx(60.0, abs=1e-12)
    assert r.inertia.shape == (3, 3) and r.inertia_changes == ()
    assert r.frame_id == 'base_link' and r.seed == 7
    np.testing.assert_allclose(r.attitude_true[0], [0, 0, 0, 1], rtol=0, atol=0)
    np.testing.assert_allclose(np.linalg.norm(r.attitude_true, axis=1), 1.0, rtol=1e-12)


# --------------------------------------------------------------------------- sensors
def test_gyro_noise_and_bias():
    """omega = truth + bias + white noise of the stated std (5 % rel on 36k draws)."""
    r = simulate(_scene(gyro={'rate': 200.0, 'noise_std': 0.002,
                              'bias': [0.01, -0.02, 0.003]}))
    e = r.omega - r.omega_true
    np.testing.assert_allclose(e.mean(axis=0), [0.01, -0.02, 0.003], rtol=0, atol=1e-4)
    np.testing.assert_allclose(e.std(axis=0), 0.002, rtol=0.05)
    assert abs(np.corrcoef(e[:, 0], e[:, 1])[0, 1]) < 0.05


def test_torque_is_held_command_plus_relative_noise():
    """Torque samples: the held command plus noise of std noise_std + noise_rel * rms(cmd)."""
    s = _scene(command_rate=50.0, torque_sensor={'rate': 200.0, 'noise_rel': 0.05,
                                                 'noise_std': 0.001})
    r = simulate(s)
    cmd = r.torque_command
    # 4 torque samples per command: the command is held (zero-order hold)
    blocks = cmd[:-1].reshape(-1, 4, 3)
    np.testing.assert_array_equal(blocks, np.broadcast_to(blocks[:, :1], blocks.shape))
    rms = np.sqrt(np.mean(cmd ** 2, axis=0))
    np.testing.assert_allclose((r.torque - cmd).std(axis=0), 0.001 + 0.05 * rms, rtol=0.05)


def test_disturbance_acts_but_is_not_measured():
    """The disturbance is reported as torque_bias_true and absent from the torque stream."""
    d = [0.01, 0.0, -0.01]
    a = simulate(_clean(disturbance=d))
    b = simulate(_clean())
    np.testing.assert_array_equal(a.torque, b.torque)
    np.testing.assert_array_equal(a.torque_bias_true, d)
    assert np.abs(a.omega_true - b.omega_true).max() > 0.1


def test_inertia_change_is_a_step_with_continuous_spin():
    """A payload change: reported, omega continuous, the new tensor drives the motion after."""
    new = [0.8, 0.95, 0.75, 0.03, -0.02, 0.015]
    s = Scene.from_dict({'duration': 20.0, 'body': NOMINAL['body'],
                         'initial_omega': [0.5, -0.3, 0.8], 'gyro': {'rate': 200.0},
                         'inertia_change': {'time': 10.0, 'inertia': new}})
    r = simulate(s)
    assert len(r.inertia_changes) == 1 and r.inertia_changes[0][0] == 10.0
    I1 = r.inertia_changes[0][1]
    np.testing.assert_allclose(I1, _theta_matrix(new), rtol=0, atol=0)
    w = r.omega_true
    i = 2000                                            # t = 10 s exactly
    assert np.linalg.norm(w[i + 1] - w[i]) < 0.02, 'omega is continuous'
    e_before = 0.5 * np.einsum('ni,ij,nj->n', w[:i + 1], r.inertia, w[:i + 1])
    e_after = 0.5 * np.einsum('ni,ij,nj->n', w[i:], I1, w[i:])
    np.testing.assert_allclose(e_before, e_before[0], rtol=1e-10)
    np.testing.assert_allclose(e_after, e_after[0], rtol=1e-10)
    assert abs(e_after[0] / e_before[-1] - 1.0) > 0.05, 'energy jumps with the tensor'


def test_imperfections_on_stamps_and_drops():
    """Jitter keeps stamps increasing; delay shifts the torque stamps; drops remove ~rate."""
    im = {'timestamp_jitter': 0.0, 'torque_delay': 0.012, 'drop_rate': 0.0}
    r = simulate(_scene(imperfections=im))
    np.testing.assert_allclose(r.t_torque, np.arange(3001) / 50.0 + 0.012, rtol=0, atol=1e-12)
    im = {'timestamp_jitter': 0.0005, 'torque_delay': 0.0, 'drop_rate': 0.1}
    r = simulate(_scene(imperfections=im))
    assert np.all(np.diff(r.t_gyro) > 0) and np.all(np.diff(r.t_torque) > 0)
    n = 12001
    assert abs(r.t_gyro.size - 0.9 * n) < 4 * np.sqrt(n * 0.09)       # 4-sigma binomial
    assert abs(r.t_torque.size - 0.9 * 3001) < 4 * np.sqrt(3001 * 0.09)
    jitter = r.t_gyro - np.round(r.t_gyro * 200.0) / 200.0
    np.testing.assert_allclose(jitter.std(), 0.0005, rtol=0.1)
    assert r.omega.shape[0] == r.omega_true.shape[0] == r.t_gyro.size


# --------------------------------------------------------------------------- seeds
def test_same_seed_same_result_other_seed_other_noise():
    """A seed reproduces everything bit for bit; another seed changes the noise only."""
    s = _scene(torque=[{'type': 'prbs', 'amplitude': 0.1}], duration=10.0)
    a, b, c = simulate(s), simulate(s), simulate(s, seed=8)
    for f in ('t_gyro', 'omega', 'omega_true', 't_torque', 'torque', 'torque_command'):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert c.seed == 8 and a.seed == 7
    assert np.abs(a.omega - c.omega).max() > 1e-4
    assert np.abs(a.torque_command - c.torque_command).max() > 1e-3, 'PRBS bits from the seed'


def test_noise_streams_are_independent_of_other_scene_parts():
    """Changing the gyro noise level leaves the torque noise draws unchanged (spawned RNGs)."""
    a = simulate(_scene(duration=5.0))
    b = simulate(_scene(duration=5.0, gyro={'rate': 200.0, 'noise_std': 0.01}))
    np.testing.assert_array_equal(a.torque, b.torque)
    np.testing.assert_allclose((b.omega - b.omega_true) / 0.01, (a.omega - a.omega_true) / 0.002,
                               rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize('seed', [-1, 1.5, True])
def test_simulate_rejects_bad_seed(seed):
    """simulate() names the seed argument when it is not a non-negative integer."""
    with pytest.raises(ValueError, match='seed: must be a non-negative integer'):
        simulate(_scene(duration=1.0), seed=seed)


def test_simulate_rejects_non_scene():
    """simulate() takes a Scene, not a dict."""
    with pytest.raises(ValueError, match='scene: expected a Scene'):
        simulate(NOMINAL)


@pytest.mark.parametrize(('args', 'pattern'), [
    (([0.0, 1.0, 0.5], np.zeros((2, 3)), np.eye(3), np.zeros(3)), 'strictly increasing'),
    (([0.0, 1.0], np.zeros((2, 3)), np.eye(3), np.zeros(3)), r'torque: expected shape \(1, 3\)'),
    (([0.0, 1.0], np.zeros((1, 3)), np.eye(2), np.zeros(3)), 'inertia: expected shape'),
    (([], np.zeros((0, 3)), np.eye(3), np.zeros(3)), 't_events: must be a non-empty'),
])
def test_integrate_rigid_body_validates(args, pattern):
    """integrate_rigid_body raises ValueError naming the bad argument."""
    with pytest.raises(ValueError, match=pattern):
        integrate_rigid_body(*args)


def test_shipped_bag_scenes_simulate_reproducibly():
    """The scenes behind bags/ simulate to the same first samples every time."""
    s = load_scene(ROOT / 'config' / 'scenes' / 'single_axis.yaml')
    a, b = simulate(s), simulate(s)
    np.testing.assert_array_equal(a.omega, b.omega)
    # single-axis: only z torque is commanded
    np.testing.assert_array_equal(a.torque_command[:, :2], 0.0)


@settings(max_examples=12, deadline=None, derandomize=True)
@given(moments=st.tuples(*[st.floats(0.5, 2.0)] * 3),
       angles=st.tuples(*[st.floats(-3.1, 3.1)] * 3),
       omega0=st.tuples(*[st.floats(-2.0, 2.0)] * 3))
def test_conservation_holds_for_any_physical_body(moments, angles, omega0):
    """Property: any physical tensor and spin (10 s torque-free) conserves E and L to 1e-9."""
    m = np.sort(moments)
    assume(m[0] + m[1] >= m[2] * 1.001)
    assume(np.linalg.norm(omega0) > 1e-3)
    R = Rotation.from_euler('xyz', angles).as_matrix()
    I = R @ np.diag(m) @ R.T
    s = Scene.from_dict({'duration': 10.0, 'body': {'inertia': I.tolist()},
                         'initial_omega': list(omega0), 'gyro': {'rate': 100.0}})
    r = simulate(s)
    energy = 0.5 * np.einsum('ni,ij,nj->n', r.omega_true, r.inertia, r.omega_true)
    np.testing.assert_allclose(energy, energy[0], rtol=1e-9, atol=0)
    L = _inertial_momentum(r, r.inertia)
    assert np.linalg.norm(L - L[0], axis=1).max() <= 1e-9 * np.linalg.norm(L[0])
