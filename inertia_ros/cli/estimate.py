"""``python -m inertia_ros estimate PATH``: the inertia tensor from a recorded log.

Reads a single ``.mcap`` file or a rosbag2 directory (:func:`inertia_ros.io.logs.read_log`),
estimates the tensor (:func:`inertia_ros.core.estimation.estimate`) and prints a report:
``--format text`` (default) for a person, ``--format json`` the DESIGN.md contract.  Exit status
0 whenever a report was produced, whatever its status; 2 with one line on stderr for unusable
input.  The input is only ever read.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from inertia_ros.cli import UserError
from inertia_ros.core.estimation import HOLDS, METHODS, MODELS, TORQUE_BIAS, estimate
from inertia_ros.core.estimation.result import InertiaEstimate, to_jsonable
from inertia_ros.core.inertia import matrix_to_theta
from inertia_ros.io.logs import LogData, LogError, log_files, read_log

#: What each status means, for the text report.
STATUS_TEXT = {
    'ok': 'all six tensor elements identified',
    'scale_unobservable': 'torque-free data: the principal axes and the ratios of the moments '
                          'are known, the scale is not (record with a known torque to get it)',
    'partially_identifiable': 'some elements could not be identified (shown as n/a); excite '
                              'rotation about more axes',
    'insufficient_excitation': 'the motion does not excite the dynamics enough; rotate about '
                               'all three axes with changing rates',
    'insufficient_data': 'too few usable samples to estimate anything',
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``estimate`` sub-command."""
    p = sub.add_parser(
        'estimate', help='estimate the inertia tensor from a recorded MCAP log',
        description='Estimate the inertia tensor from a recorded log (a .mcap file or a '
                    'rosbag2 directory) of angular velocity and known torque.')
    p.add_argument('path', metavar='PATH', help='.mcap file or rosbag2 directory (read only)')
    p.add_argument('--omega-topic', metavar='T',
                   help='angular-velocity topic (Imu, Vector3Stamped or TwistStamped); found '
                        'by type when omitted')
    p.add_argument('--torque-topic', metavar='T',
                   help='torque topic (WrenchStamped or Vector3Stamped); found by type when '
                        'omitted; "none" for torque-free data (no torque stream)')
    p.add_argument('--model', choices=MODELS, default='auto',
                   help='parameter set (default auto: the smallest the data supports)')
    p.add_argument('--symmetry-axis', choices=('x', 'y', 'z'),
                   help='body symmetry axis (needed by --model axisymmetric)')
    p.add_argument('--torque-bias', choices=TORQUE_BIAS, default='auto',
                   help='estimate a constant unmeasured disturbance torque (default auto)')
    p.add_argument('--method', choices=METHODS, default='auto',
                   help='estimator (default auto: maximum likelihood (ml) up to 100k gyro '
                        'samples, integral beyond)')
    p.add_argument('--hold', choices=HOLDS, default='zoh',
                   help='torque between samples: zero-order hold or linear (default zoh)')
    p.add_argument('--torque-delay', type=float, default=0.0, metavar='S',
                   help='torque stamps lag the applied torque by S seconds (default 0)')
    p.add_argument('--ignore-frames', action='store_true',
                   help='accept different header.frame_id values on the two streams')
    p.add_argument('--format', choices=('text', 'json'), default='text',
                   help='report format (default text)')
    p.add_argument('-o', '--output', metavar='FILE', type=Path,
                   help='write the report to FILE instead of stdout')
    p.add_argument('--plot', metavar='FILE.png', type=Path,
                   help='also draw torque fit, convergence and principal axes to FILE.png')
    p.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')
    p.set_defaults(func=run)


# --------------------------------------------------------------------------------------------


class _Progress:
    """A one-line progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.last = 0.0
        self.shown = False

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or total <= 0:
            return
        now = time.monotonic()
        if now - self.last < 0.1 and done < total:
            return
        self.last = now
        frac = min(done / total, 1.0)
        bar = '#' * int(30 * frac)
        sys.stderr.write(f'\rreading [{bar:<30s}] {100 * frac:5.1f}% '
                         f'{done / 1e6:7.1f}/{total / 1e6:.1f} MB')
        sys.stderr.flush()
        self.shown = True

    def note(self, text: str) -> None:
        """Show a one-line status (e.g. while estimating)."""
        if self.enabled:
            sys.stderr.write('\r' + text[:72].ljust(72))
            sys.stderr.flush()
            self.shown = True

    def close(self) -> None:
        if self.shown:
            sys.stderr.write('\r' + ' ' * 72 + '\r')
            sys.stderr.flush()


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse outputs that would overwrite the input."""
    src = Path(args.path)
    try:
        inputs = {p.resolve() for p in log_files(src)} if src.exists() else set()
    except LogError:
        inputs = set()
    inputs.add(src.resolve())
    if src.is_dir():
        inputs.add((src / 'metadata.yaml').resolve())
    for opt, out in (('-o', args.output), ('--plot', args.plot)):
        if out is None:
            continue
        if out.resolve() in inputs:
            raise UserError(f'{opt} {out}: refusing to overwrite the input log')
        if out.is_dir():
            raise UserError(f'{opt} {out}: is a directory; give a file name')


def run(args: argparse.Namespace) -> int:
    """Run the command; return the exit status."""
    _check_outputs(args)
    progress = _Progress(sys.stderr.isatty() and not args.no_progress)
    try:
        log = read_log(args.path, args.omega_topic, args.torque_topic,
                       ignore_frames=args.ignore_frames, torque_delay=args.torque_delay,
                       progress=progress)
    except (LogError, ValueError) as exc:
        progress.close()
        raise UserError(str(exc)) from None
    if args.model == 'axisymmetric' and args.symmetry_axis is None:
        progress.close()
        raise UserError('--model axisymmetric needs --symmetry-axis x|y|z')
    progress.note(f'estimating ({log.omega.t.size} gyro, {log.torque.t.size} torque samples)')
    try:
        est = estimate(log.omega.t, log.omega.values, log.torque.t, log.torque.values,
                       method=args.method, model=args.model, torque_bias=args.torque_bias,
                       hold=args.hold, symmetry_axis=args.symmetry_axis)
    except ValueError as exc:
        raise UserError(f'{args.path}: cannot estimate: {exc}') from None
    finally:
        progress.close()
    report = build_report(est, log, args)
    text = (json.dumps(report, indent=2, allow_nan=False) + '\n' if args.format == 'json'
            else format_text(report, log))
    if args.output is not None:
        try:
            args.output.write_text(text)
        except OSError as exc:
            raise UserError(f'-o {args.output}: {exc.strerror}') from None
    else:
        sys.stdout.write(text)
    if args.plot is not None:
        try:
            plot_report(args.plot, est, log, args)
        except OSError as exc:
            raise UserError(f'--plot {args.plot}: {exc.strerror}') from None
    return 0


# --------------------------------------------------------------------------------------------
# Report


def build_report(est: InertiaEstimate, log: LogData, args: argparse.Namespace) -> dict:
    """The JSON contract of DESIGN.md, with the log's facts under ``diagnostics``.

    ``samples.used`` counts the gyro samples in the equations; ``samples.dropped`` counts the
    gyro messages left out, by cleaning (NaN, duplicates, outside the torque coverage, ...)
    and by the estimator.
    """
    d = est.to_dict()
    diag = d.setdefault('diagnostics', {}) or {}
    d['diagnostics'] = diag
    warnings = list(diag.get('warnings') or [])
    warnings = log.warnings + [w for w in warnings if w not in log.warnings]
    diag['warnings'] = warnings
    diag['log'] = to_jsonable(log.summary())
    diag['frame_id'] = log.omega.frame_id
    diag['torque_delay_s'] = float(args.torque_delay)
    diag['hold'] = args.hold
    d['samples'] = {'used': int(est.samples_used),
                    'dropped': int(est.samples_dropped + log.omega.counts.dropped)}
    if log.truth:
        diag['truth'] = _truth_check(est, log)
    return d


def _truth_check(est: InertiaEstimate, log: LogData) -> dict[str, Any]:
    """Compare with the true tensor recorded in the log (simulated logs)."""
    truth = log.truth[0][1]
    out: dict[str, Any] = {'inertia': to_jsonable(truth),
                           'changes': len(log.truth) - 1}
    if est.inertia is not None and np.isfinite(est.inertia).all():
        err = est.inertia - truth
        out['max_abs_error'] = float(np.max(np.abs(err)))
        out['relative_error'] = float(np.linalg.norm(err) / np.linalg.norm(truth))
    if est.ratios is not None and np.isfinite(est.ratios).all():
        r = truth / np.trace(truth)
        out['ratios_max_abs_error'] = float(np.max(np.abs(est.ratios - r)))
    return out


def _fmt(x: float | None, std: float | None = None) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return f'{"n/a":>22s}'
    if std is None:
        return f'{x:>11.6g}' + ' ' * 11
    return f'{x:>11.6g} ± {std:<8.2g}'


def format_text(report: dict, log: LogData) -> str:
    """A short human-readable report."""
    lines = []
    s = report['diagnostics']['log']
    lines.append(f'inertia_ros estimate: {", ".join(s["files"])}')
    for key, label in (('omega', 'gyro  '), ('torque', 'torque')):
        st = s[key]
        rate = f'{st["rate_hz"]:.1f} Hz' if st['rate_hz'] else 'rate n/a'
        lines.append(f'  {label} {st["topic"]} ({st["type"]}, frame {st["frame_id"]!r}, '
                     f'{rate}): {st["received"]} received, {st["used"]} used, '
                     f'{st["dropped"]} dropped')
    lines.append(f'  method {report["method"]}, model {report["model"]}; '
                 f'{report["samples"]["used"]} gyro samples in the equations, '
                 f'{report["samples"]["dropped"]} left out; {s["windows"]} window(s)')
    lines.append('')
    lines.append(f'status: {report["status"]} - {STATUS_TEXT.get(report["status"], "")}')
    frame = report['diagnostics'].get('frame_id', '')
    inertia, std = report['inertia'], report['inertia_std']
    if inertia is not None:
        lines.append('')
        lines.append(f'inertia tensor about the centre of mass, frame {frame!r} [kg m^2] '
                     '(± one sigma):')
        for i in range(3):
            lines.append('  [' + '  '.join(
                _fmt(inertia[i][j], None if std is None else std[i][j]) for j in range(3))
                + ' ]')
    elif report['ratios'] is not None:
        lines.append('')
        lines.append('inertia / trace (ratios; the scale is unobservable) (± one sigma):')
        rstd = report.get('ratios_std')
        for i, row in enumerate(report['ratios']):
            lines.append('  [' + '  '.join(
                _fmt(v, None if rstd is None else rstd[i][j]) for j, v in enumerate(row))
                + ' ]')
        pr = report['diagnostics'].get('principal_ratios')
        if pr is not None:
            pr_std = report['diagnostics'].get('principal_ratios_std') or [None] * 3
            lines.append('principal moments / trace: ' + ', '.join(
                f'I{k + 1} = {_fmt(v, e).strip()}'
                for k, (v, e) in enumerate(zip(pr, pr_std, strict=True))))
    if report['principal_moments'] is not None:
        m = report['principal_moments']
        lines.append('')
        m_std = report['diagnostics'].get('principal_moments_std') or [None] * 3
        lines.append('principal moments [kg m^2]: ' + ', '.join(
            f'I{k + 1} = {_fmt(v, e).strip()}' for k, (v, e) in enumerate(zip(m, m_std,
                                                                             strict=True))))
    if report['principal_axes'] is not None:
        a = np.array(report['principal_axes'], dtype=float)
        a_std = report['diagnostics'].get('principal_axes_std') or [None] * 3
        lines.append('principal axes (unit vectors in the gyro frame, ± one-sigma angle):')
        for k in range(3):
            err = ('' if a_std[k] is None else
                   f'  ± {math.degrees(a_std[k]):.2g} deg')
            lines.append(f'  axis {k + 1}: [{a[0, k]: .4f} {a[1, k]: .4f} {a[2, k]: .4f}]'
                         + err)
    if report['torque_bias'] is not None:
        b = report['torque_bias']
        lines.append(f'disturbance torque (estimated bias) [N m]: '
                     f'[{b[0]:.4g} {b[1]:.4g} {b[2]:.4g}]')
    diag = report['diagnostics']
    facts = []
    for key in ('condition_number', 'residual_rms'):
        if key in diag and diag[key] is not None:
            facts.append(f'{key.replace("_", " ")} {_short(diag[key])}')
    if facts:
        lines.append('diagnostics: ' + ', '.join(facts))
    truth = diag.get('truth')
    if truth and 'relative_error' in truth:
        lines.append(f'recorded truth: relative error {100 * truth["relative_error"]:.3g}% '
                     f'(max abs {truth["max_abs_error"]:.3g} kg m^2)')
    if diag.get('warnings'):
        lines.append('')
        lines.append('warnings:')
        lines.extend(f'  - {w}' for w in diag['warnings'])
    return '\n'.join(lines) + '\n'


def _short(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        return '[' + ' '.join(_short(x) for x in v) + ']'
    if isinstance(v, float):
        return f'{v:.3g}'
    return str(v)


# --------------------------------------------------------------------------------------------
# Plot


def _window_torques(est: InertiaEstimate, tg: np.ndarray, w: np.ndarray, tt: np.ndarray,
                    tau: np.ndarray, hold: str, width: float = 0.25
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured and model torque averaged over sliding windows of ``width`` seconds.

    The model side is the momentum form, ``(I w(b) - I w(a) + int_a^b w x I w dt) / (b - a)``
    (minus the bias), the measured side ``int_a^b tau dt / (b - a)``: the same filter on both
    sides, so differentiation noise does not swamp the picture.

    Returns
    -------
    t_mid : (K,) window centres [s]; measured, model : (K, 3) [N m]
    """
    from inertia_ros.core.inertia import angular_momentum

    inertia = np.asarray(est.inertia)
    L = angular_momentum(inertia, w)
    gyro = np.cross(w, L)
    dt = np.diff(tg)
    G = np.concatenate((np.zeros((1, 3)), np.cumsum(0.5 * (gyro[1:] + gyro[:-1]) * dt[:, None],
                                                    axis=0)))
    if hold == 'zoh':
        j = np.clip(np.searchsorted(tt, tg[:-1], side='right') - 1, 0, len(tt) - 1)
        seg = tau[j]
    else:
        mid = 0.5 * (tg[1:] + tg[:-1])
        seg = np.stack([np.interp(mid, tt, tau[:, k]) for k in range(3)], axis=1)
    T = np.concatenate((np.zeros((1, 3)), np.cumsum(seg * dt[:, None], axis=0)))
    k = max(1, int(round(width / float(np.median(dt)))))
    if len(tg) <= k:
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
    span = (tg[k:] - tg[:-k])[:, None]
    model = (L[k:] - L[:-k] + G[k:] - G[:-k]) / span
    if est.torque_bias is not None:
        model = model - np.asarray(est.torque_bias)
    meas = (T[k:] - T[:-k]) / span
    # windows spanning a gap are meaningless
    ok = span[:, 0] < 1.5 * width + 1e-9
    return 0.5 * (tg[k:] + tg[:-k])[ok], meas[ok], model[ok]


def plot_report(path: Path, est: InertiaEstimate, log: LogData,
                args: argparse.Namespace) -> None:
    """Draw measured vs model torque (with residuals), convergence, and principal axes."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    tg, w = log.omega.t, log.omega.values
    tt, tau = log.torque.t, log.torque.values
    fig = plt.figure(figsize=(14, 9), layout='constrained')
    gs = fig.add_gridspec(4, 2, width_ratios=[1.6, 1])
    have_model = est.inertia is not None and bool(np.isfinite(est.inertia).all())
    if have_model:
        width = float(np.clip((tg[-1] - tg[0]) / 60.0, 0.25, 2.0))
        t_mid, meas, model = _window_torques(est, tg, w, tt, tau, args.hold, width)
        resid = meas - model
        step = max(1, len(t_mid) // 20000)
    ax0 = None
    for k, name in enumerate('xyz'):
        ax = fig.add_subplot(gs[k, 0], sharex=ax0)
        ax0 = ax0 or ax
        if have_model:
            ax.plot(t_mid[::step], meas[::step, k], lw=0.9, label='measured')
            ax.plot(t_mid[::step], model[::step, k], lw=0.9, alpha=0.8, ls='--',
                    label='model')
            ax.plot(t_mid[::step], resid[::step, k], lw=0.7, color='tab:red', alpha=0.8,
                    label='residual')
        else:
            st = max(1, len(tt) // 20000)
            ax.plot(tt[::st], tau[::st, k], lw=0.8, label='measured')
        ax.set_ylabel(f'torque {name} [N m]')
        if k == 0 and have_model:
            ax.set_title(f'torque, {width:.3g} s window means: measured vs model '
                         '(I dw/dt + w x I w' + (' - bias' if est.torque_bias is not None
                                                  else '') + ') and residual')
        elif k == 0:
            ax.set_title(f'measured torque (no model torque: status {est.status})')
        if k == 0 and (have_model or len(tt)):
            ax.legend(loc='upper right', fontsize=8)
    ax = fig.add_subplot(gs[3, 0], sharex=ax0)
    step = max(1, len(tg) // 20000)
    for k, name in enumerate('xyz'):
        ax.plot(tg[::step], w[::step, k], lw=0.8, label=f'w{name}')
    ax.set_ylabel('omega [rad/s]')
    ax.set_xlabel(f'time [s] since stamp {log.epoch_ns} ns')
    ax.legend(loc='upper right', fontsize=8)

    # convergence: the estimate on growing prefixes of the log, +-2 sigma
    axc = fig.add_subplot(gs[0:2, 1])
    fracs = np.array([0.1, 0.2, 0.35, 0.5, 0.75, 1.0])
    span = tg[-1] - tg[0]
    rows = []
    for f in fracs:
        t_end = tg[0] + f * span
        mg, mt = tg <= t_end, tt <= t_end
        if mg.sum() < 20 or (len(tt) and mt.sum() < 2):
            continue
        try:
            e = est if f == 1.0 else estimate(
                tg[mg], w[mg], tt[mt], tau[mt], method=args.method, model=args.model,
                torque_bias=args.torque_bias, hold=args.hold,
                symmetry_axis=args.symmetry_axis)
        except ValueError:
            continue
        if e.inertia is not None:
            th = e.theta
            sd = e.theta_std if e.theta_std is not None else np.full(6, np.nan)
        elif e.ratios is not None:  # scale unobservable: the ratios converge instead
            th = matrix_to_theta(e.ratios)
            sd = (matrix_to_theta(e.ratios_std) if e.ratios_std is not None
                  else np.full(6, np.nan))
        else:
            continue
        rows.append((t_end - tg[0], th, sd))
    names = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')
    if rows:
        tx = np.array([r[0] for r in rows])
        th = np.array([r[1] for r in rows])
        sd = np.array([r[2] for r in rows])
        for k in range(6):
            line, = axc.plot(tx, th[:, k], marker='o', ms=3, label=names[k])
            axc.fill_between(tx, th[:, k] - 2 * sd[:, k], th[:, k] + 2 * sd[:, k],
                             color=line.get_color(), alpha=0.2)
        if log.truth:
            tr = log.truth[0][1] if est.inertia is not None else (
                log.truth[0][1] / np.trace(log.truth[0][1]))
            for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)):
                axc.axhline(tr[i, j], color='k', lw=0.5, ls=':')
        axc.legend(fontsize=7, ncol=3)
    else:
        axc.text(0.5, 0.5, f'no tensor estimate (status {est.status})', ha='center',
                 transform=axc.transAxes)
    ratios_only = est.inertia is None
    axc.set_title('convergence over the log' + (' (inertia / trace, band: ±2 sigma)'
                                                if ratios_only else ' (band: ±2 sigma)'))
    axc.set_xlabel('data used [s]')
    axc.set_ylabel('[-]' if ratios_only else '[kg m^2]')

    # principal axes
    ax3 = fig.add_subplot(gs[2:4, 1], projection='3d')
    if est.principal_axes is not None:
        axes = np.asarray(est.principal_axes)
        mom = (np.asarray(est.principal_moments) if est.principal_moments is not None
               else np.ones(3))
        scale = mom / mom.max() if np.all(np.isfinite(mom)) and mom.max() > 0 else np.ones(3)
        for k, c in enumerate(('tab:blue', 'tab:orange', 'tab:green')):
            v = axes[:, k] * scale[k]
            ax3.quiver(0, 0, 0, *v, color=c, lw=2,
                       label=f'axis {k + 1}' + (f' (I{k + 1}={mom[k]:.4g})'
                                                if est.principal_moments is not None else ''))
        ax3.legend(fontsize=7)
    else:
        ax3.text2D(0.5, 0.5, 'principal axes unknown', ha='center', transform=ax3.transAxes)
    ax3.set_xlim(-1, 1)
    ax3.set_ylim(-1, 1)
    ax3.set_zlim(-1, 1)
    ax3.set_xlabel('x')
    ax3.set_ylabel('y')
    ax3.set_zlabel('z')
    ax3.set_title(f'principal axes in frame {log.omega.frame_id!r} (length ~ moment)')
    fig.suptitle(f'{Path(log.paths[0]).name}: status {est.status}, model {est.model}, '
                 f'method {est.method}')
    fig.savefig(path, dpi=110)
    plt.close(fig)
