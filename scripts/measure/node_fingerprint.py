"""Every estimate of the node path and of recursive-estimator scenarios, for before/after checks.

    PYTHONPATH=TREE .venv/bin/python scripts/measure/node_fingerprint.py dump OUT.pkl
    .venv/bin/python scripts/measure/node_fingerprint.py compare A.pkl B.pkl

``dump`` pickles the fields of every estimate (``vars(InertiaEstimate)``) of: the node's
estimator (``make_estimator`` with the node's defaults, hold ``default``, ``zoh`` and
``linear``) fed a 25 s reference record in 0.1 s blocks, an estimate and a refresh after each,
two seeds; and recursive estimators with hold ``auto``/``linear``, gaps, forgetting, a window
and a torque-free record (40 s, fed in 0.1 s blocks, some sample by sample).  ``compare``
prints, per scenario, the largest ``|d inertia| / inertia_std`` (sigma units), the largest
absolute change of the diagnostics' test statistics and sigma figures, and every change that
is not a float (status, model, hold, warnings); ``identical`` when the pickles are equal.
"""
from __future__ import annotations

import dataclasses
import pickle
import sys
from typing import Any

import numpy as np

_STATISTICS = ('sigma', 'chi2', 'p_value', 'statistic')


def _feed(est: Any, rec: Any, every: int = 10, gap: tuple[float, float] | None = None,
          refresh: bool = False) -> list[dict[str, Any]]:
    """Estimates of ``est`` fed ``rec`` in 0.1 s blocks (every 7th sample by sample)."""
    tg, wg, tq, q = rec.t_gyro, rec.omega, rec.t_torque, rec.torque
    if gap is not None:
        kg = (tg < gap[0]) | (tg > gap[1])
        kq = (tq < gap[0] + 0.5) | (tq > gap[1] + 0.5)
        tg, wg, tq, q = tg[kg], wg[kg], tq[kq], q[kq]
    kb = np.floor(tg / 0.1 + 1e-9).astype(int)
    kt = np.floor(tq / 0.1 + 1e-9).astype(int)
    out = []
    for b in range(int(max(kb[-1], kt[-1])) + 1):
        if (kt == b).any():
            est.add_torque(tq[kt == b], q[kt == b])
        g = kb == b
        if g.any():
            if b % 7 == 3:
                for i in np.flatnonzero(g):
                    est.add_gyro(float(tg[i]), wg[i])
            else:
                est.add_gyro(tg[g], wg[g])
        if b % every == every - 1:
            out.append(dict(vars(est.estimate())))
            if refresh:
                est.refresh()
    out.append(dict(vars(est.estimate())))
    return out


def dump(path: str) -> None:
    """Pickle every estimate of the scenarios to ``path``."""
    from inertia_ros.bench.truth_sim import TruthCase, simulate_truth
    from inertia_ros.core.estimation.recursive import RecursiveEstimator
    from inertia_ros.nodes import params
    from inertia_ros.nodes.selection import make_estimator
    scene = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))
    res: dict[str, list[dict[str, Any]]] = {}
    for seed in (0, 1):
        rec = simulate_truth(scene.with_(duration=25.0), [seed])[0]
        for hold in ('default', 'zoh', 'linear'):
            cfg = {n: s.default for n, s in params.ESTIMATOR.items()}
            if hold != 'default':
                cfg['hold'] = hold
            res[f'node_{hold}{seed}'] = _feed(make_estimator(cfg)(), rec, every=1,
                                              refresh=True)
    rl = simulate_truth(scene.with_(torque_kind='continuous', duration=40.0), [0])[0]
    R = RecursiveEstimator
    res['auto_gap'] = _feed(R(model='auto', torque_bias='auto', hold='auto', reselect_every=10,
                              defer_adequacy=True), rl, gap=(12.0, 12.7), refresh=True)
    res['auto_seg3_gap'] = _feed(R(model='full', torque_bias='on', hold='auto', segment=3.0),
                                 rl, gap=(20.0, 21.0))
    res['linear_gap'] = _feed(R(model='auto', torque_bias='auto', hold='linear',
                                reselect_every=5, defer_adequacy=True), rl, gap=(7.0, 7.4),
                              refresh=True)
    res['window'] = _feed(R(model='full', torque_bias='on', hold='linear', window=4.0,
                            segment=2.0, torque_scale_std=0.02, gyro_scale_std=0.01), rl,
                          gap=(5.0, 5.6))
    res['forgetting'] = _feed(R(model='diagonal', forgetting=0.9995, block=50), rl)
    res['torque_free'] = _feed(R(model='full', hold='auto'),
                               dataclasses.replace(rl, torque=rl.torque * 0.0), every=25)
    with open(path, 'wb') as f:
        pickle.dump(res, f)
    print({k: len(v) for k, v in res.items()})


def _walk(x: Any, y: Any, key: str, stats: dict[str, float], other: list[str]) -> None:
    """Collect the statistics' absolute changes and the non-float differences."""
    if isinstance(x, dict):
        if set(x) != set(y):
            other.append(f'{key}: keys {sorted(set(x) ^ set(y))}')
            return
        for k in x:
            _walk(x[k], y[k], k, stats, other)
    elif isinstance(x, (list, tuple)) and not all(isinstance(v, float) for v in x):
        if len(x) != len(y):
            other.append(f'{key}: length')
            return
        for p, q in zip(x, y, strict=True):
            _walk(p, q, key, stats, other)
    elif isinstance(x, float) and isinstance(y, float):
        if any(s in key for s in _STATISTICS) and not (np.isnan(x) and np.isnan(y)):
            stats[key] = max(stats.get(key, 0.0), abs(x - y))
    elif not isinstance(x, (np.ndarray, list, tuple)) and x != y:
        other.append(f'{key}: {str(x)[:60]!r} -> {str(y)[:60]!r}')


def compare(path_a: str, path_b: str) -> None:
    """Print the drift between two dumps."""
    with open(path_a, 'rb') as f:
        a = pickle.load(f)
    with open(path_b, 'rb') as f:
        b = pickle.load(f)
    print('identical' if pickle.dumps(a) == pickle.dumps(b) else 'not identical')
    for name in a:
        sig, stats, other = 0.0, {}, []      # type: ignore[var-annotated]
        for x, y in zip(a[name], b[name], strict=True):
            _walk(x, y, name, stats, other)
            if x.get('inertia') is None or x.get('inertia_std') is None:
                continue
            s = np.asarray(x['inertia_std'], float)
            ok = np.isfinite(s) & (s > 0)
            d = np.abs(np.asarray(x['inertia'], float) - np.asarray(y['inertia'], float))
            if ok.any():
                sig = max(sig, float(np.max(d[ok] / s[ok])))
        worst = sorted(stats.items(), key=lambda kv: -kv[1])[:3]
        print(f'{name:16s} max |d inertia|/sigma {sig:.2g}; statistics: '
              + ', '.join(f'{k} {v:.2g}' for k, v in worst)
              + (f'; OTHER: {other[:3]}' if other else ''))


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == 'dump':
        dump(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == 'compare':
        compare(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__.split('\n\n')[1])
