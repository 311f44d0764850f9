"""Does a tilt of the flywheel's stated spin axis explain the TU Delft products' scatter?

    python scripts/measure/flywheel_tilt.py run --csv-root DIR --index DIR/index.json \
        --tilts=0,0/0.5,0/-0.5,0/0,0.5/0,-0.5 --out RUNS.json [--every N] [--mcap-cache D]
    python scripts/measure/flywheel_tilt.py sens RUNS.json
    python scripts/measure/flywheel_tilt.py fit RUNS.json --index DIR/index.json [--step 0.5]

``run`` estimates every test throw (issue 27, `scripts/tudelft_throw.py bench --cli`: the plain
CLI, ``estimate W.mcap --wheels flywheel.yaml --format json``, nothing else) once per tilt
``AX,AY`` [deg]: the wheels file's axis ``[0, 0, -1]`` rotated by ``AX`` about the gyro's x
axis, then ``AY`` about its y axis (``R_y(AY) R_x(AX) [0, 0, -1] = [-cos AX sin AY, sin AX,
-cos AX cos AY]``).  The wheels YAML is written under a temporary directory, the throws' MCAP
windows under ``--mcap-cache`` (default a temporary directory); nothing of the data set is
written into the repository (it states no licence).  Each record: config, log, tilt, status,
model, the whole body's tensor elements (xx, yy, zz, xy, xz, yz) [kg m^2] and their reported
sigmas, and the object tensor (device and parallel-axis terms removed as the bench does).
``--hold-bias`` passes ``--torque-bias on`` or ``off`` per throw as the defaults chose it
untilted (``full+bias`` or ``full``), so that a tilt's effect is not mixed with a flip of
that choice (a step change, 1-8 of 45 throws flip at 0.25-1 deg).

``sens`` prints, per configuration and element, the median |change| of the element between
the tilted and the untilted run in units of its reported sigma (untilted), and the
relative linearity (the +/- tilts' half difference against each one's change).

``fit`` (from the ``--hold-bias`` runs at 0 and +-STEP about each axis, first order: each
throw's tensor ``V + G a`` with ``G`` (6, 2) the central differences per degree) prints the
sensitivities' mean over throws (a common shift, no scatter) and spread (what a constant tilt
turns into scatter), the tilt each failing cell's excess would need, the least-squares tilt of
the deviations from the configuration means (units of the median sigma; per configuration
and common to all), the object products against the truth with a common device offset and
tilt, and the 24 cells at each fitted tilt.  ``stated`` adds a stated tilt sigma per
perpendicular axis to each throw's sigma (first order) and prints the cells; ``cells``
prints the cells of every tilt of a ``run`` (end to end).
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
_spec = importlib.util.spec_from_file_location('tudelft_throw', ROOT / 'scripts' / 'tudelft_throw.py')
tt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tt)

NAMES = ('xx', 'yy', 'zz', 'xy', 'xz', 'yz')
PROD = slice(3, 6)


def tilted_axis(ax_deg: float, ay_deg: float) -> np.ndarray:
    """``R_y(ay) R_x(ax) [0, 0, -1]`` (3,), degrees."""
    a, b = math.radians(ax_deg), math.radians(ay_deg)
    return np.array([-math.cos(a) * math.sin(b), math.sin(a), -math.cos(a) * math.cos(b)])


def wheels_yaml(J: float, axis: np.ndarray) -> str:
    return ('wheels:\n  - joint: flywheel\n'
            f'    axis: [{float(axis[0])!r}, {float(axis[1])!r}, {float(axis[2])!r}]\n    inertia: {J!r}\n')


def cli_estimate(mcap: Path, wheels: Path, extra: tuple[str, ...] = ()) -> dict:
    from inertia_ros.cli import main as cli

    buf = io.StringIO()
    argv = ['estimate', str(mcap), '--wheels', str(wheels), '--format', 'json', '--no-progress',
            *extra]
    with contextlib.redirect_stdout(buf):
        code = cli(argv)
    if code != 0:
        raise SystemExit(f'estimate {mcap}: exit {code}')
    return json.loads(buf.getvalue())


def _object(body: np.ndarray, J: float, dev: dict, e: dict, cog: np.ndarray) -> list[float]:
    I_prime = tt._matrix(np.asarray(body)) - J * np.eye(3)
    tr = e['truth_object']
    I = tt.object_inertia(I_prime, np.array(dev['I_prime']), dev['m'], np.array(dev['x']),
                          tr['m'], cog)
    return tt._theta(I).tolist()


def run(args: argparse.Namespace) -> int:
    idx = json.loads(Path(args.index).read_text())
    J, dev = idx['wheel']['inertia'], idx['device']
    tilts = [tuple(float(v) for v in s.split(',')) for s in args.tilts.split('/')]
    cache = Path(args.mcap_cache or tempfile.mkdtemp(prefix='tilt_mcap_'))
    cache.mkdir(parents=True, exist_ok=True)
    old = json.loads(Path(args.out).read_text()) if Path(args.out).is_file() else []
    done = {(r['log'], tuple(r['tilt'])) for r in old}
    out = list(old)
    tests = [e for e in idx['logs'] if e.get('series', 'final_tests') == 'final_tests']
    with tempfile.TemporaryDirectory() as d:
        for e in tests[::args.every]:
            p = Path(args.csv_root) / e['csv']
            mc = cache / (p.stem + '.mcap')
            s = tt.read_throw_csv(p)
            t, w, acc, fw = tt._window(s, e)
            if args.rest_bias:
                # the gyro's reading at rest at the start of the log (the device on the table)
                w = w - s['w'][:args.rest_bias].mean(0)
            if args.gyro_coupling:
                c = tuple(float(v) for v in args.gyro_coupling.split(','))
                w = w @ np.linalg.inv(tt.gyro_coupling_matrix(c)).T
            if not mc.is_file():
                tt.write_mcap(mc, {'t': t, 'w': w, 'a': acc, 'wheel': fw})
            cog = tt.combined_cog(t, w, acc)
            extra: tuple[str, ...] = ()
            if args.hold_bias:
                wy = Path(d) / 'flywheel.yaml'
                wy.write_text(wheels_yaml(J, tilted_axis(0.0, 0.0)))
                m0 = cli_estimate(mc, wy)['model']
                extra = ('--torque-bias', 'on' if 'bias' in m0 else 'off')
            for tl in tilts:
                if (p.stem, tl) in done:
                    continue
                wy = Path(d) / 'flywheel.yaml'
                wy.write_text(wheels_yaml(J, tilted_axis(*tl)))
                rep = cli_estimate(mc, wy, extra)
                rec = {'config': e['config'], 'log': p.stem, 'tilt': list(tl),
                       'status': rep['status'], 'model': rep['model']}
                if rep.get('inertia') is not None and rep.get('inertia_std') is not None:
                    body = tt._theta(np.array(rep['inertia'], dtype=float))
                    rec.update(body=body.tolist(),
                               std=tt._theta(np.array(rep['inertia_std'], dtype=float)).tolist(),
                               object=_object(body, J, dev, e, cog),
                               truth=tt._theta(np.array(e['truth_object']['I'])).tolist())
                out.append(rec)
                print(e['config'], p.stem, tl, rep['status'], rep['model'], flush=True)
            Path(args.out).write_text(json.dumps(out))
    return 0


def _table(recs: list[dict]) -> dict:
    """{(log, tilt): rec}."""
    return {(r['log'], tuple(r['tilt'])): r for r in recs if 'body' in r}


def sens(args: argparse.Namespace) -> int:
    recs = json.loads(Path(args.runs).read_text())
    T = _table(recs)
    logs = sorted({(r['config'], r['log']) for r in recs})
    tilts = sorted({tuple(r['tilt']) for r in recs if tuple(r['tilt']) != (0.0, 0.0)})
    for tl in tilts:
        print(f'tilt {tl} deg: median |d element| / sigma (xx yy zz xy xz yz); max over throws')
        for c in sorted({c for c, _ in logs}):
            D = []
            for cc, lg in logs:
                if cc != c or (lg, tl) not in T or (lg, (0.0, 0.0)) not in T:
                    continue
                r0, r1 = T[(lg, (0.0, 0.0))], T[(lg, tl)]
                D.append((np.array(r1['body']) - r0['body']) / np.array(r0['std']))
            D = np.abs(np.array(D))
            print(f'  {c:<6} n={len(D):2d} median {np.round(np.median(D, 0), 2)}  '
                  f'max {np.round(D.max(0), 2)}')
    return 0


def _config_data(recs: list[dict], step: float) -> dict:
    """Per configuration: untilted body values V (n, 6), sigmas S (n, 6), the first-order
    tilt sensitivities G (n, 6, 2) per degree (central differences of the +-step runs), the
    same for the object tensor (Vo, Go) and the object truth (n, 6)."""
    T = _table(recs)
    need = [(0.0, 0.0), (step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)]
    logs = sorted({(r['config'], r['log']) for r in recs
                   if all((r['log'], n) in T for n in need)})
    out = {}
    for c in sorted({c for c, _ in logs}):
        L = [g for cc, g in logs if cc == c]
        d = {'logs': L}
        for key in ('body', 'object'):
            gx = [(np.array(T[(g, (step, 0.0))][key]) - T[(g, (-step, 0.0))][key]) / (2 * step)
                  for g in L]
            gy = [(np.array(T[(g, (0.0, step))][key]) - T[(g, (0.0, -step))][key]) / (2 * step)
                  for g in L]
            d[key] = np.array([T[(g, (0.0, 0.0))][key] for g in L])
            d['G_' + key] = np.stack([np.array(gx), np.array(gy)], 2)
        d['S'] = np.array([T[(g, (0.0, 0.0))]['std'] for g in L])
        d['truth'] = np.array([T[(g, (0.0, 0.0))]['truth'] for g in L])
        out[c] = d
    return out


def _ratio(d: dict, a: np.ndarray) -> np.ndarray:
    """Scatter / median sigma (6,) of the body elements at tilt ``a`` (2,) deg, first order."""
    B = d['body'] + d['G_body'] @ a
    return B.std(0, ddof=1) / np.median(d['S'], 0)


def _deviation_system(d: dict, elements: range) -> tuple[np.ndarray, np.ndarray]:
    """The elements' deviations from their configuration mean in units of the median sigma,
    ``b`` (m,), and their first-order change per degree of tilt, ``A`` (m, 2)."""
    n = len(d['logs'])
    P = np.eye(n) - 1.0 / n
    s = np.median(d['S'], 0)
    A = np.vstack([P @ d['G_body'][:, k, :] / s[k] for k in elements])
    b = np.concatenate([P @ d['body'][:, k] / s[k] for k in elements])
    return A, b


def fit(args: argparse.Namespace) -> int:
    """The tilt's sensitivity spread, the least-squares tilts and the cells at them."""
    data = _config_data(json.loads(Path(args.runs).read_text()), args.step)
    configs = sorted(data)
    print('per degree of tilt, in median sigmas: mean over throws (a common shift) / std over '
          'throws (what makes scatter); xx yy zz xy xz yz')
    for c in configs:
        Gs = data[c]['G_body'] / np.median(data[c]['S'], 0)[None, :, None]
        for j, name in enumerate(('x', 'y')):
            print(f'  {c:<6} about {name}: mean {np.round(Gs[:, :, j].mean(0), 2)}  '
                  f'std {np.round(Gs[:, :, j].std(0, ddof=1), 2)}')
    print('cells outside [0.5, 2]: the tilt whose throw-to-throw spread alone would make the '
          'excess, sqrt(q^2 - 1) / (largest std of the sensitivity) [deg]')
    for c in configs:
        q = _ratio(data[c], np.zeros(2))
        Gs = data[c]['G_body'] / np.median(data[c]['S'], 0)[None, :, None]
        for k in np.flatnonzero(q > 2):
            sd = math.sqrt(np.linalg.norm(np.cov(Gs[:, k, :].T), 2))
            print(f'  {c} {NAMES[k]} q {q[k]:.2f}: excess {math.sqrt(q[k] ** 2 - 1):.2f} sigma, '
                  f'spread {sd:.2f} sigma/deg -> {math.sqrt(q[k] ** 2 - 1) / sd:.1f} deg')
    fits = {}
    for name, cs in [(c, [c]) for c in configs] + [('all', configs)]:
        for label, els in (('products', range(3, 6)), ('all six', range(6))):
            A, b = (np.vstack(v) if i == 0 else np.concatenate(v) for i, v in enumerate(
                zip(*(_deviation_system(data[c], els) for c in cs), strict=True)))
            a = np.linalg.lstsq(A, -b, rcond=None)[0]
            print(f'{name:<6} {label:<8} chi-square of the deviations {b @ b:7.1f} -> '
                  f'{np.sum((b + A @ a) ** 2):7.1f} at tilt ({a[0]:+.2f}, {a[1]:+.2f}) deg')
            if label == 'products':
                fits[name] = a
    _truth_fit(data)
    for name, a in fits.items():
        cells = {c: _ratio(data[c], a) for c in configs}
        n_in = sum(int(np.sum((q >= 0.5) & (q <= 2.0))) for q in cells.values())
        print(f'cells at the {name} fit ({a[0]:+.2f}, {a[1]:+.2f}) deg, first order: {n_in} of '
              f'{6 * len(configs)} in [0.5, 2]')
        for c, q in cells.items():
            print(f'    {c:<6} {np.round(q, 2)}')
    return 0


def _truth_fit(data: dict) -> None:
    """Object products against the truth, all throws: a common device-product offset (3) and
    a common tilt (2) by least squares, in units of the median body sigma."""
    rows, rhs = [], []
    for d in data.values():
        s = np.median(d['S'], 0)
        for k in range(3, 6):
            M = np.zeros((len(d['logs']), 5))
            M[:, :2] = d['G_object'][:, k, :] / s[k]
            M[:, 2 + k - 3] = 1.0 / s[k]
            rows.append(M)
            rhs.append((d['object'][:, k] - d['truth'][:, k]) / s[k])
    A, b = np.vstack(rows), np.concatenate(rhs)
    x0 = np.linalg.lstsq(A[:, 2:], -b, rcond=None)[0]
    x = np.linalg.lstsq(A, -b, rcond=None)[0]
    print(f'truth (object products, all throws): chi-square {b @ b:.0f}; a common offset '
          f'{np.sum((b + A[:, 2:] @ x0) ** 2):.0f}; offset and tilt {np.sum((b + A @ x) ** 2):.0f} '
          f'at tilt ({x[0]:+.2f}, {x[1]:+.2f}) deg')


def cells(args: argparse.Namespace) -> int:
    """The 24 scatter/sigma cells of each tilt run (end to end, CLI)."""
    recs = json.loads(Path(args.runs).read_text())
    for tl in sorted({tuple(r['tilt']) for r in recs}):
        fails, n_in, lines = [], 0, []
        for c in sorted({r['config'] for r in recs}):
            rr = [r for r in recs if r['config'] == c and tuple(r['tilt']) == tl and 'body' in r]
            q = tt.scatter_ratio([{'body': r['body'], 'body_std': r['std']} for r in rr])
            n_in += int(np.sum((q >= 0.5) & (q <= 2.0)))
            fails += [f'{c} {n} {v:.2f}' for n, v in zip(NAMES, q, strict=True) if not 0.5 <= v <= 2.0]
            lines.append(f'    {c:<6} {np.round(q, 2)}')
        n_ok = sum(1 for r in recs if tuple(r['tilt']) == tl and r['status'] == 'ok')
        print(f'tilt {tl}: {n_in} in [0.5, 2], {n_ok} ok; outside: {", ".join(fails)}')
        print('\n'.join(lines))
    return 0


def stated(args: argparse.Namespace) -> int:
    """First order: each throw's sigma with a stated tilt sigma per perpendicular axis added,
    ``sqrt(S^2 + s^2 (gx^2 + gy^2))``, and the cells with it."""
    data = _config_data(json.loads(Path(args.runs).read_text()), args.step)
    for sd in (0.25, 0.5, 1.0, 2.0):
        n_in, lines = 0, []
        for c, d in data.items():
            tot = np.sqrt(d['S'] ** 2 + sd ** 2 * np.sum(d['G_body'] ** 2, 2))
            q = d['body'].std(0, ddof=1) / np.median(tot, 0)
            n_in += int(np.sum((q >= 0.5) & (q <= 2.0)))
            wid = np.round(np.median(tot / d['S'], 0), 2)
            lines.append(f'    {c:<6} {np.round(q, 2)}  sigma x {wid}')
        print(f'axis std {sd} deg per perpendicular axis: {n_in} of 24 in [0.5, 2]')
        print('\n'.join(lines))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = p.add_subparsers(dest='cmd', required=True)
    r = sub.add_parser('run')
    r.add_argument('--csv-root', required=True)
    r.add_argument('--index', required=True)
    r.add_argument('--tilts', default='0,0', help='AX,AY pairs [deg] separated by /')
    r.add_argument('--out', required=True)
    r.add_argument('--every', type=int, default=1)
    r.add_argument('--mcap-cache')
    r.add_argument('--rest-bias', type=int, default=0,
                   help='subtract the mean gyro reading of the first N samples of the log (at '
                        'rest) from the rates: a gyro bias removed (use another --mcap-cache)')
    r.add_argument('--gyro-coupling', metavar='XY,XZ,YZ',
                   help='remove a symmetric gyro coupling from the rates first, as '
                        'tudelft_throw.py bench --gyro-coupling (use another --mcap-cache)')
    r.add_argument('--hold-bias', action='store_true',
                   help="pass --torque-bias on/off per throw as the CLI defaults chose it untilted "
                        "(the tilt's own effect, without the bias choice flipping)")
    s = sub.add_parser('sens')
    s.add_argument('runs')
    for name in ('fit', 'stated', 'cells'):
        f = sub.add_parser(name)
        f.add_argument('runs')
        f.add_argument('--step', type=float, default=0.5)
    a = p.parse_args(argv)
    return {'run': run, 'sens': sens, 'fit': fit, 'stated': stated, 'cells': cells}[a.cmd](a)


if __name__ == '__main__':
    raise SystemExit(main())
