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
