#!/usr/bin/env python3
"""UBC tennis-racquet tosses (torque-free, phone gyro): convert to MCAP, check ratios and axes.

Data set: github.com/fbubbar/sci1-t2 (F. Bubbar, L. Zhu, "The Intermediate Axis Theorem: A
Model for the Period and a Phenomenal Explanation", UBC Science One, doi:10.14288/1.0448943):
an iPhone 12 zip-tied to the strings of a tennis racquet, tossed about its intermediate axis;
phyphox "Gyroscope rotation rate" exports at ~100 Hz with hand-picked free-flight windows.
**The data set states no licence**: nothing of it is committed here; this script works on the
user's own clone.

Truth (the authors' pendulum measurements, racquet + phone about the centre of mass, phone
axes assumed principal): ``Ix = 18.8 +- 5.7``, ``Iy = 1.391 +- 0.076`` (torsional pendulum),
``Iz = 20.7 +- 3.8`` g m^2.  A toss is torque-free, so only the ratios and the principal axes
are observable: ``Ix/Iz = 0.91 +- 0.30`` (weak) and ``Iy/Iz = 0.067 +- 0.013``.

Commands::

    ubc_racquet.py convert --repo CLONE --out DIR
        -> DIR/NAME.mcap per toss (/imu: Imu angular velocity, phone frame), DIR/index.json
    ubc_racquet.py bench --repo CLONE [--method M] [--out results.json]
        -> per toss: status, Ix/Iz and Iy/Iz with sigma, principal-axis angles to the phone
           axes; the spread of the tosses against their own sigma; the ratios against the truth

``CLONE`` is a clone of the repository (``data/round*/Gyroscope rotation rate */Raw Data.csv``
with ``meta/segments.csv``: the authors' windows and labels).  Instead of a clone, ``--csv-dir``
reads per-toss CSVs ``t,wx,wy,wz`` with an ``index.json`` listing ``{"csv", "comment"}`` per
toss (the research note's converter writes that form).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: Pendulum truth [kg m^2] (phone axes x, y, z) and its one sigma.
TRUTH_I = np.array([18.8e-3, 1.391e-3, 20.7e-3])
TRUTH_STD = np.array([5.7e-3, 0.076e-3, 3.8e-3])
#: The label of the tosses about the intermediate axis in ``meta/segments.csv``.
INTERMEDIATE = 'intermediate axis rotation'


def truth_ratios() -> tuple[np.ndarray, np.ndarray]:
    """``[Ix/Iz, Iy/Iz]`` of the pendulum truth and their sigma (independent errors)."""
    r = TRUTH_I[[0, 1]] / TRUTH_I[2]
    rel = np.sqrt((TRUTH_STD[[0, 1]] / TRUTH_I[[0, 1]]) ** 2 + (TRUTH_STD[2] / TRUTH_I[2]) ** 2)
    return r, r * rel


def read_tosses(repo: Path | None, csv_dir: Path | None) -> list[dict]:
    """Every labelled window as ``{name, comment, t [s], w (n, 3) [rad/s]}``."""
    out: list[dict] = []
    if csv_dir is not None:
        idx = json.loads((csv_dir / 'index.json').read_text())
        for s in idx['segments']:
            d = np.loadtxt(csv_dir / s['csv'], delimiter=',', skiprows=1, ndmin=2)
            out.append({'name': Path(s['csv']).stem, 'comment': s.get('comment', ''),
                        't': d[:, 0], 'w': d[:, 1:4]})
        return out
    if repo is None:
        raise SystemExit('give --repo CLONE or --csv-dir DIR')
    runs = sorted(p.parent.parent for p in repo.glob('data/*/*/meta/segments.csv'))
    if not runs:
        raise SystemExit(f'{repo}: no data/*/*/meta/segments.csv (a clone of '
                         'github.com/fbubbar/sci1-t2 is expected)')
    for run in runs:
        d = np.genfromtxt(run / 'Raw Data.csv', delimiter=',', skip_header=1)
        with open(run / 'meta' / 'segments.csv', newline='') as f:
            segs = list(csv.DictReader(f))
        tag = run.parent.name + '_' + ''.join(c for c in run.name.split(' ', 3)[-1]
                                              if c.isdigit())
        for s in segs:
            try:
                t0, t1 = float(s['start']), float(s['end'])
            except (TypeError, ValueError):          # blank rows in some segments.csv
                continue
            sel = (d[:, 0] >= t0) & (d[:, 0] <= t1)
            if sel.sum() < 10:
                continue
            out.append({'name': f"{tag}_seg{int(s['segment']):02d}",
                        'comment': s.get('comment', ''), 't': d[sel, 0] - d[sel, 0][0],
                        'w': d[sel, 1:4]})
    return out


def write_mcap(path: Path, t: np.ndarray, w: np.ndarray,
               start_ns: int = 1_700_000_000_000_000_000) -> None:
    """One toss as MCAP: ``/imu`` (Imu, angular velocity only; no torque topic)."""
    from inertia_ros.io import cdr_encode
    from inertia_ros.io.mcap_writer import McapWriter, seconds_to_ns

    t_ns = seconds_to_ns(t, start_ns)
    vals = np.zeros((len(t_ns), 37))
    vals[:, 3] = 1.0
    vals[:, 4] = -1.0                 # no orientation
    vals[:, 13:16] = w
    with McapWriter(path, overwrite=True) as wr:
        wr.add_topic('/imu', cdr_encode.IMU, qos='sensor_data')
        wr.write_many('/imu', t_ns, cdr_encode.encode_stamped_float64(t_ns, 'phone', vals))


def toss_ratios(t: np.ndarray, w: np.ndarray, method: str) -> dict:
    """Torque-free estimate of one toss: status, ``[Ix/Iz, Iy/Iz]`` with sigma, axis angles.

    The principal ratios are matched to the phone axes by the principal axes (smallest:
    the handle, y; largest: the string-plane normal, z); the ratio sigma is first-order from
    the principal ratios' sigma (their correlation neglected).
    """
    from inertia_ros.core.estimation import estimate

    res = estimate(t, w, np.zeros(0), np.zeros((0, 3)), method=method, model='full')
    row: dict = {'status': res.status, 'method': res.method}
    pr = res.diagnostics.get('principal_ratios')
    if pr is None or res.principal_axes is None:
        row['reason'] = res.diagnostics.get('reason', '')
        return row
    pr = np.asarray(pr, dtype=float)
    ps = np.asarray(res.diagnostics.get('principal_ratios_std', np.full(3, np.nan)), float)
    axes = np.asarray(res.principal_axes, dtype=float)
    # principal (ascending) -> phone axes y, x, z
    phone = np.eye(3)[:, [1, 0, 2]]
    ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(axes * phone, axis=0)), 0.0, 1.0)))
    r = np.array([pr[1] / pr[2], pr[0] / pr[2]])
    rs = r * np.sqrt((ps[[1, 0]] / pr[[1, 0]]) ** 2 + (ps[2] / pr[2]) ** 2)
    row.update(ratios=r.tolist(), ratios_std=rs.tolist(), axis_angle_deg=ang.tolist())
    return row


def bench(args: argparse.Namespace) -> int:
    tosses = read_tosses(Path(args.repo) if args.repo else None,
                         Path(args.csv_dir) if args.csv_dir else None)
    out = []
    for s in tosses:
        if s['comment'].strip().lower() != INTERMEDIATE and not args.all:
            continue
        row = {'name': s['name'], 'comment': s['comment'].strip(), 'samples': len(s['t'])}
        try:
            row.update(toss_ratios(s['t'], s['w'], args.method))
        except ValueError as exc:
            row.update(status='error', reason=str(exc))
        out.append(row)
    summary(out)
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


def summary(out: list[dict]) -> dict:
    """Print and return the figures: statuses, ratio medians, spread and truth comparison."""
    from collections import Counter

    rows = [r for r in out if 'ratios' in r]
    counts = Counter(r['status'] for r in out)
    print(f'tosses {len(out)}; statuses {dict(counts)}')
    if not rows:
        return {'tosses': len(out)}
    R = np.array([r['ratios'] for r in rows])
    S = np.array([r['ratios_std'] for r in rows])
    A = np.array([r['axis_angle_deg'] for r in rows])
    tr, ts = truth_ratios()
    med = np.median(R, axis=0)
    # repeatability: the tosses about their weighted mean, in units of their own sigma
    wts = 1.0 / S ** 2
    mean = np.sum(wts * R, axis=0) / np.sum(wts, axis=0)
    z_rep = (R - mean) / S
    rms_rep = np.sqrt(np.mean(z_rep ** 2, axis=0))
    z_truth = (med - tr) / ts
    fig = {'tosses': len(out), 'with_ratios': len(rows), 'median': med.tolist(),
           'iqr': np.percentile(R, [25, 75], axis=0).tolist(),
           'median_sigma': np.median(S, axis=0).tolist(), 'rms_z_repeat': rms_rep.tolist(),
           'z_truth': z_truth.tolist(), 'axis_angle_median_deg': np.median(A, 0).tolist()}
    for k, name in enumerate(('Ix/Iz', 'Iy/Iz')):
        print(f'{name}: median {med[k]:.4f} (IQR {fig["iqr"][0][k]:.4f}-{fig["iqr"][1][k]:.4f}), '
              f'median sigma {fig["median_sigma"][k]:.2g}; truth {tr[k]:.3f} +- {ts[k]:.3f} '
              f'(z {z_truth[k]:+.2f}); tosses about their mean: RMS z {rms_rep[k]:.2f}')
    print('principal axes to the phone axes (y, x, z): median '
          + ', '.join(f'{a:.1f}' for a in fig['axis_angle_median_deg']) + ' deg')
    return fig


def convert(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tosses = read_tosses(Path(args.repo) if args.repo else None,
                         Path(args.csv_dir) if args.csv_dir else None)
    index = {'segments': []}
    for s in tosses:
        write_mcap(out / f"{s['name']}.mcap", s['t'], s['w'])
        index['segments'].append({'mcap': f"{s['name']}.mcap", 'comment': s['comment'],
                                  'samples': len(s['t']),
                                  'duration_s': float(s['t'][-1] - s['t'][0])})
    (out / 'index.json').write_text(json.dumps(index, indent=1))
    print(f'{len(tosses)} tosses -> {out} (estimate NAME.mcap --torque-topic none)')
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    sub = ap.add_subparsers(dest='cmd', required=True)
    for name, fn, helptext in (('convert', convert, 'labelled windows -> MCAP'),
                               ('bench', bench, 'ratios and axes of every toss vs the truth')):
        p = sub.add_parser(name, help=helptext)
        p.add_argument('--repo', help='clone of github.com/fbubbar/sci1-t2')
        p.add_argument('--csv-dir', help='per-toss CSVs t,wx,wy,wz with index.json')
        p.set_defaults(func=fn)
        if name == 'convert':
            p.add_argument('--out', required=True)
        else:
            p.add_argument('--method', default='auto')
            p.add_argument('--all', action='store_true',
                           help='every labelled window, not only the intermediate-axis tosses')
            p.add_argument('--out')
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == '__main__':
    sys.exit(main())
