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

    tudelft_throw.py index --repo CHECKOUT --out DIR
        -> DIR/*.csv (converted throws) and DIR/index.json from the LOG*.BFL logs (needs
           orangebox, optional: pip install orangebox==0.5.0)

    tudelft_throw.py convert CSV... --out DIR [--window-index index.json]
        -> DIR/NAME.mcap (/imu: Imu with angular velocity and acceleration; /joint_states:
           JointState 'flywheel' velocity) and DIR/flywheel.yaml (the wheels file)
    tudelft_throw.py bench --csv-root DIR --index index.json [--out results.json]
        -> per throw: status, tensor, device removal, eps / Psi / Frobenius error against
           the object truth, principal moments within 3 sigma

``index.json`` (per throw: ``csv``, ``config``, ``fit_window`` [first, end) sample indices,
``truth_object`` {m, cog, I}; plus ``wheel`` {axis, inertia} and ``device`` {m, x, I_prime})
holds the truth and the authors' calibration; ``index --repo CHECKOUT --out DIR`` writes it
(with the converted CSVs) from the user's checkout of the authors' repository.

Metrics (as the authors): ``eps = ||lambda - lambda_true|| / ||lambda_true||`` of the sorted
principal moments (orientation-free), ``Psi`` the largest principal-axis angle error, and the
Frobenius error of the whole tensor.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import types
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

WHEEL_AXIS = (0.0, 0.0, -1.0)
#: ``--cutoff-rule wheel``: the filtered method's cutoff is the flywheel's lowest rotation
#: frequency in the window divided by this (4th-order Butterworth: -16 dB there).
WHEEL_CUTOFF_MARGIN = 1.6
POLE_PAIRS = 7
#: the authors' calibrated flywheel inertia [kg m^2] (their calibrate.py on final_calibration)
DEFAULT_J = 1.6887711495328251e-06


BFL_HINT = ('reading a .BFL blackbox log needs orangebox (optional, not an inertia_ros '
             'dependency): pip install orangebox==0.5.0')


def read_blackbox(path: Path) -> dict[str, np.ndarray]:
    """The main-frame columns of a Betaflight/indiflight ``LOG*.BFL`` (first log in the file)
    by orangebox (optional): name -> (N,) float array, empty fields NaN."""
    try:
        from orangebox import Parser
    except ImportError:
        raise SystemExit(f'{path}: {BFL_HINT}') from None
    parser = Parser.load(str(path))
    names = list(parser.field_names)
    rows = [[np.nan if v == '' else v for v in f.data[:len(names)]] for f in parser.frames()]
    if not rows:
        raise SystemExit(f'{path}: no frames decoded; is it a blackbox log?')
    d = np.array(rows, dtype=float)
    return {n: d[:, i] for i, n in enumerate(names)}


def read_throw_csv(path: Path) -> dict[str, np.ndarray]:
    """A throw (converted CSV, raw blackbox CSV or ``.BFL`` log) as ``t`` [s], ``w`` [rad/s],
    ``a`` [m/s^2], ``wheel`` [rad/s]."""
    path = Path(path)
    if path.suffix.lower() == '.bfl':
        return _from_blackbox(read_blackbox(path), path)
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
    return _from_blackbox(col, path)


def _from_blackbox(col: dict[str, np.ndarray], path: Path) -> dict[str, np.ndarray]:
    """Raw blackbox columns in the authors' units and axes (module docstring)."""
    need = ['time', 'gyroADC[0]', 'gyroADC[1]', 'gyroADC[2]', 'erpm[0]']
    missing = [n for n in need if n not in col]
    if missing:
        raise SystemExit(f'{path}: columns {missing} missing: expected the converted form '
                         't,wx,wy,wz,ax,ay,az,wheel or a blackbox log/CSV (bb2csv)')
    ok = np.isfinite(col['time'])
    for n in need:
        ok &= np.isfinite(col[n])
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


def write_csv(path: Path, s: dict[str, np.ndarray]) -> None:
    """A throw in the converted form ``t,wx,wy,wz,ax,ay,az,wheel``."""
    np.savetxt(path, np.column_stack([s['t'], s['w'], s['a'], s['wheel']]), delimiter=',',
               header='t,wx,wy,wz,ax,ay,az,wheel', comments='', fmt='%.9g')


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


def combined_cog(t: np.ndarray, w: np.ndarray, a: np.ndarray, dt: float | None = None
                 ) -> np.ndarray:
    """Centre of mass relative to the IMU from the accelerometer in free flight:
    ``-a = w' x r + w x (w x r)`` by least squares (filtered as the authors: 20 Hz)."""
    dt = float(np.median(np.diff(t))) if dt is None else dt
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


def object_inertia(I_prime: np.ndarray, I_dev: np.ndarray, m_dev: float, x_dev: np.ndarray,
                   m_obj: float, x_test: np.ndarray) -> np.ndarray:
    """The object's tensor about its own centre of mass (the authors' ``translateI``).

    ``I_prime`` is the whole body's tensor without the flywheel's ``J 1`` about the combined
    centre of mass ``x_test``; the device (``I_dev`` about its centre of mass ``x_dev``) and
    both parallel-axis terms are removed.  Positions relative to the IMU [m], kg, kg m^2.
    """
    r = (m_dev / m_obj) * (x_dev - x_test)
    return I_prime - _steiner(m_dev, x_test - x_dev) - I_dev - _steiner(m_obj, r)


def principal(I: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lam, v = np.linalg.eigh(I)
    return lam, v


def psi(I: np.ndarray, It: np.ndarray) -> float:
    """Largest angle [rad] between matched principal axes (sorted moments)."""
    _, v = principal(I)
    _, vt = principal(It)
    return float(max(math.acos(min(1.0, abs(float(v[:, k] @ vt[:, k])))) for k in range(3)))


def _window(s: dict[str, np.ndarray], e: dict, delay: float = 0.0, offset: int | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The authors' fit window of one throw: ``t``, ``w``, ``a``, flywheel speed.

    ``delay`` [s] > 0 reads the flywheel speed that much later (telemetry lagging the gyro);
    ``offset`` starts the window that many samples after the throw start instead (the
    authors: 300).
    """
    a0, a1 = e['fit_window']
    if offset is not None:
        a0 = e['throw_start'] + offset
    t = s['t'][a0:a1]
    fw = s['wheel'][a0:a1] if delay == 0.0 else np.interp(t + delay, s['t'], s['wheel'])
    return t, s['w'][a0:a1], s['a'][a0:a1], fw


def _estimate_unit(s: dict[str, np.ndarray], e: dict, J0: float, args: argparse.Namespace
                   ) -> tuple[object, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One throw's estimate in units of the flywheel inertia.

    The estimate is linear in ``J`` (the only scale input), so the throw is estimated once with
    ``J0`` and returned as ``I_total / J0`` with its covariance (6, 6) ``/ J0^2``; ``I' =
    I_total - J 1`` for any calibrated ``J`` is then ``J (I_total / J0 - 1)``.  Returns
    ``(result, I_unit (3, 3) or None, cov_unit (6, 6), cog (3,) [m], t)``.
    """
    from inertia_ros.core.estimation.momentum import Wheel, estimate_with_momentum, wheels_momentum

    t, w, acc, fw = _window(s, e, args.delay, args.offset)
    if args.gyro_coupling is not None:
        w = w @ np.linalg.inv(gyro_coupling_matrix(args.gyro_coupling)).T
    if args.cli:
        res, Iu, cu = _estimate_cli({'t': t, 'w': w, 'a': acc, 'wheel': fw}, J0, args)
        return res, Iu, cu, combined_cog(t, w, acc), t
    if args.method == 'reference':
        Ip, x = reference_fit(s, _window_bounds(e, args.offset), J0)
        res = types.SimpleNamespace(status='-', method='authors', model='full', diagnostics={})
        return res, Ip / J0 + np.eye(3), np.zeros((6, 6)), x, t
    window = args.window
    if args.method == 'filtered' and window is None and args.cutoff_rule == 'wheel':
        # below the flywheel's lowest rotation frequency in the window: its imbalance shakes
        # the gyro at that frequency (and above), which is not rigid-body motion
        window = WHEEL_CUTOFF_MARGIN * 2.0 * math.pi / max(float(np.min(np.abs(fw))), 1.0)
    if args.prefilter:
        dt = float(np.median(np.diff(t)))
        w, fw = _lowpass(w, dt, args.prefilter), _lowpass(fw, dt, args.prefilter)
    mom = wheels_momentum(t, fw[:, None], [Wheel('flywheel', WHEEL_AXIS, J0, 0.0)])
    res = estimate_with_momentum(t, w, np.zeros(0), np.zeros((0, 3)), mom,
                                 method=args.method, model='full',
                                 torque_bias=args.torque_bias, window=window,
                                 gyro_noise=args.gyro_noise)
    if res.inertia is None or not np.all(np.isfinite(res.inertia)) or res.covariance is None:
        return res, None, np.full((6, 6), np.nan), np.full(3, np.nan), t
    return (res, np.asarray(res.inertia) / J0, np.asarray(res.covariance) / J0 ** 2,
            combined_cog(t, w, acc), t)


def gyro_coupling_matrix(c: tuple[float, float, float]) -> np.ndarray:
    """The gyro's symmetric axis coupling (non-orthogonality) ``M = 1 + C`` (3, 3), ``C`` with
    ``(xy, xz, yz)`` off the diagonal: the gyro reads ``M w``; ``bench --gyro-coupling``
    removes it (``M^-1`` on the read rates) before the estimate."""
    xy, xz, yz = (float(v) for v in c)
    return np.eye(3) + np.array([[0.0, xy, xz], [xy, 0.0, yz], [xz, yz, 0.0]])


def _window_bounds(e: dict, offset: int | None) -> tuple[int, int]:
    a0, a1 = e['fit_window']
    return (a0 if offset is None else e['throw_start'] + offset), a1


def _estimate_cli(s: dict[str, np.ndarray], J0: float, args: argparse.Namespace
                  ) -> tuple[object, np.ndarray | None, np.ndarray]:
    """One throw's window through the plain CLI: ``estimate W.mcap --wheels flywheel.yaml
    --format json`` (plus ``--method`` when given).  Returns a result-like namespace, the
    tensor in units of ``J0`` and a (6, 6) covariance from the report's element sigmas
    (the JSON report states no correlations: diagonal)."""
    import contextlib
    import io
    import tempfile

    from inertia_ros.cli import main as cli

    with tempfile.TemporaryDirectory() as d:
        mc, wy = Path(d) / 'throw.mcap', Path(d) / 'flywheel.yaml'
        write_mcap(mc, s)
        wy.write_text(_wheels_yaml(J0))
        argv = ['estimate', str(mc), '--wheels', str(wy), '--format', 'json', '--no-progress']
        if args.method not in (None, 'auto'):
            argv += ['--method', args.method]
        if args.model is not None:
            argv += ['--model', args.model]
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            code = cli(argv)
    if code != 0:
        raise SystemExit(f'estimate {" ".join(argv[1:])}: exit {code}')
    rep = json.loads(buf.getvalue())
    res = types.SimpleNamespace(status=rep['status'], method=rep['method'], model=rep['model'],
                                diagnostics=rep.get('diagnostics') or {})
    if rep.get('inertia') is None or rep.get('inertia_std') is None:
        return res, None, np.full((6, 6), np.nan)
    I = np.array(rep['inertia'], dtype=float)
    sd = _theta(np.array(rep['inertia_std'], dtype=float))
    return res, I / J0, np.diag(sd ** 2) / J0 ** 2


def _wheels_yaml(J: float) -> str:
    return ('wheels:\n  - joint: flywheel\n    axis: [0.0, 0.0, -1.0]\n'
            f'    inertia: {J!r}   # the authors\' calibration procedure on '
            'input/final_calibration\n')


def _theta(I: np.ndarray) -> np.ndarray:
    return np.array([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])


def _matrix(th: np.ndarray) -> np.ndarray:
    """(..., 6) -> (..., 3, 3)."""
    i, j = (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)
    M = np.zeros(th.shape[:-1] + (3, 3))
    for k in range(6):
        M[..., i[k], j[k]] = th[..., k]
        M[..., j[k], i[k]] = th[..., k]
    return M


def proof_body(idx: dict) -> tuple[float, np.ndarray]:
    """Mass [kg] and inertia [kg m^2] of the calibration cuboid, about its centre of mass.

    As the authors' ``input/final_calibration/config.py``: sides ``(a, b, c) = (30.2, 60,
    70) mm`` with ``Ixx = m (a^2 + c^2) / 12``, ``Iyy = m (a^2 + b^2) / 12``, ``Izz = m (b^2 +
    c^2) / 12`` (the 30.2 mm side is common to x and y, the 60 mm side lies along x).
    """
    pb = idx['proof_body']
    m = float(pb['m'])
    if 'I' in pb:
        return m, np.asarray(pb['I'], dtype=float)
    a, b, c = pb.get('dims', (0.0302, 0.06, 0.07))
    return m, m / 12.0 * np.diag([a * a + c * c, a * a + b * b, b * b + c * c])


def calibrate(idx: dict, root: Path, args: argparse.Namespace, rng: np.random.Generator,
              draws: int) -> dict:
    """The authors' calibration (``calibrate.py``) redone with this estimator.

    Device-only throws give ``I'_dev / J`` and the device's centre of mass; throws with the
    proof body (a cuboid of known mass and size) give ``I'_dev+cal / J``; ``J`` is the
    projection that makes their difference the proof body's inertia (moved to the combined
    centre of mass), as the authors do.  The calibration is only as good as the throws agree:
    the throw means are drawn ``draws`` times from their scatter (standard error of the mean)
    and every draw gives its own ``J`` and ``I_dev``, which the bench propagates.
    """
    J0 = idx['wheel']['inertia']
    sets: dict[str, list] = {'device_only': [], 'proof_body': []}
    for e in idx['logs']:
        if e.get('series') != 'final_calibration' or e.get('config') not in sets:
            continue
        p = root / e['csv']
        if not p.is_file():
            continue
        res, Iu, _, x, _ = _estimate_unit(read_throw_csv(p), e, J0, args)
        if Iu is not None:
            sets[e['config']].append((_theta(Iu - np.eye(3)), x))
    if min(len(v) for v in sets.values()) < 2:
        raise SystemExit(f'{root}: calibration throws missing (device_only '
                         f'{len(sets["device_only"])}, proof_body {len(sets["proof_body"])}); '
                         'use --calibration authors')
    m_dev, m_pb, I_pb = idx['device']['m'], *proof_body(idx)

    def draw(v: list) -> tuple[np.ndarray, np.ndarray]:
        th = np.array([a for a, _ in v])
        xs = np.array([b for _, b in v])
        n = len(v)
        return (th.mean(0) + rng.normal(size=(draws, 6)) * th.std(0, ddof=1) / np.sqrt(n),
                xs.mean(0) + rng.normal(size=(draws, 3)) * xs.std(0, ddof=1) / np.sqrt(n))

    def solve(td: np.ndarray, tc: np.ndarray, xd: np.ndarray, xc: np.ndarray
              ) -> tuple[float, np.ndarray]:
        s = xd - xc
        r = (m_dev / m_pb) * s
        left = _theta(I_pb + _steiner(m_pb, r) + _steiner(m_dev, s))
        right = tc - td
        J = float(right @ left / (right @ right))

        return J, J * td

    (td, xd), (tc, xc) = draw(sets['device_only']), draw(sets['proof_body'])
    mean = [np.mean(np.array([a for a, _ in sets[k]]), 0) for k in sets]
    xm = [np.mean(np.array([b for _, b in sets[k]]), 0) for k in sets]
    J, th_dev = solve(mean[0], mean[1], xm[0], xm[1])
    Js, devs = zip(*(solve(td[k], tc[k], xd[k], xc[k]) for k in range(draws)), strict=True)
    return {'J': J, 'I_dev': _matrix(th_dev), 'x_dev': xm[0],
            'J_draws': np.array(Js), 'I_dev_draws': _matrix(np.array(devs)),
            'x_dev_draws': xd, 'throws': {k: len(v) for k, v in sets.items()}}


# --- the authors' conventions, read from the user's checkout (``index``) ------------------

#: the authors' throw detection: the throw starts where |flywheel speed| first exceeds this
THROW_WHEEL_SPEED = 10.0
#: samples skipped after the throw start (their ``--offset``) and, in calibration, at the end
THROW_OFFSET, CAL_TAIL = 300, 50


def throw_start(wheel: np.ndarray) -> int | None:
    """First sample ``i`` whose next sample has |flywheel speed| above 10 rad/s (their rule)."""
    hit = np.nonzero(np.abs(wheel[1:]) > THROW_WHEEL_SPEED)[0]
    return int(hit[0]) if len(hit) else None


def _symmetric_basis() -> np.ndarray:
    """(6, 3, 3) basis of symmetric matrices in ``_theta`` order."""
    E = np.zeros((6, 3, 3))
    for k, (i, j) in enumerate(((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))):
        E[k, i, j] = E[k, j, i] = 1.0
    return E


def reference_fit(s: dict[str, np.ndarray], window: tuple[int, int], J: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The authors' estimator, re-stated: ``I' = I - J 1`` [kg m^2] and the combined centre of
    mass [m] from the samples ``window`` = [first, end) (rows of :func:`_pooled_rows`)."""
    A, b, C, d = _pooled_rows(s, {'fit_window': window})
    th = np.linalg.lstsq(A, J * b, rcond=None)[0]
    return _matrix(th), np.linalg.lstsq(C, d, rcond=None)[0]


def _cross_matrix(v: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) with ``M v' = v x v'``."""
    M = np.zeros(v.shape[:-1] + (3, 3))
    M[..., 0, 1], M[..., 0, 2], M[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return M - np.swapaxes(M, -1, -2)


def _authors_namespace(repo: Path) -> dict:
    """Run the checkout's ``lib.calcGridObject`` (and the helpers it calls) with numpy only:
    the functions' source is taken from the user's ``lib.py`` (which imports plotting and
    data packages at the top, not needed here)."""
    import ast

    src = (repo / 'lib.py').read_text()
    keep = {'calcGridObject', 'parallelAxisTheorem', 'kroneckerDelta'}
    tree = ast.parse(src)
    body = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name in keep]
    if {n.name for n in body} != keep:
        raise SystemExit(f'{repo / "lib.py"}: {sorted(keep)} not all found; is --repo the '
                         'tudelft/inertiaEstimation checkout?')
    ns: dict = {'np': np}
    exec(compile(ast.Module(body=body, type_ignores=[]), str(repo / 'lib.py'), 'exec'), ns)
    return ns


def _run_config(path: Path, lib_ns: dict) -> dict:
    """The variables of one of the authors' ``config.py`` (``lib`` as the numpy-only subset)."""
    import types

    lib = types.ModuleType('lib')
    lib.__dict__.update(lib_ns)
    ns: dict = {'__name__': 'config', '__file__': str(path)}
    saved = sys.modules.get('lib')
    sys.modules['lib'] = lib
    try:
        exec(compile(path.read_text(), str(path), 'exec'), ns)
    finally:
        if saved is None:
            sys.modules.pop('lib', None)
        else:
            sys.modules['lib'] = saved
    return ns


def _index_entry(log: Path, repo: Path, out: Path, series: str, config: str,
                 tail: int = 0) -> tuple[dict, dict] | None:
    """Decode one log, write its converted CSV and return its index entry and samples."""
    s = read_throw_csv(log)
    start = throw_start(s['wheel'])
    if start is None:
        print(f'{log}: no throw detected (flywheel never above {THROW_WHEEL_SPEED} rad/s); '
              'skipped', file=sys.stderr)
        return None
    name = f'{series}_{config}_{log.stem}.csv'
    write_csv(out / name, s)
    n = len(s['t'])
    e = {'csv': name, 'series': series, 'config': config,
         'source': str(log.relative_to(repo)), 'throw_start': start,
         'fit_window': [start + THROW_OFFSET, n - tail]}
    return e, s


def authors_calibration(cal: list[tuple[dict, dict]], cfg: dict) -> dict:
    """The authors' ``calibrate.py`` re-stated: pooled fits with ``J = 1`` of the device-only
    and the proof-body throws (each window ``[start + 300, end - 50)``), ``J`` the projection
    that makes their difference the proof body's tensor moved to the combined centre of
    mass; the device tensor is the device-only fit times ``J``."""
    fits = {}
    for kind in ('device_only', 'proof_body'):
        rows = [(s, e) for e, s in cal if e['config'] == kind]
        if not rows:
            raise SystemExit(f'final_calibration/{kind}: no throws found')
        parts = [_pooled_rows(s, e) for s, e in rows]
        A = np.concatenate([p[0] for p in parts])
        b = np.concatenate([p[1] for p in parts])
        C = np.concatenate([p[2] for p in parts])
        d = np.concatenate([p[3] for p in parts])
        fits[kind] = (np.linalg.lstsq(A, b, rcond=None)[0],
                      np.linalg.lstsq(C, d, rcond=None)[0])
    (td, xd), (tc, xc) = fits['device_only'], fits['proof_body']
    m_dev, m_pb = float(cfg['m_dev']), float(cfg['m_obj'])
    sv = xd - xc
    left = _theta(np.asarray(cfg['I_obj'], dtype=float) + _steiner(m_pb, m_dev / m_pb * sv)
                  + _steiner(m_dev, sv))
    right = tc - td
    J = float(right @ left / (right @ right))
    return {'J': J, 'I_dev': _matrix(J * td), 'x_dev': xd, 'm_dev': m_dev}


def _pooled_rows(s: dict, e: dict) -> tuple[np.ndarray, ...]:
    """One throw's regression rows in the authors' form (J = 1): inertia ``(A, b)``, centre
    of mass ``(C, d)``.

    Zero-phase 4th-order 20 Hz Butterworth on gyro, flywheel speed and accelerometer over the
    whole record; the derivatives by central differences of the raw signals, then the same
    filter; the sample step is the record's mean.  ``A theta = b`` is ``I' w' + w x (I' w) =
    -(w x (w + f) + w' + f')`` with ``f`` the flywheel's velocity relative to the body and
    ``I' = I - J 1``; ``C x = d`` is ``-a = w' x x + w x (w x x)``; both over the samples
    ``e['fit_window']``.
    """
    t, w = s['t'], s['w']
    dt = float(t[-1] - t[0]) / len(t)
    f = s['wheel'][:, None] * np.array(WHEEL_AXIS)
    sl = slice(*e['fit_window'])
    wf, ff = _lowpass(w, dt)[sl], _lowpass(f, dt)[sl]
    wd = _lowpass(np.gradient(w, dt, axis=0), dt)[sl]
    fd = _lowpass(np.gradient(f, dt, axis=0), dt)[sl]
    E = _symmetric_basis()
    A = (np.einsum('kij,nj->nik', E, wd)
         + np.cross(wf[:, :, None], np.einsum('kij,nj->nik', E, wf), axis=1))
    b = -(np.cross(wf, wf + ff) + wd + fd)
    af = _lowpass(s['a'], dt)[sl]
    C = _cross_matrix(wd) + np.einsum('nij,njk->nik', _cross_matrix(wf), _cross_matrix(wf))
    return A.reshape(-1, 6), b.reshape(-1), C.reshape(-1, 3), -af.reshape(-1)


def index(args: argparse.Namespace) -> int:
    """``index``: decode the checkout's logs, write their CSVs and ``index.json``."""
    repo, out = Path(args.repo), Path(args.out)
    tests = sorted((repo / 'input' / 'final_tests').glob('config_*/config.py'))
    if not tests:
        raise SystemExit(f'{repo}: no input/final_tests/config_*/config.py; is --repo the '
                         'tudelft/inertiaEstimation checkout?')
    out.mkdir(parents=True, exist_ok=True)
    lib_ns = _authors_namespace(repo)
    logs, cal = [], []
    for kind in ('device_only', 'proof_body'):
        for log in sorted((repo / 'input' / 'final_calibration' / kind).glob('*.BFL')):
            r = _index_entry(log, repo, out, 'final_calibration', kind, tail=CAL_TAIL)
            if r:
                logs.append(r[0])
                cal.append(r)
    cfg = _run_config(repo / 'input' / 'final_calibration' / 'config.py', lib_ns)
    c = authors_calibration(cal, cfg)
    for conf in tests:
        ns = _run_config(conf, lib_ns)
        truth = {'m': float(ns['m_obj']), 'cog': np.asarray(ns['x_obj']).ravel().tolist(),
                 'I': np.asarray(ns['I_obj'], dtype=float).tolist()}
        for log in sorted(conf.parent.glob('*.BFL')):   # not archive/: the authors' set
            r = _index_entry(log, repo, out, 'final_tests', str(ns['name']))
            if r:
                logs.append({**r[0], 'truth_object': truth})
        print(f'{conf.parent.name}: {ns["name"]}, m {truth["m"]:.4f} kg', flush=True)
    idx = {'source': str(repo), 'wheel': {'axis': list(WHEEL_AXIS), 'inertia': c['J']},
           'device': {'m': c['m_dev'], 'x': c['x_dev'].tolist(), 'I_prime': c['I_dev'].tolist()},
           'proof_body': {'m': float(cfg['m_obj']),
                          'I': np.asarray(cfg['I_obj'], dtype=float).tolist()},
           'logs': logs}
    (out / 'index.json').write_text(json.dumps(idx, indent=1))
    print(f"{out / 'index.json'}: {len(logs)} throws; flywheel J {c['J']:.6g} kg m^2 (the "
          "authors' calibration procedure)")
    return 0


def _read_index(path: str) -> dict:
    """``index.json`` as written by ``index`` (a one-line exit when it cannot be read)."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise SystemExit(f'{path}: cannot read the throws index ({exc.__class__.__name__}); '
                         'write it with: tudelft_throw.py index --repo CHECKOUT --out DIR'
                         ) from None


def bench(args: argparse.Namespace) -> int:
    if args.method is None and not args.cli:
        args.method = 'filtered'
    idx = _read_index(args.index)
    root = Path(args.csv_root)
    rng = np.random.default_rng(args.seed)
    draws = args.draws
    J0 = idx['wheel']['inertia']
    dev = idx['device']
    if args.calibration == 'ours':
        cal = calibrate(idx, root, args, rng, draws)
        print(f"calibration (this estimator, {cal['throws']} throws): J = {cal['J']:.5g} kg m^2 "
              f"+- {100 * np.std(cal['J_draws']) / cal['J']:.2f} % (authors' {J0:.5g}); "
              f"I_dev diag {np.round(np.diag(cal['I_dev']) * 1e6, 2)} g cm^2 x 100 "
              f"(authors' {np.round(np.diag(np.array(dev['I_prime'])) * 1e6, 2)})", flush=True)
    else:
        rel = args.wheel_inertia_rel_std
        cal = {'J': J0, 'I_dev': np.array(dev['I_prime']), 'x_dev': np.array(dev['x']),
               'J_draws': J0 * (1.0 + rel * rng.normal(size=draws)),
               'I_dev_draws': np.repeat(np.array(dev['I_prime'])[None], draws, 0),
               'x_dev_draws': np.repeat(np.array(dev['x'])[None], draws, 0)}
    out = []
    tests = [e for e in idx['logs'] if e.get('series', 'final_tests') == 'final_tests']
    for e in tests[::args.every]:
        p = root / e['csv']
        if not p.is_file():
            continue
        res, Iu, cu, xt, t = _estimate_unit(read_throw_csv(p), e, J0, args)
        row: dict = {'config': e['config'], 'log': p.stem, 'status': res.status,
                     'method': res.method, 'model': res.model,
                     'cutoff_hz': res.diagnostics.get('filter_cutoff_hz')}
        adq = res.diagnostics.get('adequacy')
        if isinstance(adq, dict):
            row['adequacy'] = {k: adq.get(k) for k in ('covariance', 'sigma_widened_by',
                                                       'windows', 'residual_excess')}
        sel = res.diagnostics.get('method_selection')
        if isinstance(sel, dict):
            row['candidates'] = {k: v.get('status') for k, v in
                                 (sel.get('candidates') or {}).items() if isinstance(v, dict)}
        if Iu is not None:
            row.update(body=_theta(Iu * J0).tolist(),
                       body_std=(np.sqrt(np.diag(cu)) * J0).tolist())
            tr = e['truth_object']
            m, It = tr['m'], np.array(tr['I'])

            def obj(Iu_: np.ndarray, J: float, I_dev: np.ndarray, xd: np.ndarray,
                    m: float = m, xt: np.ndarray = xt) -> np.ndarray:
                return object_inertia(J * (Iu_ - np.eye(3)), I_dev, dev['m'], xd, m, xt)

            I_obj = obj(Iu, cal['J'], cal['I_dev'], cal['x_dev'])
            # sigma: the throw's own covariance and the calibration's draws, together
            th = _theta(Iu) + rng.multivariate_normal(np.zeros(6), 0.5 * (cu + cu.T),
                                                      size=draws, method='eigh')
            Is = _matrix(th)
            lam_d = np.array([np.linalg.eigvalsh(obj(Is[k], cal['J_draws'][k],
                                                     cal['I_dev_draws'][k],
                                                     cal['x_dev_draws'][k]))
                              for k in range(draws)])
            lam = np.linalg.eigvalsh(I_obj)
            lam_t = np.linalg.eigvalsh(It)
            mstd = lam_d.std(0, ddof=1)
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
    summary(out)
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))
    return 0


def summary(out: list[dict]) -> None:
    """Print the acceptance figures of a bench run (per configuration and over all throws)."""
    ok = [r for r in out if 'eps' in r]
    if not ok:
        print('no throw gave a tensor')
        return
    for name in sorted({r['config'] for r in ok}) + ['all']:
        rows = [r for r in ok if name in ('all', r['config'])]
        E = np.array([r['eps'] for r in rows])
        F = np.array([r['fro'] for r in rows])
        Z = np.concatenate([r['z'] for r in rows])
        n_ok = sum(1 for r in rows if r['status'] == 'ok')
        print(f'{name:<12} throws {len(rows)}, ok {n_ok}; eps median {100 * np.median(E):.2f} '
              f'% mean {100 * E.mean():.2f} % max {100 * E.max():.2f} %; Frobenius median '
              f'{100 * np.median(F):.2f} %; Psi mean '
              f"{np.mean([r['psi_deg'] for r in rows]):.1f} deg; moments within 3 sigma "
              f'{np.mean(np.abs(Z) <= 3):.0%}; ok with eps > 10 %: '
              f"{sum(1 for r in rows if r['status'] == 'ok' and r['eps'] > 0.10)}"
              + _scatter_text(rows))


def scatter_ratio(rows: list[dict]) -> np.ndarray:
    """Throw-to-throw scatter / median reported sigma of the whole body's tensor elements
    (xx, yy, zz, xy, xz, yz) over throws of one configuration (the same body: its tensor does
    not change from throw to throw); (6,), NaN without sigmas or with fewer than 3 throws."""
    B = np.array([r['body'] for r in rows if 'body' in r])
    S = np.array([r['body_std'] for r in rows if 'body' in r])
    if len(B) < 3 or not np.all(np.median(S, 0) > 0):
        return np.full(6, np.nan)
    return B.std(0, ddof=1) / np.median(S, 0)


def _scatter_text(rows: list[dict]) -> str:
    if len({r['config'] for r in rows}) != 1:
        return ''
    q = scatter_ratio(rows)
    return '' if np.isnan(q).all() else f'; scatter/sigma (body xx..yz) {np.round(q, 2)}'


def convert(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    J = args.flywheel_inertia
    idx = _read_index(args.window_index) if args.window_index else None
    if idx and J is None:
        J = idx['wheel']['inertia']
    (out / 'flywheel.yaml').write_text(_wheels_yaml(J if J is not None else DEFAULT_J))
    windows = {Path(e['csv']).stem: e for e in idx['logs']} if idx else {}
    for c in args.csv:
        p = Path(c)
        s = read_throw_csv(p)
        if windows:
            if p.stem not in windows:
                raise SystemExit(f'{p}: not in {args.window_index}; convert it without '
                                 '--window-index')
            a0, a1 = windows[p.stem]['fit_window']
            s = {k: v[a0:a1] for k, v in s.items()}
        write_mcap(out / f'{p.stem}.mcap', s)
        print(f'{out / (p.stem + ".mcap")}: {len(s["t"])} samples')
    return 0


def _coupling(text: str) -> tuple[float, float, float]:
    """``--gyro-coupling XY,XZ,YZ``: three numbers (argparse type)."""
    try:
        v = tuple(float(x) for x in text.split(','))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) and abs(x) < 0.2 for x in v):
        raise argparse.ArgumentTypeError(f'{text!r}: give three couplings XY,XZ,YZ, each '
                                         'below 0.2 in size (0.005 = 0.5 %)')
    return v  # type: ignore[return-value]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    sub = ap.add_subparsers(dest='cmd', required=True)
    c = sub.add_parser('convert', help='CSV -> MCAP (+ flywheel.yaml)')
    c.add_argument('csv', nargs='+')
    c.add_argument('--out', required=True)
    c.add_argument('--flywheel-inertia', type=float, default=None,
                   help="kg m^2 (default: the index's, else the authors' published "
                        f'{DEFAULT_J:.6g})')
    c.add_argument('--window-index', default=None,
                   help="index.json: cut each throw to its fit window (the authors' rule) "
                        'and take the flywheel J from it')
    c.set_defaults(func=convert)
    b = sub.add_parser('bench', help='estimate every throw and compare with the truth')
    b.add_argument('--csv-root', required=True)
    b.add_argument('--index', required=True)
    b.add_argument('--method', default=None,
                   help='estimation method (default: filtered with the cutoff from '
                        "--cutoff-rule; with --cli the CLI's default); 'reference': the "
                        "authors' pipeline re-stated (20 Hz filter, differences, OLS)")
    b.add_argument('--torque-bias', default='off')
    b.add_argument('--window', type=float, default=None,
                   help='window [s] of the method (filtered: the filter time constant)')
    b.add_argument('--calibration', choices=('authors', 'ours'), default='authors',
                   help="flywheel J and device inertia: the authors' published values "
                        "(default: only the estimator differs from their pipeline), or their "
                        "calibrate.py procedure redone with this estimator on "
                        "input/final_calibration")
    b.add_argument('--wheel-inertia-rel-std', type=float, default=0.005,
                   help="relative one-sigma of the authors' J (--calibration authors; default "
                        "0.5 %%: their proof-body reproduction)")
    b.add_argument('--delay', type=float, default=0.0,
                   help='flywheel telemetry delay [s] behind the gyro (read the speed that '
                        'much later)')
    b.add_argument('--draws', type=int, default=400,
                   help='Monte Carlo draws of the calibration and estimate uncertainty')
    b.add_argument('--seed', type=int, default=0)
    b.add_argument('--gyro-noise', type=float, default=None,
                   help='gyro white-noise std [rad/s] (default: from the data)')
    b.add_argument('--every', type=int, default=1, help='every n-th test throw only')
    b.add_argument('--offset', type=int, default=None,
                   help="window start in samples after the throw start (default: the index's "
                        "fit_window, the authors' 300)")
    b.add_argument('--cutoff-rule', choices=('wheel', 'data'), default='wheel',
                   help="filtered method without --window: cutoff below the flywheel's lowest "
                        "rotation frequency (wheel, default) or the estimator's own choice")
    b.add_argument('--prefilter', type=float, default=0.0,
                   help='zero-phase 4th-order Butterworth cutoff [Hz] on gyro and flywheel '
                        'speed before the estimate (0: none; the authors use 20 Hz)')
    b.add_argument('--gyro-coupling', type=_coupling, default=None, metavar='XY,XZ,YZ',
                   help="remove a symmetric gyro axis coupling (non-orthogonality, e.g. "
                        "0.0057,0,0.0027) from the rates before the estimate (a diagnosis: the "
                        'value is measured, not known)')
    b.add_argument('--model', default=None, choices=('auto', 'full', 'diagonal'),
                   help="with --cli: pass --model to the CLI (default: the CLI's, auto)")
    b.add_argument('--cli', action='store_true',
                   help='estimate each window through the plain CLI (estimate W.mcap --wheels '
                        'flywheel.yaml, defaults only; --method if given); --window, '
                        '--cutoff-rule, --prefilter, --torque-bias do not apply')
    b.add_argument('--out')
    b.set_defaults(func=bench)
    x = sub.add_parser('index', help="decode the authors' checkout (BFL, needs orangebox) "
                                     'into CSVs and index.json')
    x.add_argument('--repo', required=True,
                   help='checkout of github.com/tudelft/inertiaEstimation (read only)')
    x.add_argument('--out', required=True, help='directory for the CSVs and index.json')
    x.set_defaults(func=index)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == '__main__':
    sys.exit(main())
