#!/usr/bin/env python3
"""TU Delft thrown-flywheel recordings: convert to rosbag2 MCAP and validate against CAD truth.

Data set: github.com/tudelft/inertiaEstimation (Blaha, Kuijper, Pop, Smeur, "Rapid and
Inexpensive Inertia Tensor Estimation from a Single Object Throw", arXiv:2503.13137): a small
flight controller with a flywheel, thrown with test objects; 4 kHz gyro, flywheel eRPM.
**The data set states no licence**: nothing of it (logs, CSV, MCAP, truth) is committed here;
this script works on the user's own copy.

Input: per throw a CSV, either

* the converted form ``t,wx,wy,wz,ax,ay,az,wheel[,erpm]`` (s, rad/s in the authors' body
  frame, m/s^2, flywheel speed rad/s), or
* the raw blackbox CSV that Betaflight's ``blackbox_decode`` or orangebox's ``bb2csv`` writes
  from a ``LOG*.BFL`` (columns ``time``, ``gyroADC[0..2]``, ``accSmooth[0..2]``, ``erpm[0]``,
  optionally with a unit suffix such as ``time (us)``), converted with the authors' conventions:
  ``w = [-g1, g0, g2] pi / 180 / 16.384``, ``a = [-a1, a0, a2] 9.81 / 2048``,
  ``wheel = erpm * 100 / 7 * 2 pi / 60`` (14-pole motor), flywheel axis ``[0, 0, -1]``.

Commands::

    tudelft_throw.py convert CSV... --out DIR [--window-index index.json]
        -> DIR/NAME.mcap (/imu: Imu with angular velocity and acceleration; /joint_states:
           JointState 'flywheel' velocity) and DIR/flywheel.yaml (the wheels file)
    tudelft_throw.py bench --csv-root DIR --index index.json [--out results.json]
        -> per throw: status, tensor, device removal, eps / Psi / Frobenius error against
           the object truth, principal moments within 3 sigma

``index.json`` (per throw: ``csv``, ``config``, ``fit_window`` [first, end) sample indices,
``truth_object`` {m, cog, I}; plus ``wheel`` {axis, inertia} and ``device`` {m, x, I_prime})
holds the truth and the authors' calibration; the research note's converter writes it.

Metrics (as the authors): ``eps = ||lambda - lambda_true|| / ||lambda_true||`` of the sorted
principal moments (orientation-free), ``Psi`` the largest principal-axis angle error, and the
Frobenius error of the whole tensor.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

WHEEL_AXIS = (0.0, 0.0, -1.0)
POLE_PAIRS = 7


def read_throw_csv(path: Path) -> dict[str, np.ndarray]:
    """A throw CSV (converted or raw blackbox) as ``t`` [s], ``w`` [rad/s], ``a`` [m/s^2],
    ``wheel`` [rad/s]."""
    with open(path) as f:
        header = [h.strip() for h in f.readline().split(',')]
    base = [h.split(' (')[0].strip() for h in header]
    d = np.genfromtxt(path, delimiter=',', skip_header=1, dtype=float)
    if d.ndim == 1:
        d = d[None]
    col = {n: d[:, i] for i, n in enumerate(base)}
    if {'t', 'wx', 'wy', 'wz', 'wheel'} <= set(col):
        a = np.column_stack([col.get(k, np.zeros(len(d))) for k in ('ax', 'ay', 'az')])
        return {'t': col['t'], 'w': np.column_stack([col['wx'], col['wy'], col['wz']]),
                'a': a, 'wheel': col['wheel']}
    need = ['time', 'gyroADC[0]', 'gyroADC[1]', 'gyroADC[2]', 'erpm[0]']
    missing = [n for n in need if n not in col]
    if missing:
        raise SystemExit(f'{path}: columns {missing} missing: expected the converted form '
                         't,wx,wy,wz,ax,ay,az,wheel or a blackbox CSV (bb2csv)')
    ok = np.isfinite(col['time'])
    g = np.column_stack([col[f'gyroADC[{i}]'] for i in range(3)])[ok]
    w = np.column_stack([-g[:, 1], g[:, 0], g[:, 2]]) * math.pi / 180.0 / 16.384
    if all(f'accSmooth[{i}]' in col for i in range(3)):
        ac = np.column_stack([col[f'accSmooth[{i}]'] for i in range(3)])[ok]
        a = np.column_stack([-ac[:, 1], ac[:, 0], ac[:, 2]]) * 9.81 / 2048.0
    else:
        a = np.zeros_like(w)
    wheel = col['erpm[0]'][ok] * 100.0 / POLE_PAIRS * 2.0 * math.pi / 60.0
    t = (col['time'][ok] - col['time'][ok][0]) * 1e-6
    return {'t': t, 'w': w, 'a': a, 'wheel': wheel}


def write_mcap(path: Path, s: dict[str, np.ndarray], start_ns: int = 1_700_000_000_000_000_000
               ) -> None:
    """One throw as MCAP: ``/imu`` (Imu) and ``/joint_states`` (JointState 'flywheel')."""
    from inertia_ros.io import cdr_encode
    from inertia_ros.io.joint_state import JOINT_STATE, encode_joint_state
    from inertia_ros.io.mcap_writer import McapWriter, seconds_to_ns

    t_ns = seconds_to_ns(s['t'], start_ns)
    vals = np.zeros((len(t_ns), 37))
    vals[:, 3] = 1.0
    vals[:, 4] = -1.0                 # no orientation
    vals[:, 13:16] = s['w']
    vals[:, 25:28] = s['a']
    with McapWriter(path, overwrite=True) as wr:
        wr.add_topic('/imu', cdr_encode.IMU, qos='sensor_data')
        wr.add_topic('/joint_states', JOINT_STATE, qos='sensor_data')
        wr.write_many('/imu', t_ns, cdr_encode.encode_stamped_float64(t_ns, 'imu', vals))
        wr.write_many('/joint_states', t_ns,
                      encode_joint_state(t_ns, ['flywheel'], s['wheel'][:, None]))


def _lowpass(x: np.ndarray, dt: float, fc: float = 20.0) -> np.ndarray:
    from scipy import signal

    b, a = signal.butter(4, fc, fs=1.0 / dt)
    return signal.filtfilt(b, a, x, axis=0)


def _steiner(m: float, r: np.ndarray) -> np.ndarray:
    r = np.asarray(r, dtype=float)
    return m * (float(r @ r) * np.eye(3) - np.outer(r, r))


def combined_cog(t: np.ndarray, w: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Centre of mass relative to the IMU from the accelerometer in free flight:
    ``-a = w' x r + w x (w x r)`` by least squares (filtered as the authors: 20 Hz)."""
    dt = float(np.median(np.diff(t)))
    wf = _lowpass(w, dt)
    wd = _lowpass(np.gradient(w, dt, axis=0), dt)
    af = _lowpass(a, dt)
    rows = []
    for k in range(len(t)):
        wx, wy, wz = wf[k]
        ax, ay, az = wd[k]
        rows.append([[-wy * wy - wz * wz, wx * wy - az, wx * wz + ay],
                     [wx * wy + az, -wx * wx - wz * wz, wy * wz - ax],
                     [wx * wz - ay, wy * wz + ax, -wx * wx - wy * wy]])
    return np.linalg.lstsq(np.array(rows).reshape(-1, 3), -af.reshape(-1), rcond=None)[0]


def principal(I: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lam, v = np.linalg.eigh(I)
    return lam, v


def psi(I: np.ndarray, It: np.ndarray) -> float:
    """Largest angle [rad] between matched principal axes (sorted moments)."""
    _, v = principal(I)
    _, vt = principal(It)
    return float(max(math.acos(min(1.0, abs(float(v[:, k] @ vt[:, k])))) for k in range(3)))


def bench(args: argparse.Namespace) -> int:
    from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum

    idx = json.loads(Path(args.index).read_text())
    wheel = Wheel('flywheel', idx['wheel']['axis'], idx['wheel']['inertia'],
                  args.wheel_inertia_rel_std * idx['wheel']['inertia'])
    dev = idx['device']
    out = []
    for e in idx['logs']:
        if e.get('series', 'final_tests') != 'final_tests':
            continue
        p = Path(args.csv_root) / e['csv']
        if not p.is_file():
            continue
        s = read_throw_csv(p)
        a0, a1 = e['fit_window']
        t, w, acc, fw = s['t'][a0:a1], s['w'][a0:a1], s['a'][a0:a1], s['wheel'][a0:a1]
        mom = wheels_momentum(t, fw[:, None], [wheel])
        res = estimate_with_momentum(t, w, np.zeros(0), np.zeros((0, 3)), mom,
                                     method=args.method, model='full',
                                     torque_bias=args.torque_bias)
        row = {'config': e['config'], 'log': p.stem, 'status': res.status,
               'method': res.method, 'model': res.model}
        if res.inertia is not None and np.all(np.isfinite(res.inertia)):
            Ip = res.inertia - wheel.inertia * np.eye(3)
            xt = combined_cog(t, w, acc)
            tr = e['truth_object']
            m, It = tr['m'], np.array(tr['I'])
            xd = np.array(dev['x'])
            r = (dev['m'] / m) * (xd - xt)
            I_obj = Ip - _steiner(dev['m'], xt - xd) - np.array(dev['I_prime']) \
                - _steiner(m, r)
            lam = np.linalg.eigvalsh(I_obj)
            lam_t = np.linalg.eigvalsh(It)
            # the object's moments carry the whole estimate's std (the removal is exact)
            mstd = np.asarray(res.diagnostics.get('principal_moments_std', np.full(3, np.nan)))
            z = (lam - lam_t) / mstd
            row.update(eps=float(np.linalg.norm(lam - lam_t) / np.linalg.norm(lam_t)),
                       psi_deg=math.degrees(psi(I_obj, It)),
                       fro=float(np.linalg.norm(I_obj - It) / np.linalg.norm(It)),
                       moments=lam.tolist(), moments_true=lam_t.tolist(),
                       moments_std=mstd.tolist(), z=z.tolist(),
                       within_3sigma=int(np.sum(np.abs(z) <= 3)))
        out.append(row)
        print(f"{row['config']:<12} {row['log']} {row['status']:<24} "
              + (f"eps {100 * row['eps']:5.2f} %  Psi {row['psi_deg']:4.1f} deg  "
                 f"fro {100 * row['fro']:5.2f} %  z {np.round(row['z'], 1)}"
                 if 'eps' in row else ''), flush=True)
    ok = [r for r in out if 'eps' in r]
    if ok:
        E = np.array([r['eps'] for r in ok])
        F = np.array([r['fro'] for r in ok])
        Z = np.concatenate([r['z'] for r in ok])
        print(f'throws {len(out)}, with a tensor {len(ok)}; eps median {100 * np.median(E):.2f} '
              f'% mean {100 * E.mean():.2f} % max {100 * E.max():.2f} %; Frobenius median '
              f'{100 * np.median(F):.2f} %; principal moments within 3 sigma '
              f'{np.mean(np.abs(Z) <= 3):.0%}; status ok with eps > 10 %: '
              f"{sum(1 for r in ok if r['status'] == 'ok' and r['eps'] > 0.10)}")
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


def convert(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    J = args.flywheel_inertia
    (out / 'flywheel.yaml').write_text(
        'wheels:\n  - joint: flywheel\n    axis: [0.0, 0.0, -1.0]\n'
        f'    inertia: {J!r}   # authors\' calibrate.py on input/final_calibration\n')
    for c in args.csv:
        p = Path(c)
        s = read_throw_csv(p)
        write_mcap(out / f'{p.stem}.mcap', s)
        print(f'{out / (p.stem + ".mcap")}: {len(s["t"])} samples')
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    sub = ap.add_subparsers(dest='cmd', required=True)
    c = sub.add_parser('convert', help='CSV -> MCAP (+ flywheel.yaml)')
    c.add_argument('csv', nargs='+')
    c.add_argument('--out', required=True)
    c.add_argument('--flywheel-inertia', type=float, default=1.6887711495328251e-06,
                   help='kg m^2 (default: the authors\' calibration)')
    c.set_defaults(func=convert)
    b = sub.add_parser('bench', help='estimate every throw and compare with the truth')
    b.add_argument('--csv-root', required=True)
    b.add_argument('--index', required=True)
    b.add_argument('--method', default='auto')
    b.add_argument('--torque-bias', default='off')
    b.add_argument('--wheel-inertia-rel-std', type=float, default=0.005,
                   help='relative one-sigma of J (default 0.5 %%: the authors\' proof-body '
                        'reproduction)')
    b.add_argument('--out')
    b.set_defaults(func=bench)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == '__main__':
    sys.exit(main())
