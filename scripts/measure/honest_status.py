"""Status and sigma on the reference simulator (issue 27 items 3-4): estimate() defaults or CLI.

    python scripts/measure/honest_status.py CASE SEEDS DURATION [api|cli|node|tracking] [KEY=VALUE ...]

CASE: conforming, continuous, a case of ``bench.honesty.CASES`` (disturbance, gyro_bias,
payload_change, ...), or a peer-like sine profile ``sine_{x,y,z,iso}_{AMPLITUDE}[_LEVEL]``
(:func:`inertia_ros.bench.honesty.peer_like`: one tone per axis, quiet sensors, an unmodelled
disturbance fixed in inertial axes of LEVEL x (1, -0.75, 0.5) N m, 2e-4 when not given;
``_nodist`` for none).  Prints the statuses, RMS z over all records and over the ok ones,
max |z| of the ok ones, the ok records with some |z| > 5 and the median error.
``KEY=VALUE`` options go to the estimator of the path (``node``: over the honesty benchmark's
node options, e.g. ``hold=auto``, the node's default, or ``inertial_torque=auto``, the
node's parameter of the torque fixed in inertial axes; numbers are read as floats).
``tracking``: the node's ``method: tracking`` estimator at the node's defaults
(:class:`TrackingEstimator`, memory 10 s, torque bias and hold 'auto'), fed as the node feeds
it (10 Hz blocks, an estimate after each); the options go to it.  It also prints how many
records the tracker's whiteness test (reported, it does not decide) rejects at ``ALPHA``,
the range of the average NIS per degree of freedom and how many its fault score test rejects.
"""

import sys

import numpy as np

from inertia_ros.bench.honesty import CASES, PATHS, HonestyCase, feed_online, peer_like, run_case
from inertia_ros.bench.truth_sim import TruthCase, TruthRecord

#: The tracker's innovation tests of each record run (whiteness p-value, average NIS / dof,
#: 1.0 when the record is ``ok``).
TRACKER_TESTS: list[tuple[float, float, float]] = []
#: The tracker's fault score p-value of each record run that has one.
FAULT_P: list[float] = []
SCENE = TruthCase(amplitude=0.06, torque_noise=0.0012, omega0=(0.05, -0.03, 0.02))


def case_named(name: str, duration: float) -> TruthCase:
    """The scenario called ``name`` (see the module docstring), ``duration`` s long."""
    if name == 'conforming':
        return SCENE.with_(duration=duration)
    if name == 'continuous':
        return SCENE.with_(torque_kind='continuous', duration=duration)
    if name.startswith('sine_'):
        parts = name.split('_')
        level = 0.0 if parts[-1] == 'nodist' else float(parts[3]) if len(parts) > 3 else 2e-4
        return peer_like(parts[1], float(parts[2]), level, duration)
    t = CASES[name].truth.with_(duration=duration)
    return t.with_(t_change=duration / 2) if t.t_change is not None else t


def _tracking(rec: TruthRecord, opts: dict) -> tuple:
    """The node's tracker (``make_estimator`` for ``method: tracking`` at the defaults)."""
    from inertia_ros.core.estimation.tracking import TrackingEstimator
    kw = dict({'window': 10.0, 'model': 'full', 'torque_bias': 'auto', 'hold': 'auto'}, **opts)
    e = feed_online(TrackingEstimator(**kw), rec, 10.0)
    if e is None:
        return 'insufficient_data', None, None
    ad = (e.diagnostics or {}).get('adequacy') or {}
    if 'fault_p_value' in ad:
        FAULT_P.append(ad['fault_p_value'])
    if 'whiteness_p_value' in ad:
        TRACKER_TESTS.append((ad['whiteness_p_value'], ad['anis_chi2'] / ad['anis_dof'],
                              float(e.status == 'ok')))
    return e.status, e.inertia, e.inertia_std


PATHS.setdefault('tracking', _tracking)


def _option(arg: str) -> tuple[str, object]:
    """``KEY=VALUE`` as a pair (the value a float when it reads as one)."""
    key, _, value = arg.partition('=')
    try:
        return key, float(value)
    except ValueError:
        return key, value


def main() -> None:
    name, n, dur = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    path = sys.argv[4] if len(sys.argv) > 4 else 'api'
    opts = dict(_option(a) for a in sys.argv[5:])
    case = HonestyCase(case_named(name, dur), options=opts, node=opts)
    out = run_case(name, case, range(n), (path,))
    st: dict[str, int] = {}
    for o in out:
        st[o.status] = st.get(o.status, 0) + 1
    z_all = np.concatenate([o.z[np.isfinite(o.z)] for o in out])
    ok = [o for o in out if o.status == 'ok']
    z_ok = np.concatenate([o.z[np.isfinite(o.z)] for o in ok]) if ok else np.zeros(0)
    errs = [o.rel_error for o in out if np.isfinite(o.rel_error)] or [float('nan')]
    maxz = [float(np.nanmax(np.abs(o.z), initial=0.0)) for o in out]
    print(f'{name} {path} {" ".join(sys.argv[5:])} {n} x {dur:g} s: {st} RMS z all {np.sqrt(np.mean(z_all ** 2)):.2f} '
          f'ok {np.sqrt(np.mean(z_ok ** 2)) if z_ok.size else float("nan"):.2f} '
          f'max|z| ok {np.max(np.abs(z_ok)) if z_ok.size else float("nan"):.1f} '
          f'(all: {min(maxz):.1f}-{max(maxz):.1f}) ok with |z|>5: {sum(o.defect for o in out)} '
          f'median error {100 * np.median(errs):.3g} % (max {100 * np.max(errs):.3g} %)')
    if TRACKER_TESTS:
        from inertia_ros.core.estimation.options import ALPHA
        p, anis, ok = np.array(TRACKER_TESTS).T
        print(f'tracker whiteness p < {ALPHA:g}: {int(np.sum(p < ALPHA))} of {len(p)} tested, '
              f'{int(np.sum((p < ALPHA) & (ok > 0)))} of them ok '
              f'(min p {p.min():.2g}); average NIS/dof {anis.min():.2f}-{anis.max():.2f} '
              f'(median {np.median(anis):.2f})')
    if FAULT_P:
        from inertia_ros.core.estimation.options import ALPHA
        p = np.array(FAULT_P)
        print(f'tracker fault score p < {ALPHA:g}: {int(np.sum(p < ALPHA))} of {len(p)} '
              f'(median p {np.median(p):.2g})')


if __name__ == '__main__':
    main()
