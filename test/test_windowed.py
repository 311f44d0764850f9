"""Online estimators behind one interface: BatchWindow (sliding batch) and RecursiveEstimator."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from inertia_ros.core.estimation.batch import estimate
from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.windowed import ONLINE_METHODS, BatchWindow, OnlineEstimator
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate
from inertia_ros.io.scene_file import load_scene


@pytest.fixture(scope='module')
def sim():
    """20 s of the default scene (seed 2)."""
    d = dict(load_scene(ROOT / 'config' / 'scenes' / 'default.yaml').source, duration=20.0)
    return simulate(Scene.from_dict(d), seed=2)


def _feed(est, sim, block=1.0):
    """Feed both streams in ``block``-second pieces, gyro and torque interleaved."""
    for t0 in np.arange(0.0, sim.t_gyro[-1] + block, block):
        g = (sim.t_gyro >= t0) & (sim.t_gyro < t0 + block)
        q = (sim.t_torque >= t0) & (sim.t_torque < t0 + block)
        if g.any():
            est.add_gyro(sim.t_gyro[g], sim.omega[g])
        if q.any():
            est.add_torque(sim.t_torque[q], sim.torque[q])


def test_both_online_estimators_satisfy_the_protocol():
    """RecursiveEstimator and BatchWindow are OnlineEstimators; ONLINE_METHODS names them."""
    assert ONLINE_METHODS == ('recursive', 'batch')
    assert isinstance(RecursiveEstimator(), OnlineEstimator)
    assert isinstance(BatchWindow(10.0), OnlineEstimator)


def test_window_solves_the_newest_window_exactly_as_batch(sim):
    """estimate() equals the batch estimate() of the samples in [t_end - window, t_end]."""
    win = BatchWindow(8.0, method='integral', model='full', torque_bias='off')
    _feed(win, sim)
    got = win.estimate()
    t_end = max(sim.t_gyro[-1], sim.t_torque[-1])
    g, q = sim.t_gyro >= t_end - 8.0, sim.t_torque >= t_end - 8.0
    ref = estimate(sim.t_gyro[g], sim.omega[g], sim.t_torque[q], sim.torque[q],
                   method='integral', model='full', torque_bias='off')
    assert got.status == ref.status == 'ok'
    np.testing.assert_array_equal(got.inertia, ref.inertia)
    assert got.to_dict()['samples'] == ref.to_dict()['samples']
    # 8 s of the nominal scene: within 2% of the largest moment (tolerance of the node test)
    assert np.max(np.abs(got.inertia - sim.inertia)) < 0.02 * np.linalg.eigvalsh(sim.inertia)[-1]


def test_window_reset_forgets_and_then_too_little_data_raises(sim):
    """After reset() the window is empty: the batch estimator refuses, naming the problem."""
    win = BatchWindow(5.0)
    _feed(win, sim)
    win.reset()
    with pytest.raises(ValueError):
        win.estimate()


@pytest.mark.parametrize('kwargs, match', [
    ({'window': 0.0}, 'window: must be a positive'),
    ({'window': float('nan')}, 'window: must be a positive'),
    ({'method': 'recursive'}, 'method: must be one of'),
    ({'model': 'octagonal'}, 'model: must be one of'),
    ({'torque_bias': 'maybe'}, 'torque_bias: must be one of'),
    ({'hold': 'cubic'}, 'hold: must be one of'),
    ({'model': 'axisymmetric'}, "symmetry_axis: required for model='axisymmetric'"),
])
def test_window_rejects_bad_options(kwargs, match):
    """Every option is checked at construction against the one vocabulary (options)."""
    args = {'window': 10.0, **kwargs}
    with pytest.raises(ValueError, match=match):
        BatchWindow(args.pop('window'), **args)


def test_batch_window_takes_wheels_through_the_batch_momentum_estimator() -> None:
    """Issue 26: ``BatchWindow(momentum=True)`` takes the wheels' momentum blocks (as the
    recursive momentum estimator does) and each re-solve is the batch
    ``estimate_with_momentum`` on the newest ``window`` seconds of every stream: the same
    numbers (rtol 1e-12) for a 6 s window of a 10 s wheels-only record, status ok, |z| < 4.
    Misuse is one line.  On f0eb6ad the window refused wheels and rotors."""
    from test_wheels import THETA_IDX, scene_dict

    from inertia_ros.core.estimation.momentum import (
        Wheel,
        estimate_with_momentum,
        wheel_inputs,
    )

    sc = Scene.from_dict(scene_dict(duration=10.0, gyro_rate=100.0))
    r = simulate(sc, 1)
    ws = [Wheel(w.joint, w.axis, w.inertia) for w in sc.wheels.wheels]
    win = BatchWindow(6.0, momentum=True, other_torque=False, model='full',
                      torque_bias='off')
    for t0 in np.arange(0.0, 10.5, 0.5):
        g = (r.t_gyro >= t0) & (r.t_gyro < t0 + 0.5)
        k = (r.t_wheel >= t0) & (r.t_wheel < t0 + 0.5)
        win.add_gyro(r.t_gyro[g], r.omega[g])
        if k.any():
            win.add_momentum(wheel_inputs(r.t_wheel[k], r.wheel_speed[k], ws))
    e = win.estimate()
    t_min = max(r.t_gyro[-1], r.t_wheel[-1]) - 6.0
    g, k = r.t_gyro >= t_min, r.t_wheel >= t_min
    b = estimate_with_momentum(r.t_gyro[g], r.omega[g], [], np.zeros((0, 3)),
                               wheel_inputs(r.t_wheel[k], r.wheel_speed[k], ws),
                               method='integral', model='full', torque_bias='off')
    assert e.status == b.status == 'ok', (e.status, b.status)
    np.testing.assert_allclose(e.theta, b.theta, rtol=1e-12)
    np.testing.assert_allclose(e.theta_std, b.theta_std, rtol=1e-12)
    z = (e.theta - r.inertia[THETA_IDX]) / e.theta_std
    assert np.all(np.abs(z) < 4), z
    with pytest.raises(ValueError, match='other_torque=False'):
        win.add_torque([11.0], [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match='momentum=True'):
        BatchWindow(6.0).add_momentum(wheel_inputs(r.t_wheel[:2], r.wheel_speed[:2], ws))
    with pytest.raises(ValueError, match="^window mode, wheels input: nuisance terms"):
        BatchWindow(6.0, momentum=True, other_torque=False, nuisance='auto')
