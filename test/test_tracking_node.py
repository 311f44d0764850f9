"""The node's ``method: tracking`` wiring (parameter table, estimator factory)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('rclpy')

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.estimation.tracking import TrackingEstimator
from inertia_ros.nodes import estimator, params

DEFAULTS = {name: spec.default for name, spec in params.ESTIMATOR.items()}


def test_method_tracking_is_a_choice() -> None:
    spec = params.ESTIMATOR['method']
    assert params.coerce('method', spec, 'tracking') == 'tracking'
    with pytest.raises(ValueError, match="parameter 'method' must be one of"):
        params.coerce('method', spec, 'kalman')
    assert 'tracking' in params.help_text('inertia_estimator')


def test_factory_builds_the_tracker_with_its_memory() -> None:
    est = estimator.make_estimator(dict(DEFAULTS, method='tracking'))()
    assert isinstance(est, TrackingEstimator)
    assert est.window == estimator.TRACKING_DEFAULT_WINDOW
    est = estimator.make_estimator(dict(DEFAULTS, method='tracking', window=30))()
    assert est.window == 30.0


def test_torque_free_tracking_uses_the_recursive_estimator() -> None:
    """Without torque the scale is unobservable: ratios and axes from the recursive core."""
    cfg = dict(DEFAULTS, method='tracking', torque_topic='none')
    assert isinstance(estimator.make_estimator(cfg)(), RecursiveEstimator)
    assert isinstance(estimator.torque_free_estimator(dict(DEFAULTS, method='tracking'))(),
                      RecursiveEstimator)


def test_bad_tracking_option_is_one_line() -> None:
    with pytest.raises(ValueError, match='symmetry_axis'):
        estimator.make_estimator(dict(DEFAULTS, method='tracking', model='axisymmetric'))


def test_tracker_fed_as_the_node_feeds_it() -> None:
    """10 ms blocks, estimate at 10 Hz: ok, tensor within 2 % and sigma finite."""
    rec = simulate_truth(TruthCase(duration=15.0), [4])[0]
    est = estimator.make_estimator(dict(DEFAULTS, method='tracking'))()
    ig = iq = 0
    res = None
    for k in range(1, 1500):
        t = 0.01 * k
        jg = int(np.searchsorted(rec.t_gyro, t, side='right'))
        jq = int(np.searchsorted(rec.t_torque, t, side='right'))
        if jg > ig:
            est.add_gyro(rec.t_gyro[ig:jg], rec.omega[ig:jg])
        if jq > iq:
            est.add_torque(rec.t_torque[iq:jq], rec.torque[iq:jq])
        ig, iq = jg, jq
        if k % 10 == 0:
            res = est.estimate()
    assert res.status == 'ok'
    assert np.linalg.norm(res.inertia - rec.inertia) / np.linalg.norm(rec.inertia) < 0.02
    assert np.all(np.isfinite(res.inertia_std))
