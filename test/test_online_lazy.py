"""The online accumulators' lazy merging (issue 26, node speed): the same statistics.

:attr:`OnlineStats.lazy` queues blocks and merges each run between two segment closes as one
block; the sums may differ from block-by-block merging by rounding only.  :class:`ShiftRows`
queues its blocks and cuts them at a read: the same rows, so the same Gram bit for bit.
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation.accumulator import OnlineStats
from inertia_ros.core.estimation.online_shift import ShiftRows


def _blocks(seed: int = 0, duration: float = 9.0):
    """Gyro-rate rows (200 Hz) in 0.1 s blocks, each with the torque times (50 Hz) the
    aligner would hold then: from the last sample at or before the previous block's end,
    up to 0.05 s past the block (torque runs ahead of the gyro)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0025, duration, 0.005)
    V = np.cumsum(rng.normal(size=(len(t), 13)), axis=0) * 0.01
    ts_all = np.arange(0.0, duration + 0.2, 0.02)
    out, lo = [], 0
    for k in range(int(duration / 0.1)):
        sel = (t >= 0.1 * k) & (t < 0.1 * (k + 1))
        tb = t[sel]
        first = max(int(np.searchsorted(ts_all, t[lo], side='right')) - 1, 0)
        ts = ts_all[first:int(np.searchsorted(ts_all, tb[-1] + 0.05, side='right'))]
        out.append((tb, V[sel], ts))
        lo = int(np.flatnonzero(sel)[-1])
    return out


def _feed(acc: OnlineStats, blocks, close_at: int) -> None:
    for k, (tb, Vb, ts) in enumerate(blocks):
        acc.add_torque_power(np.ones((5, 3)))
        acc.add_motion(Vb[:, :3])
        if k == close_at:            # a gap: a new segment before this block
            acc.close(float(tb[0]))
        acc.merge(tb, Vb, ts)


@pytest.mark.parametrize('close_at', [30, 57])
def test_lazy_accumulator_matches_block_by_block(close_at: int) -> None:
    """Queued runs give the statistics of block-by-block merging to rounding (1e-10
    relative): the centred Gram, the torque-noise Gram, the walk time, the effective
    equations, the groups of the adequacy test, and the 4x shorter shadow's."""
    blocks = _blocks(0, 24.0)
    eager, lazy = (OnlineStats(2.0, None, 1.0) for _ in range(2))
    assert not eager.short.lazy         # until the window test has two groups
    lazy.lazy = lazy.short.lazy = True
    assert lazy.lazy and not eager.lazy
    _feed(eager, blocks, close_at)
    _feed(lazy, blocks, close_at)
    assert lazy._queued > 0 and lazy.short._queued > 0   # still queued: the reads merge them
    for a, b in ((eager, lazy), (eager.short, lazy.short)):
        Ce, Ge, we = a.totals()
        Cl, Gl, wl = b.totals()
        np.testing.assert_allclose(Cl, Ce, rtol=1e-10, atol=1e-12 * np.abs(Ce).max())
        np.testing.assert_allclose(Gl, Ge, rtol=1e-10, atol=1e-12 * np.abs(Ge).max())
        assert wl == pytest.approx(we, rel=1e-12)
        assert b.n_eff() == a.n_eff()
        np.testing.assert_allclose(b.omega_m2(), a.omega_m2(), rtol=0, atol=0)
    ge = eager.group_stats(np.full(3, 1e-6), torque_dt=0.02, gyro_dt=0.005, white_y_cov=None)
    gl = lazy.group_stats(np.full(3, 1e-6), torque_dt=0.02, gyro_dt=0.005, white_y_cov=None)
    assert len(gl) == len(ge) >= 2
    for (se, fe, me), (sl, fl, ml) in zip(ge, gl, strict=True):
        assert (fl, ml) == (fe, me)
        for x, y in ((sl.C, se.C), (sl.CP, se.CP)):
            np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-12 * np.abs(y).max())


def test_lazy_only_with_unit_weights() -> None:
    """Forgetting keeps block-by-block merging (the side sums decay with each merge)."""
    acc = OnlineStats(2.0, 5.0, 1.0)
    acc.lazy = acc.short.lazy = True
    assert not acc.lazy and not acc.short.lazy
    acc = OnlineStats(2.0, None, 1.0)
    acc.lazy = acc.short.lazy = True
    assert acc.lazy and acc.short.lazy


def test_shift_rows_queued_is_bit_for_bit() -> None:
    """ShiftRows cut block by block (a gap: a new segment) and queued, cut at the read:
    the same Gram, equations and segments, bit for bit."""
    blocks = _blocks(1, 24.0)
    now, queued = ShiftRows(10.0), ShiftRows(10.0)
    for k, (tb, Vb, _) in enumerate(blocks):
        breaks = [7] if k in (40, 171) else []
        if breaks:
            now._merge(tb[:7], Vb[:7])
            now.close(float(tb[7]))
        now._merge(tb[len(breaks) and 7:], Vb[len(breaks) and 7:])
        queued.merge(tb, Vb, breaks)
    assert queued._queued > 0
    a, b = now.gram(), queued.gram()
    assert a[1:] == b[1:] and a[2] >= 3
    np.testing.assert_array_equal(a[0], b[0])


def test_short_lazy_only_after_the_bias_split() -> None:
    """The recursive estimator's shadows merge block by block while the adequacy test may
    use the (rounding-sensitive) bias split, i.e. before two groups of segments, and lazily
    after: both holds' shadows after 30 s, neither after 4 s."""
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
    from inertia_ros.core.estimation.recursive import RecursiveEstimator
    rec = simulate_truth(TruthCase(amplitude=0.06, torque_noise=0.0012,
                                   omega0=(0.05, -0.03, 0.02)).with_(duration=30.0), [0])[0]
    est = RecursiveEstimator(model='full', torque_bias='on', hold='auto', segment=4.0)
    lazy = {}
    for k in range(30):
        q = (rec.t_torque >= k) & (rec.t_torque < k + 1)
        g = (rec.t_gyro >= k) & (rec.t_gyro < k + 1)
        est.add_torque(rec.t_torque[q], rec.torque[q])
        est.add_gyro(rec.t_gyro[g], rec.omega[g])
        est.estimate()
        lazy[k + 1] = [a.short.lazy for a in est._accs.values()]
    assert lazy[4] == [False, False] and lazy[30] == [True, True]
