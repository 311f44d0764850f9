"""Prototype: a torque constant in inertial axes as a nuisance of the momentum equations (issue 27).

    python scripts/measure/space_fixed_prototype.py SCENE DURATION [--seeds 0-39]
        [--segments 0.5,1,record] [--boot 200] [--show 3,31]

e.g. ``for s in inertial zero body; do python scripts/measure/space_fixed_prototype.py $s 5;
done`` and ``... $s 10 --seeds 0-7,31`` (about a minute per 40 records of 5 s).

SCENE: ``inertial`` (``bench.honesty.CASES['disturbance']``: 0.01 N m per axis fixed in inertial
axes, via ``honest_status.case_named``), ``zero`` (the same scene without disturbance) or
``body`` (the same disturbance constant in body axes).  Standalone: the package is only read.

Per record: the attitude ``R(t)`` (body -> start frame) is integrated from the measured gyro
(scipy ``Rotation``, a midpoint rotation vector per sample); anchored momentum equations over
consecutive segments of length T (each gyro sample t against its segment's first sample a),

    I (w(t) - w(a)) + int_a^t w x (I w) = int_a^t tau + b (t - a) + (int_a^t R') d,

(torque zero-order held; trapezoid integrals) are fitted by ordinary least squares for four
models: ``none`` (theta only), ``body`` (+ body-fixed bias b, as the package), ``space``
(+ d fixed in the start frame) and ``both``.  Sigma: a noise-addition bootstrap on the record
itself: fresh white noise of the record's own sensor noise levels (robust MAD of the second
differences of each gyro / torque axis, no model involved) is added to the measured gyro and
torque, everything (attitude included) recomputed and refitted, ``--boot`` times; the spread
of the refits is the first-order propagation ``J Sigma J'`` of the sensor noise through this
estimator on this record (exact for the linear parts, it needs no cluster count, which a 5 s
record with 10 segments of 0.5 s does not have for 12 parameters).  It is the sigma of the
noise alone, not widened for mismatch: an unmodelled torque shows as |z| >> 1, and as
``excess`` = RSS / (mean bootstrap RSS - RSS) >> 1 (about 1 when the model holds).  The
regressors carry gyro noise, so OLS shrinks the moments (errors in variables); the replicates
(noise variance doubled) show the shift, and the estimate is corrected by one SIMEX step,
``2 theta - mean(theta*)`` (extrapolation of the noise variance to zero).
The package's ``estimate()`` with defaults runs on the same record for comparison.

Measured (hspace 1fb4ae1 package, 2026-11-28; --boot 200; seeds 0-39 at 5 s, 0-7 and 31 at 10 and
20 s).  err: median relative Frobenius error; RMS z / max|z| over all six elements of all
records; s_izz: median sigma of izz; s/pkg: median over records and moments of this sigma / the
package's reported sigma (s/pkg0: / its sigma before its mismatch widening); s_d: median sigma
of d per axis (|d| = 0.01 N m); r_bd: median |corr(b_i, d_i)| of the ``both`` model.
Sigma check: RMS z 0.9-1.1 for every model on data it conforms to (the one-step SIMEX
correction above removes the OLS attenuation: before it, ``both`` had mean z -0.75 on the
moments and RMS z 1.39 on the zero control).

    5 s, record-long anchor   err %  RMS z  max|z|  s_izz e-3  s/pkg  s/pkg0  s_d e-3  r_bd  b, d kept
    inertial  package          3.20   1.25    6.0     19.19    (35 model_mismatch, 5 ok: 4, 31, 33 at |z| 4.5, 6.0, 4.5)
              none             9.15  11.78   35.6      5.87    0.30   2.36
              body             3.53   5.00   17.1      4.88    0.27   2.08                  40/40
              space            0.75   1.03    3.4      5.80    0.29   2.22     0.93               40/40
              both             1.17   1.07    3.4      5.76    0.34   2.64     7.22   0.93   3/40 39/40
              select           0.76   1.04    3.4      5.69    0.29   2.20     (space 36, both 4)
    zero      package          0.31   1.08    3.0      2.08    (40 ok)
              none             0.82   0.89    2.8      5.90    2.84   2.85
              body             0.74   1.01    3.5      4.87    2.67   2.70                   2/40
              space            0.69   1.03    3.5      5.60    2.67   2.77     0.93                2/40
              both             1.17   1.05    3.4      5.53    3.08   3.18     7.14   0.92   3/40  2/40
              select           0.78   0.94    3.1      5.73    2.81   2.86     (none 35, both 4, body 1)
    body      package          0.36   1.03    3.2      2.35    (40 ok)
              body             0.77   1.02    3.5      4.94    2.13   2.24                  40/40
              space            3.13   4.33   15.3      5.48    2.19   2.30     0.93               40/40
              both             1.20   1.06    3.3      5.61    2.55   2.81     6.94   0.93  38/40  1/40
              select           0.77   1.01    3.5      4.94    2.12   2.23     (body 37, both 3)
    (b, d kept: a 5 % joint Wald test of the block in that model's fit, bootstrap covariance;
    select: ``none`` unless (b, d) jointly matter in ``both``, then the blocks that matter given
    the other, ``both`` when neither alone does.)  Sigma per element, ``both`` / ``body`` on the
    zero control: x1.06-1.34 (median per element); ``space`` / ``body``: x0.99-1.06.
    5 s, 1 s segments: inertial body 3.00 % RMS z 2.01, space 1.61 % 1.09, both 2.36 % 1.10
    (s_d 14.6e-3, r_bd 0.95); zero: body 1.62 % 1.10, both 2.44 % 1.12; s_izz 8.8-13.4e-3.
    10 s, record anchor: inertial package 2.76 % (9 of 9 model_mismatch), body 2.72 % RMS z
    9.45, space 0.19 % 0.69, both 0.18 % 0.74 (s_d 0.83e-3, r_bd 0.59); zero: body 0.26 %,
    both 0.18 %, package 0.15 % (s/pkg0 2.2-2.4).
    20 s, record anchor: inertial package 2.24 % (9 of 9 model_mismatch), body 3.10 % RMS z
    14.96, space 0.20 % 1.06, both 0.22 % 1.08 (s_d 0.34e-3, r_bd 0.31); zero: body 0.21 %,
    both 0.18 %, package 0.07 %.
    Seeds 3 / 31 (inertial, 5 s, record anchor): package ok 2.84 % |z| 3.7 / ok 3.80 % |z| 6.0;
    body 3.99 % |z| 8.6 / 3.77 % 6.8; space 1.96 % 2.2 / 0.31 % 1.2; both 1.67 % 3.0 / 0.94 % 0.7.
"""
from __future__ import annotations

import argparse

import numpy as np
from honest_status import case_named  # this directory (sys.path[0] of a script)
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from inertia_ros.bench.truth_sim import TruthCase, TruthRecord, simulate_truth
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.regressors import (
    cumtrapz,
    cumulative_torque,
    gyroscopic_matrix,
    momentum_matrix,
    monomials,
)

IU = ([0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2])           # theta order ixx iyy izz ixy ixz iyz
MODELS = {'none': list(range(6)), 'body': list(range(9)),
          'space': list(range(6)) + [9, 10, 11], 'both': list(range(12))}


def scene(name: str, duration: float) -> TruthCase:
    """The disturbance scene or one of its controls, ``duration`` s long."""
    case = case_named('disturbance', duration)
    if name == 'zero':
        return case.with_(disturbance=(0.0, 0.0, 0.0))
    if name == 'body':
        return case.with_(disturbance_kind='body')
    return case


def noise_std(x: np.ndarray) -> np.ndarray:
    """White-noise sigma per column of (n, 3) samples: 1.4826 MAD of second differences / sqrt 6."""
    d2 = x[2:] - 2 * x[1:-1] + x[:-2]
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(6.0)


def attitude_integral(t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``int_0^t R(s)' ds`` for gyro stamps ``t`` (N,) and rates ``w`` (N, B, 3) -> (N, B, 3, 3)."""
    n, b = w.shape[:2]
    phi = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None, None]
    q = np.empty((n, b, 4))
    r = Rotation.identity(b)
    q[0] = r.as_quat()
    for k in range(n - 1):
        r = r * Rotation.from_rotvec(phi[k])          # body increment on the right
        q[k + 1] = r.as_quat()
    rt = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(n, b, 3, 3)
    return cumtrapz(t, rt.transpose(0, 1, 3, 2))


def normal_equations(rec: TruthRecord, w: np.ndarray, tau: np.ndarray, seg: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gram ``X'X`` (B, 12, 12), ``X'y`` (B, 12), ``y'y`` (B,) of the anchored equations.

    ``w`` (N, B, 3) and ``tau`` (M, B, 3): B versions of the record's gyro and torque; columns
    theta (6), b (3), d (3); segments of ``seg`` s (the whole record when longer).
    """
    t = rec.t_gyro
    n, b = w.shape[:2]
    m = cumtrapz(t, monomials(w))
    y = np.stack([cumulative_torque(rec.t_torque, tau[:, j], t, 'zoh') for j in range(b)], 1)
    c = attitude_integral(t, w)
    k = np.arange(1, n)
    nt = n if np.isinf(seg) else max(1, int(round(seg / np.median(np.diff(t)))))
    a = ((k - 1) // nt) * nt
    X = np.empty((n - 1, b, 3, 12))
    X[..., :6] = momentum_matrix(w[k] - w[a]) + gyroscopic_matrix(m[k] - m[a])
    X[..., 6:9] = -(t[k] - t[a])[:, None, None, None] * np.eye(3)
    X[..., 9:] = -(c[k] - c[a])
    yy = y[k] - y[a]
    return (np.einsum('rbij,rbik->bjk', X, X), np.einsum('rbij,rbi->bj', X, yy),
            np.einsum('rbi,rbi->b', yy, yy))


def fit_record(rec: TruthRecord, segs: list[float], boot: int, rng: np.random.Generator,
               simex: bool = True) -> dict:
    """Every model at every segment length on one record: estimates, bootstrap sigma, stats."""
    sg, st = noise_std(rec.omega), noise_std(rec.torque)
    w = np.repeat(rec.omega[:, None], boot + 1, 1)
    tau = np.repeat(rec.torque[:, None], boot + 1, 1)
    w[:, 1:] += rng.normal(size=w[:, 1:].shape) * sg
    tau[:, 1:] += rng.normal(size=tau[:, 1:].shape) * st
    truth = rec.inertia_end[IU]
    out = {'noise': (sg, st)}
    for seg in segs:
        G, g, yy = normal_equations(rec, w, tau, seg)
        for name, cols in MODELS.items():
            Gs, gs = G[:, cols][:, :, cols], g[:, cols]
            th = np.linalg.solve(Gs, gs[..., None])[..., 0]
            rss = yy - np.einsum('bj,bj->b', th, gs)       # (before the correction)
            sig = th[1:].std(axis=0, ddof=1)
            if simex:                   # noise variance 1 -> 2 moved it by the mean shift
                th[0] = 2 * th[0] - th[1:].mean(axis=0)
            dg = np.sqrt(np.diag(Gs[0]))
            ev = np.linalg.eigvalsh(Gs[0] / np.outer(dg, dg))
            full = np.full(12, np.nan)
            full[cols] = th[0]
            sfull = np.full(12, np.nan)
            sfull[cols] = sig
            wald = {}                   # p-value of the joint Wald test of each nuisance
            for key, blk in (('b', [6, 7, 8]), ('d', [9, 10, 11]), ('bd', list(range(6, 12)))):
                if all(c in cols for c in blk):
                    j = [cols.index(c) for c in blk]
                    v = th[0, j]
                    wald[key] = float(chi2.sf(v @ np.linalg.solve(np.cov(th[1:, j].T), v),
                                              len(j)))
            corr = np.nan
            if name == 'both':
                cc = np.corrcoef(th[1:, 6:].T)
                corr = float(np.mean(np.abs(np.diag(cc[:3, 3:]))))
            I = np.zeros((3, 3))
            I[IU] = th[0, :6]
            I = I + np.triu(I, 1).T
            out[seg, name] = {
                'theta': full, 'sigma': sfull, 'z': (th[0, :6] - truth) / sig[:6],
                'err': np.linalg.norm(I - rec.inertia_end) / np.linalg.norm(rec.inertia_end),
                'excess': rss[0] / max(rss[1:].mean() - rss[0], 1e-300),
                'cond': float(np.sqrt(ev[-1] / ev[0])), 'corr_bd': corr, 'wald': wald}
    e = estimate(rec.t_gyro, rec.omega, rec.t_torque, rec.torque)
    Ip, Sp = np.asarray(e.inertia), np.asarray(e.inertia_std)
    wid = ((e.diagnostics or {}).get('adequacy') or {}).get('sigma_widened_by') or 1.0
    out['pkg'] = {'status': e.status, 'z': (Ip[IU] - truth) / Sp[IU], 'sdiag': np.diag(Sp),
                  'widened': float(wid),
                  'err': np.linalg.norm(Ip - rec.inertia_end) / np.linalg.norm(rec.inertia_end)}
    return out


def seg_name(seg: float) -> str:
    return 'rec' if np.isinf(seg) else f'{seg:g}s'


def kept(fits: list[dict], key: str) -> str:
    """How many fits' nuisance ``key`` (b or d) a 5 % joint Wald test keeps ('' if none has it)."""
    p = [x['wald'][key] for x in fits if key in x['wald']]
    return f'{sum(q < 0.05 for q in p)}/{len(p)}' if p else ''


def selected(r: dict, seg: float) -> str:
    """The model the ``both`` fit's 5 % Wald tests choose: ``none`` unless (b, d) jointly
    matter; then the nuisances that matter given the other, ``both`` when neither alone does."""
    w = r[seg, 'both']['wald']
    b, d = w['b'] < 0.05, w['d'] < 0.05
    if w['bd'] >= 0.05:
        return 'none'
    return 'body' if b and not d else 'space' if d and not b else 'both'


def summarize(res: list[dict], segs: list[float]) -> None:
    """One line per segment length and model, one for the package."""
    pk = [r['pkg'] for r in res]
    zp = np.concatenate([p['z'] for p in pk])
    st: dict[str, int] = {}
    for p in pk:
        st[p['status']] = st.get(p['status'], 0) + 1
    bad = [r['seed'] for r, p in zip(res, pk, strict=True)
           if p['status'] == 'ok' and np.max(np.abs(p['z'])) > 4]
    print(f'package   err {100 * np.median([p["err"] for p in pk]):5.2f} %  RMS z '
          f'{np.sqrt(np.mean(zp ** 2)):5.2f}  max|z| {np.max(np.abs(zp)):5.1f}  '
          f'sigma izz {1e3 * np.median([p["sdiag"][2] for p in pk]):6.2f}e-3  {st}  '
          f'ok with |z|>4: seeds {bad}')
    print(f'{"seg":>4} {"model":6} {"err%":>6} {"RMSz":>6} {"max|z|":>6} {"#>4":>4} '
          f'{"s_izz e-3":>9} {"s/pkg":>6} {"s/pkg0":>6} {"cond":>6} {"excess":>7} '
          f'{"s_d e-3":>8} {"|d|/s_d":>7} {"|r_bd|":>6} {"b kept":>6} {"d kept":>6}')
    for seg in segs:
        for name in [*MODELS, 'select']:
            f = [r[seg, selected(r, seg) if name == 'select' else name] for r in res]
            z = np.concatenate([x['z'] for x in f])
            ratio = [x['sigma'][:3] / p['sdiag'] for x, p in zip(f, pk, strict=True)]
            ratio0 = [x['sigma'][:3] / p['sdiag'] * p['widened'] for x, p in zip(f, pk, strict=True)]
            sd = np.median([np.mean(x['sigma'][9:]) for x in f])
            dz = np.median([np.mean(np.abs(x['theta'][9:]) / x['sigma'][9:]) for x in f])
            print(f'{seg_name(seg):>4} {name:6} {100 * np.median([x["err"] for x in f]):6.2f} '
                  f'{np.sqrt(np.mean(z ** 2)):6.2f} {np.max(np.abs(z)):6.1f} '
                  f'{sum(np.max(np.abs(x["z"])) > 4 for x in f):4d} '
                  f'{1e3 * np.median([x["sigma"][2] for x in f]):9.2f} '
                  f'{np.median(ratio):6.2f} {np.median(ratio0):6.2f} '
                  f'{np.median([x["cond"] for x in f]):6.0f} '
                  f'{np.median([x["excess"] for x in f]):7.2f} {1e3 * sd:8.2f} {dz:7.1f} '
                  f'{np.median([x["corr_bd"] for x in f]):6.2f} '
                  f'{kept(f, "b"):>6} {kept(f, "d"):>6}')


def show(res: list[dict], seeds: list[int], seg: float) -> None:
    """Per-seed errors and max |z| of the package and each model at one segment length."""
    for r in res:
        if r['seed'] not in seeds:
            continue
        p = r['pkg']
        cells = ' '.join(f'{m} {100 * r[seg, m]["err"]:.2f}% |z|{np.max(np.abs(r[seg, m]["z"])):.1f}'
                         for m in MODELS)
        print(f'seed {r["seed"]:3d} package {p["status"]} {100 * p["err"]:.2f}% '
              f'|z|{np.max(np.abs(p["z"])):.1f} ({seg_name(seg)}) {cells}')


def parse_seeds(text: str) -> list[int]:
    """``'0-39'`` or ``'3,31'`` -> list of int."""
    out: list[int] = []
    for part in text.split(','):
        lo, _, hi = part.partition('-')
        out.extend(range(int(lo), int(hi) + 1) if hi else [int(lo)])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene', choices=['inertial', 'zero', 'body'])
    ap.add_argument('duration', type=float, help='record length [s]')
    ap.add_argument('--seeds', default='0-39', help="'0-39' or '3,31'")
    ap.add_argument('--segments', default='0.5,1,record', help="lengths [s] or 'record'")
    ap.add_argument('--boot', type=int, default=200, help='bootstrap replicates')
    ap.add_argument('--show', default='3,31', help='seeds to print one by one')
    args = ap.parse_args()
    try:
        seeds, shown = parse_seeds(args.seeds), parse_seeds(args.show)
        segs = [np.inf if s == 'record' else float(s) for s in args.segments.split(',')]
    except ValueError as exc:
        ap.error(f'--seeds/--show/--segments: {exc}; expected e.g. 0-39, 3,31, 0.5,1,record')
    if args.duration < 1 or args.boot < 10 or not seeds or any(s <= 0 for s in segs):
        ap.error(f'need duration >= 1 s, --boot >= 10, seeds, segments > 0; got {args.duration}, '
                 f'{args.boot}, {args.seeds!r}, {args.segments!r}')
    recs = simulate_truth(scene(args.scene, args.duration), seeds)
    res = []
    for rec in recs:
        r = fit_record(rec, segs, args.boot, np.random.default_rng(10_000 + rec.seed))
        r['seed'] = rec.seed
        res.append(r)
    sg = np.mean([r['noise'][0] for r in res])
    st = np.mean([r['noise'][1] for r in res])
    print(f'{args.scene} {args.duration:g} s, {len(seeds)} seeds, boot {args.boot}: noise from '
          f'the data gyro {sg:.2e} rad/s torque {st:.2e} N m')
    summarize(res, segs)
    bad = [r['seed'] for r in res
           if r['pkg']['status'] == 'ok' and np.max(np.abs(r['pkg']['z'])) > 4]
    for seg in segs:
        show(res, sorted(set(shown) | set(bad)), seg)


if __name__ == '__main__':
    main()
