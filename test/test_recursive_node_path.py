"""The node's latency path through RecursiveEstimator: ``merge()`` between updates and the
adequacy test deferred to ``refresh()`` give the estimates of the plain estimator.

- ``merge()`` at any poll only moves work earlier: every estimate equals the one of an
  estimator fed one block per update (rtol 1e-9: rounding of the block merges);
- ``defer_adequacy`` with ``refresh()`` after each estimate leaves every tensor bit for bit
  and every verdict that of the default, a test estimate reporting the previous test's one;
- a deferred test never refreshed runs at the next estimate (no verdict goes stale).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from inertia_ros.bench.common import nominal_scene
from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.core.estimation import RecursiveEstimator
from inertia_ros.core.simulation import simulate

NODE = dict(model='full', torque_bias='auto', reselect_every=10)


@pytest.fixture(scope='module')
def record() -> Any:
    """20 s of the nominal scene at 1 kHz (both streams)."""
    return simulate(nominal_scene(20.0, rate=1000.0), seed=4)


@pytest.fixture(scope='module')
def payload_change() -> Any:
    """30 s with a +20 % payload change at 15 s (the honesty benchmark's case)."""
    truth = CASES['payload_change'].truth
    return simulate_truth(truth.with_(duration=30.0, t_change=15.0), [2])[0]


def _feed(est: RecursiveEstimator, rec: Any, polls: int = 1, merge: bool = False,
          refresh: bool = False, on_estimate: Any = None) -> list[Any]:
    """Feed ``rec`` as the node does: ``polls`` blocks per 0.1 s update, optionally merged at
    the last poll before the update and refreshed after it (``on_estimate()`` called right
    after each estimate); the estimates."""
    out = []
    edges = np.arange(0.0, rec.t_gyro[-1] + 0.1, 0.1 / polls)
    gi = np.searchsorted(rec.t_gyro, edges, side='right')
    ti = np.searchsorted(rec.t_torque, edges, side='right')
    for k in range(1, len(edges)):
        if gi[k] > gi[k - 1]:
            est.add_gyro(rec.t_gyro[gi[k - 1]:gi[k]], rec.omega[gi[k - 1]:gi[k]])
        if ti[k] > ti[k - 1]:
            est.add_torque(rec.t_torque[ti[k - 1]:ti[k]], rec.torque[ti[k - 1]:ti[k]])
        if k % polls == polls - 1 and merge:
            est.merge()
        if k % polls == 0:
            out.append(est.estimate())
            if on_estimate is not None:
                on_estimate()
            if refresh:
                est.refresh()
    return out


def _verdict(e: Any) -> str | None:
    """The adequacy test's record of an estimate as text (NaN compares equal to NaN),
    without ``covariance``: that names what the estimate's own sigma is (the fit's residual
    excess), not the test's result."""
    a = e.diagnostics.get('adequacy')
    return None if a is None else repr(sorted((k, v) for k, v in a.items()
                                              if k != 'covariance'))


def _same_tensor(a: Any, b: Any, rtol: float) -> None:
    assert a.status == b.status
    if a.inertia is None:
        assert b.inertia is None
        return
    np.testing.assert_allclose(a.inertia, b.inertia, rtol=rtol, atol=0)
    np.testing.assert_allclose(a.inertia_std, b.inertia_std, rtol=max(rtol, 1e-12), atol=0)


def test_merge_between_updates_gives_the_same_estimates(record: Any) -> None:
    """10 polls per update with a merge before each update: every estimate equals the
    one-block-per-update estimator's (rtol 1e-9), and all 200 are ok by the end."""
    ref = _feed(RecursiveEstimator(**NODE), record)
    polled = _feed(RecursiveEstimator(**NODE), record, polls=10, merge=True)
    assert len(ref) == len(polled) == 200
    for a, b in zip(ref, polled, strict=True):
        _same_tensor(a, b, rtol=1e-9)
    assert ref[-1].status == 'ok'


def test_deferred_adequacy_reports_each_verdict_one_estimate_later(payload_change: Any
                                                                  ) -> None:
    """A payload change: tensors bit for bit; every verdict is the default's, except that a
    test estimate after the first reports the previous test's (unless that one saw under
    90 % of its samples: then its own, :data:`.schedule.STALE_FRACTION`); so the mismatch is
    flagged at most one test period after the default flags it, and stays flagged."""
    est = RecursiveEstimator(**NODE)
    ref, tested = [], []
    for e in _feed(est, payload_change, on_estimate=lambda: tested.append(
            est._schedule.adequacy_left == NODE['reselect_every'] - 1)):
        ref.append(e)
    dfr = _feed(RecursiveEstimator(defer_adequacy=True, **NODE), payload_change, refresh=True)
    verdict = [_verdict(e) for e in ref]
    tests = [i for i, (v, t) in enumerate(zip(verdict, tested, strict=True))
             if v is not None and t]
    assert len(tests) >= 20
    for i, (a, b) in enumerate(zip(ref, dfr, strict=True)):
        np.testing.assert_array_equal(a.inertia, b.inertia)
        if verdict[i] is None:
            assert _verdict(b) is None
        elif i in tests[1:]:     # the previous test's, or its own when that one is stale
            assert _verdict(b) in (verdict[tests[tests.index(i) - 1]], verdict[i]), i
        else:
            assert b.diagnostics['adequacy'] == pytest.approx(a.diagnostics['adequacy'],
                                                              nan_ok=True), i
            assert b.status == a.status
            np.testing.assert_array_equal(a.inertia_std, b.inertia_std)
    first = [i for i, e in enumerate(ref) if e.status == 'model_mismatch'][0]
    assert all(e.status == 'model_mismatch' for e in dfr[first + 10:])
    assert ref[-1].status == dfr[-1].status == 'model_mismatch'


def test_deferred_test_without_refresh_runs_at_the_next_estimate(payload_change: Any
                                                                ) -> None:
    """Never refreshed: each owed test runs inside the next estimate, so the mismatch is
    still found and the tensors are unchanged."""
    ref = _feed(RecursiveEstimator(**NODE), payload_change)
    est = RecursiveEstimator(defer_adequacy=True, **NODE)
    lazy = _feed(est, payload_change)
    for a, b in zip(ref, lazy, strict=True):
        np.testing.assert_array_equal(a.inertia, b.inertia)
    assert lazy[-1].status == 'model_mismatch'
    assert est._schedule.due is None or est._schedule.due[0] == len(lazy)


def test_refresh_without_a_deferred_test_does_nothing(record: Any) -> None:
    """refresh() is False with nothing owed (default estimator, or before any test)."""
    est = RecursiveEstimator(**NODE)
    assert est.refresh() is False
    _feed(est, record)
    assert est.refresh() is False
