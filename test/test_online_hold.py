"""The online estimator's ``hold='auto'`` (issue 27, item 2): the batch rule, on the fly.

:class:`~inertia_ros.core.estimation.recursive.RecursiveEstimator` keeps both holds'
statistics on the same rows and decides by :func:`~inertia_ros.core.estimation.selection.
select_hold` (the higher likelihood: the lower residual excess of the two fits).  Records
from the independent RK4 simulator :mod:`inertia_ros.bench.truth_sim` with the default
scene (multisine of RMS 0.06 N m per axis, torque noise 2 % of it, 200 Hz gyro, 50 Hz
torque), the applied torque held between its samples (a command) or continuous between them.
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.recursive import RecursiveEstimator
from inertia_ros.core.inertia import matrix_to_theta

SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
#: The node's selection options (model and bias re-selected), hold by evidence.
OPTIONS = dict(model='auto', torque_bias='auto', hold='auto')


def _records(kind: str, seeds: range, duration: float = 20.0) -> list:
    return list(simulate_truth(SCENE.with_(torque_kind=kind, duration=duration), seeds))


def _online(rec, block: float | None = None, **kw):
    """The online estimate over the whole record (all at once, or in ``block``-second
    chunks of both streams, as a node receives them)."""
    r = RecursiveEstimator(**{**OPTIONS, **kw})
    if block is None:
        r.add_torque(rec.t_torque, rec.torque)
        r.add_gyro(rec.t_gyro, rec.omega)
        return r.estimate()
    edges = [*rec.t_gyro[::int(round(block / np.median(np.diff(rec.t_gyro))))], np.inf]
    for t0, t1 in zip(edges[:-1], edges[1:], strict=True):
        s = (rec.t_torque >= t0) & (rec.t_torque < t1)
        g = (rec.t_gyro >= t0) & (rec.t_gyro < t1)
        r.add_torque(rec.t_torque[s], rec.torque[s])
        r.add_gyro(rec.t_gyro[g], rec.omega[g])
        r.merge()
    return r.estimate()


@pytest.mark.parametrize('kind, chosen', [('continuous', 'linear'), ('zoh', 'zoh')])
def test_online_auto_hold_follows_the_torque(kind: str, chosen: str) -> None:
    """20 s records, seeds 0-2: continuous torque -> linear, held -> zoh, each by at least
    0.5 % of residual excess, status ok, max |z| < 4; the estimate equals the batch
    ``integral`` one with the same hold (and the same 10 s segments) within 0.1 sigma."""
    for rec in _records(kind, range(3)):
        e = _online(rec)
        sel = e.diagnostics['hold_selection']
        assert sel['chosen'] == chosen == e.diagnostics['hold'], sel
        assert sel['requested'] == 'auto' and sel['test'] == 'likelihood'
        assert abs(sel['statistic']) > 0.005 and (sel['statistic'] < 0) == (chosen == 'linear')
        assert e.status == 'ok', e.diagnostics.get('reason')
        z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
        assert np.max(np.abs(z)) < 4.0, z
        b = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque, method='integral',
                     hold=chosen, segment=10.0, model='auto', torque_bias='auto')
        assert b.model == e.model
        np.testing.assert_array_less(np.abs(e.theta - b.theta), 0.1 * b.theta_std)


def test_online_auto_hold_matches_a_fixed_hold_and_ignores_the_cut() -> None:
    """Continuous torque, seed 3: fed in 0.37 s chunks the choice and its statistic are those
    of one block (to 1e-6), and the tensor is the one of ``hold='linear'`` (to 1e-9 rel)."""
    rec = _records('continuous', range(3, 4))[0]
    whole, chunks = _online(rec), _online(rec, block=0.37)
    a, b = whole.diagnostics['hold_selection'], chunks.diagnostics['hold_selection']
    assert a['chosen'] == b['chosen'] == 'linear'
    assert b['statistic'] == pytest.approx(a['statistic'], rel=1e-6)
    fixed = _online(rec, hold='linear')
    np.testing.assert_allclose(whole.theta, fixed.theta, rtol=1e-9)
    assert 'hold_selection' not in fixed.diagnostics


def test_choice_reused_between_reselections() -> None:
    """With ``reselect_every=3`` the hold is chosen on the 1st and 4th estimate and reused
    (marked) on the 2nd and 3rd."""
    rec = _records('continuous', range(1))[0]
    r = RecursiveEstimator(**OPTIONS, reselect_every=3)
    records = []
    # fed progressively: each call adds the samples since the previous cut
    lo = -np.inf
    for t1 in (1.0, 12.0, 14.0, 20.0):
        s = (rec.t_torque >= lo) & (rec.t_torque < t1)
        g = (rec.t_gyro >= lo) & (rec.t_gyro < t1)
        r.add_torque(rec.t_torque[s], rec.torque[s])
        r.add_gyro(rec.t_gyro[g], rec.omega[g])
        records.append(r.estimate().diagnostics.get('hold_selection'))
        lo = t1
    first, second, third, fourth = records
    assert 'reused' not in first and first['selected_at_samples'] > 0, first
    assert second['reused'] and third['reused'] and second['chosen'] == first['chosen']
    assert second['selected_at_samples'] == first['selected_at_samples']
    assert 'reused' not in fourth and fourth['chosen'] == 'linear', fourth


def test_node_estimator_defaults_are_ok_on_continuous_torque() -> None:
    """The node's estimator with every parameter at its default (``hold: auto``), fed in
    0.1 s updates with ``refresh()`` after each: continuous torque, seeds 0-2, ends ok with
    linear and max |z| < 4 (the issue's "node, defaults" case)."""
    from inertia_ros.nodes import params
    from inertia_ros.nodes.selection import make_estimator

    cfg = {name: spec.default for name, spec in params.ESTIMATOR.items()}
    for rec in _records('continuous', range(3)):
        est = make_estimator(cfg)()
        edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1)
        gi = np.searchsorted(rec.t_gyro, edges, side='right')
        ti = np.searchsorted(rec.t_torque, edges, side='right')
        for k in range(1, len(edges)):
            est.add_torque(rec.t_torque[ti[k - 1]:ti[k]], rec.torque[ti[k - 1]:ti[k]])
            est.add_gyro(rec.t_gyro[gi[k - 1]:gi[k]], rec.omega[gi[k - 1]:gi[k]])
            est.estimate()
            est.refresh()
        e = est.estimate()
        assert e.status == 'ok' and e.diagnostics['hold'] == 'linear', e.diagnostics
        z = (e.theta - matrix_to_theta(rec.inertia)) / e.theta_std
        assert np.max(np.abs(z)) < 4.0, z
