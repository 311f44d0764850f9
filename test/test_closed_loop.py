"""Closed-loop simulation core (issue 28 part 2): a body driven by commands step by step."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core.closed_loop import ClosedLoopBody
from inertia_ros.core.exciter_rules import TorqueSchedule
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene


def scene(name: str = 'default.yaml', **changes) -> Scene:
    d = dict(load_scene(ROOT / 'config' / 'scenes' / name).source)
    d.update(changes)
    return Scene.from_dict(d)


def drive(body: ClosedLoopBody, sched: TorqueSchedule, rate: float, seed: int = 1):
    """Advance in random steps shorter than one command period, commanding the plan's
    value for the next command instant (what a controller one step ahead does)."""
    rng = np.random.default_rng(seed)
    t, parts = 0.0, []
    while not body.finished:
        t2 = t + rng.uniform(0.001, 0.975 / rate)
        parts.append(body.advance(t2, sched.at(np.ceil(t * rate - 1e-9) / rate)))
        t = t2
    return {k: np.concatenate([getattr(p, k) for p in parts])
            for k in ('t_gyro', 'omega', 'omega_true', 't_torque', 'torque')}


@pytest.mark.parametrize('name, changes', [
    ('default.yaml', {'duration': 20.0}),
    ('payload_change.yaml', {}),
    ('damping.yaml', {'duration': 15.0}),
])
def test_fed_the_scene_profile_it_reproduces_the_open_loop_run(name, changes):
    """Same body, same command grid: the true rates agree with simulate() to 1e-9 rad/s,
    the gyro stamps exactly, and the gyro noise has the scene's sigma (10 %)."""
    sc = scene(name, **changes)
    sim = simulate(sc)
    got = drive(ClosedLoopBody(sc), TorqueSchedule.from_scene(sc), sc.command_rate)
    np.testing.assert_array_equal(got['t_gyro'], np.arange(sim.t_gyro.size) / sc.gyro.rate)
    np.testing.assert_allclose(got['omega_true'], sim.omega_true, rtol=0, atol=1e-9)
    if sc.gyro.noise_std > 0 and sc.gyro.lsb == 0 and sc.gyro.time_constant == 0:
        resid = got['omega'] - got['omega_true'] - np.asarray(sc.gyro.bias)
        assert resid.std() == pytest.approx(sc.gyro.noise_std, rel=0.1)
    np.testing.assert_allclose(got['t_torque'], np.arange(got['t_torque'].size)
                               / sc.torque_sensor.rate, atol=1e-12)
    assert got['t_torque'].size == sim.t_torque.size


def test_a_command_is_applied_from_the_next_command_instant():
    """Zero torque, then 0.1 N m about x sent at t = 0.105 s: the body (Ixx 1, no spin)
    accelerates from 0.12 s (the 50 Hz grid), and the torque sensor reads it from there."""
    sc = scene(duration=1.0, initial_omega=[0.0, 0.0, 0.0],
               body={'inertia': [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]},
               gyro={'rate': 200.0, 'noise_std': 0.0},
               torque_sensor={'rate': 50.0, 'noise_rel': 0.0, 'noise_std': 0.0})
    body = ClosedLoopBody(sc)
    body.advance(0.105, np.zeros(3))
    got = body.advance(1.0, np.array([0.1, 0.0, 0.0]))
    w_end = got.omega_true[-1, 0]
    assert w_end == pytest.approx(0.1 * (1.0 - 0.12), abs=1e-9)
    assert np.all(got.torque[got.t_torque < 0.12 - 1e-9] == 0.0)
    np.testing.assert_allclose(got.torque[got.t_torque >= 0.12 - 1e-9], [[0.1, 0, 0]] *
                               int(np.sum(got.t_torque >= 0.12 - 1e-9)), atol=1e-15)
    assert body.finished and body.advance(2.0, np.zeros(3)).t_gyro.size == 0


def test_refuses_actuator_scenes_and_bad_commands_in_one_line():
    with pytest.raises(ValueError, match='wheels or rotors') as err:
        ClosedLoopBody(load_scene(ROOT / 'config' / 'scenes' / 'wheels.yaml'))
    assert '\n' not in str(err.value)
    body = ClosedLoopBody(scene(duration=1.0))
    with pytest.raises(ValueError, match='finite'):
        body.advance(0.5, np.array([np.nan, 0.0, 0.0]))
