"""The numbers of ``python -m inertia_ros estimate``: the JSON contract, the text report, and
the series the figure draws (window torques, convergence over the log).

Everything here is computation on arrays; :mod:`inertia_ros.cli.plots` draws the series and
is the only module of the command that imports matplotlib.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from inertia_ros.core.dynamics import angular_momentum
from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.align import cumtrapz
from inertia_ros.core.estimation.options import MIN_GYRO_SAMPLES
from inertia_ros.core.estimation.regressors import cumulative_torque
from inertia_ros.core.estimation.result import InertiaEstimate, to_jsonable
from inertia_ros.core.tensor import matrix_to_theta
from inertia_ros.io.logs import LogData

__all__ = ['STATUS_TEXT', 'Convergence', 'NumericalWarnings', 'build_report', 'convergence',
           'format_text', 'momentum_view', 'numerical_warnings', 'remedy',
           'window_torques']

#: What each status means, for the text report.
STATUS_TEXT = {
    'ok': 'all six tensor elements identified',
    'model_mismatch': 'the residuals do not fit the noise model: the estimate and its sigma '
                      'are reported, but the data contain something the model lacks (the '
                      'reason below names the likely cause)',
    'scale_unobservable': 'torque-free data: the principal axes and the ratios of the moments '
                          'are known, the scale is not (record with a known torque to get it)',
    'partially_identifiable': 'some elements could not be identified (named below, null in '
                              'the JSON); excite rotation about more axes',
    'insufficient_excitation': 'the motion does not excite the dynamics enough; rotate about '
                               'all three axes with changing rates',
    'insufficient_data': 'too few usable samples to estimate anything',
}

#: Tensor element names in the documented parameter order theta.
THETA_NAMES: tuple[str, ...] = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')


# --------------------------------------------------------------------------------------------
# Numerical warnings


#: Warnings meant for developers of the code, not for the user of a report: not collected.
_DEVELOPER_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, ImportWarning,
                       ResourceWarning)


class NumericalWarnings(list):
    """The distinct numpy/runtime warnings raised inside :func:`numerical_warnings`.

    A list of one-line strings, ``'<message> (<category>, <count>x)'``, in order of first
    occurrence.
    """


@contextmanager
def numerical_warnings() -> Iterator[NumericalWarnings]:
    """Collect the warnings of the block instead of printing them.

    numpy's floating-point warnings (overflow, invalid value, division by zero) and any other
    user-facing warning raised by the block are recorded, counted and returned as one line
    each; nothing reaches stderr (deprecation-type warnings are dropped).  Use the lines in
    the report's ``diagnostics.warnings``.
    """
    found = NumericalWarnings()
    with warnings.catch_warnings(record=True) as caught, np.errstate(all='warn', under='ignore'):
        warnings.simplefilter('always')
        yield found
    counts: dict[tuple[str, str], int] = {}
    for w in caught:
        if issubclass(w.category, _DEVELOPER_WARNINGS):
            continue
        key = (str(w.message).strip().splitlines()[0], w.category.__name__)
        counts[key] = counts.get(key, 0) + 1
    found.extend(f'numerical warning: {msg} ({cat}, {n}x)' for (msg, cat), n in counts.items())


# --------------------------------------------------------------------------------------------
# JSON report


def build_report(est: InertiaEstimate, log: LogData, torque_delay: float, hold: str,
                 extra_warnings: list[str] | None = None) -> dict:
    """The JSON contract of DESIGN.md, with the log's facts under ``diagnostics``.

    ``samples.used`` counts the gyro samples in the equations; ``samples.dropped`` counts the
    gyro messages left out, by cleaning (NaN, duplicates, outside the torque coverage, ...)
    and by the estimator.

    Parameters
    ----------
    est : InertiaEstimate
    log : LogData
    torque_delay : float
        The ``--torque-delay`` applied [s].
    hold : str
        The torque hold (``zoh`` or ``linear``).
    extra_warnings : list of str, optional
        Further warnings (numerical warnings of the run), appended once each.
    """
    d = est.to_dict()
    diag = d.setdefault('diagnostics', {}) or {}
    d['diagnostics'] = diag
    warns = list(log.warnings)
    for w in list(diag.get('warnings') or []) + list(extra_warnings or []):
        if w not in warns:
            warns.append(w)
    diag['warnings'] = warns
    diag['log'] = to_jsonable(log.summary())
    diag['frame_id'] = log.omega.frame_id
    diag['torque_delay_s'] = float(torque_delay)
    diag['hold'] = diag.get('hold', hold)      # the hold used (auto: the one chosen)
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


# --------------------------------------------------------------------------------------------
# Text report


def _fmt(x: float | None, std: float | None = None, missing: str = 'n/a') -> str:
    """A value with its one-sigma error, fixed width (``missing`` when unknown)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return f'{missing:>22s}'
    if std is None:
        return f'{x:>11.6g}' + ' ' * 11
    return f'{x:>11.6g} ± {std:<8.2g}'


def _short(v: Any) -> str:
    """A compact rendering of a diagnostic value."""
    if isinstance(v, (list, tuple)):
        return '[' + ' '.join(_short(x) for x in v) + ']'
    if isinstance(v, float):
        return f'{v:.3g}'
    return str(v)


def _matrix_lines(m: list, std: list | None, missing: str = 'n/a') -> list[str]:
    """Three rows ``[ a ± s  b ± s  c ± s ]`` (``missing`` where an element is unknown)."""
    return ['  [' + '  '.join(_fmt(m[i][j], None if std is None else std[i][j], missing)
                              for j in range(3)) + ' ]' for i in range(3)]


def _moments_line(label: str, values: list, stds: list | None) -> str:
    """``label I1 = a ± s, I2 = ..., I3 = ...``."""
    stds = stds or [None] * 3
    return label + ', '.join(f'I{k + 1} = {_fmt(v, e).strip()}'
                             for k, (v, e) in enumerate(zip(values, stds, strict=True)))


def _header_lines(report: dict) -> list[str]:
    """The files, the two streams and what went into the equations."""
    s = report['diagnostics']['log']
    lines = [f'inertia_ros estimate: {", ".join(s["files"])}']
    for key, label in (('omega', 'gyro  '), ('torque', 'torque')):
        st = s[key]
        if not st.get('topic'):
            lines.append(f'  {label} none (torque-free data: no torque stream)')
            continue
        rate = f'{st["rate_hz"]:.1f} Hz' if st['rate_hz'] else 'rate n/a'
        lines.append(f'  {label} {st["topic"]} ({st["type"]}, frame {st["frame_id"]!r}, '
                     f'{rate}): {st["received"]} received, {st["used"]} used, '
                     f'{st["dropped"]} dropped')
    lines.append(f'  method {report["method"]}, model {report["model"]}; '
                 f'{report["samples"]["used"]} gyro samples in the equations, '
                 f'{report["samples"]["dropped"]} left out; {s["windows"]} window(s)')
    lines += method_choice_lines(report['diagnostics'].get('method_selection'))
    lines += ['', f'status: {report["status"]} - {STATUS_TEXT.get(report["status"], "")}']
    return lines + _reason_lines(report)


#: Causes in a model_mismatch reason that a sensor nuisance term may explain.
_NUISANCE_CAUSES = ('gyro bias', 'unmodelled torque', 'correlated sensor noise',
                    'window estimates disagree')


def method_choice_lines(sel: dict | None) -> list[str]:
    """What ``--method auto`` chose and why (:mod:`inertia_ros.core.estimation.method_choice`):
    one line when the residual spectrum showed nothing, else the evidence and each candidate."""
    if not sel or sel.get('requested') != 'auto':
        return []
    ev = sel.get('evidence') or {}
    if not ev.get('found'):
        why = ev.get('reason') or 'no line or excess power in the residual spectrum'
        return [f'  method auto: {sel["chosen"]} ({why}; {sel["rule"]})']
    def hz(x: float | None) -> str:
        return 'n/a' if x is None else f'{x:.4g} Hz'

    lines = ', '.join(hz(f) for f in ev.get('lines_hz', [])[:4]) or 'none'
    head = (f'  method auto: {sel["chosen"]}; residual spectrum: lines {lines}, excess from '
            f'{hz(ev.get("excess_from_hz"))}; band edge {hz(ev.get("edge_hz"))}'
            + (f' (rotation line {hz(ev["rotation_hz"])})' if ev.get('rotation_hz') else '')
            + f', filter cutoff {hz(ev.get("cutoff_hz"))}')
    out = [head] + ([f'    {ev["reason"]}'] if ev.get('reason') else [])
    for name, c in (sel.get('candidates') or {}).items():
        failed = '; '.join(c['failed']) or 'passed'
        out.append(f'    {name:9s} {c["status"]:16s} predicted relative variance '
                   f'{c["relative_variance"]:.3g}; tests: {failed}')
    return out + [f'    rule: {sel["rule"]}']


def remedy(report: dict) -> str | None:
    """The next thing to try for a report that is not ok, or None.

    Parameters
    ----------
    report : dict
        :func:`build_report`'s dictionary.

    Returns
    -------
    str or None
        One sentence naming an option (e.g. ``--nuisance auto`` when the mismatch reads like
        a sensor nuisance and no nuisance term was fitted).
    """
    diag = report.get('diagnostics') or {}
    reason = str(diag.get('reason') or '')
    if report.get('status') != 'model_mismatch':
        return None
    nuisance = diag.get('nuisance') or {}
    fitted = bool(nuisance.get('chosen')) or (nuisance and not nuisance.get('skipped'))
    if 'inertia change near' in reason:
        return ('the tensor seems to change during the log (a payload or configuration '
                'change): estimate the parts before and after it as separate logs')
    if 'wheels' in diag or 'rotors' in diag:        # --nuisance is not available with them
        return ('check the wheel inertias / rotor coefficients in the YAML and their stated '
                '*_std (--nuisance is not available with --wheels/--rotors)'
                if 'rotor coefficients' in reason else None)
    if any(c in reason for c in _NUISANCE_CAUSES):
        if not fitted:
            return ('try --nuisance auto: a gyro bias, a torque delay, damping or a gyro '
                    'low-pass is kept where the data support it')
        if 'try hold linear' in reason and diag.get('hold') != 'linear':
            return 'try --hold linear (torque that varies between its samples)'
    return None


def _reason_lines(report: dict) -> list[str]:
    """``reason:`` (diagnostics.reason) and a remedy, for every status but ok."""
    diag = report.get('diagnostics') or {}
    lines: list[str] = []
    if report.get('status') == 'ok':
        return lines
    if diag.get('reason'):
        lines.append(f'reason: {diag["reason"]}')
    und = diag.get('undetermined')
    if und and not all(name in str(diag.get('reason')) for name in und):
        lines.append(f'undetermined elements: {", ".join(und)}')
    hint = remedy(report)
    if hint:
        lines.append(f'remedy: {hint}')
    return lines


def _tensor_lines(report: dict) -> list[str]:
    """The tensor (or its ratios), principal moments and axes, the bias."""
    diag = report['diagnostics']
    lines: list[str] = []
    missing = 'undetermined' if diag.get('undetermined') else 'n/a'
    if report['inertia'] is not None:
        lines += ['', f'inertia tensor about the centre of mass, frame '
                      f'{diag.get("frame_id", "")!r} [kg m^2] (± one sigma):']
        lines += _matrix_lines(report['inertia'], report['inertia_std'], missing)
    elif report['ratios'] is not None:
        lines += ['', 'inertia / trace (ratios; the scale is unobservable) (± one sigma):']
        lines += _matrix_lines(report['ratios'], report.get('ratios_std'), missing)
        if diag.get('principal_ratios') is not None:
            lines.append(_moments_line('principal moments / trace: ', diag['principal_ratios'],
                                       diag.get('principal_ratios_std')))
    if report['principal_moments'] is not None:
        lines += ['', _moments_line('principal moments [kg m^2]: ', report['principal_moments'],
                                    diag.get('principal_moments_std'))]
    if report['principal_axes'] is not None:
        a = np.array(report['principal_axes'], dtype=float)
        a_std = diag.get('principal_axes_std') or [None] * 3
        lines.append('principal axes (unit vectors in the gyro frame, ± one-sigma angle):')
        for k in range(3):
            err = '' if a_std[k] is None else f'  ± {math.degrees(a_std[k]):.2g} deg'
            lines.append(f'  axis {k + 1}: [{a[0, k]: .4f} {a[1, k]: .4f} {a[2, k]: .4f}]'
                         + err)
    if report['torque_bias'] is not None:
        b = report['torque_bias']
        lines.append(f'disturbance torque (estimated bias) [N m]: '
                     f'[{b[0]:.4g} {b[1]:.4g} {b[2]:.4g}]')
    if report.get('inertial_torque') is not None:
        d, sd = report['inertial_torque'], diag.get('inertial_torque_std') or [None] * 3
        err = '' if None in sd else f' ± [{sd[0]:.2g} {sd[1]:.2g} {sd[2]:.2g}]'
        lines.append(f'disturbance torque fixed in inertial axes [N m]: [{d[0]:.4g} {d[1]:.4g} '
                     f'{d[2]:.4g}]{err} (in body axes at the first gyro sample of the epoch, '
                     'the first one used; it turns with the body in these axes)')
    return lines


def _footer_lines(report: dict) -> list[str]:
    """Condition and residual, the recorded truth, the warnings."""
    diag = report['diagnostics']
    lines: list[str] = []
    facts = [f'{key.replace("_", " ")} {_short(diag[key])}'
             for key in ('condition_number', 'residual_rms') if diag.get(key) is not None]
    if facts:
        lines.append('diagnostics: ' + ', '.join(facts))
    lines += nuisance_lines(diag.get('nuisance'))
    truth = diag.get('truth')
    if truth and 'relative_error' in truth:
        lines.append(f'recorded truth: relative error {100 * truth["relative_error"]:.3g}% '
                     f'(max abs {truth["max_abs_error"]:.3g} kg m^2)')
    if diag.get('warnings'):
        lines += ['', 'warnings:'] + [f'  - {w}' for w in diag['warnings']]
    return lines


def nuisance_lines(rec: dict | None) -> list[str]:
    """The ``diagnostics.nuisance`` record in a line or two (nothing when not requested)."""
    if not rec:
        return []
    if rec.get('skipped'):
        return [f'nuisance: not fitted ({rec["skipped"]})']
    chosen = rec.get('chosen') or []
    parts = [f'{t} {_short(rec["values"][t])} +- {_short(rec["sigma"][t])} '
             f'{rec["units"][t]}' for t in chosen]
    lines = ['nuisance: ' + ('; '.join(parts) if parts else 'none chosen')]
    tested = [f'{t} p={v["p_value"]:.2g}' for t, v in (rec.get('evidence') or {}).items()]
    if tested:
        lines.append('  evidence: ' + ', '.join(tested))
    return lines


def format_text(report: dict) -> str:
    """A short human-readable report of :func:`build_report`'s dictionary."""
    return '\n'.join(_header_lines(report) + _tensor_lines(report)
                     + _footer_lines(report)) + '\n'


# --------------------------------------------------------------------------------------------
# Series for the figure


def window_torques(est: InertiaEstimate, tg: np.ndarray, w: np.ndarray, tt: np.ndarray,
                   tau: np.ndarray, hold: str, width: float = 0.25
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured and model torque averaged over sliding windows of ``width`` seconds.

    The model side is the momentum form, ``(I w(b) - I w(a) + int_a^b w x I w dt) / (b - a)``
    (minus the bias), the measured side ``int_a^b tau dt / (b - a)``: the same filter on both
    sides, so differentiation noise does not swamp the picture.

    Parameters
    ----------
    est : InertiaEstimate
        With a finite ``inertia``.
    tg : numpy.ndarray, shape (N,)
        Gyro times [s]; ``w`` : shape (N, 3) angular velocity [rad/s].
    tt : numpy.ndarray, shape (M,)
        Torque times [s]; ``tau`` : shape (M, 3) torque [N m].
    hold : str
        ``'zoh'`` or ``'linear'``.
    width : float
        Window length [s].

    Returns
    -------
    t_mid : numpy.ndarray, shape (K,)
        Window centres [s].
    measured, model : numpy.ndarray, shape (K, 3)
        Window-mean torques [N m].
    """
    L = angular_momentum(np.asarray(est.inertia), w)
    gyro = np.cross(w, L)
    dt = np.diff(tg)
    G = cumtrapz(tg, gyro)
    # the estimator's own held-torque integral (regressors.cumulative_torque)
    T = cumulative_torque(tt, tau, tg, 'zoh' if hold == 'zoh' else 'linear')
    k = max(1, int(round(width / float(np.median(dt)))))
    if len(tg) <= k:
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
    span = (tg[k:] - tg[:-k])[:, None]
    model = (L[k:] - L[:-k] + G[k:] - G[:-k]) / span
    if est.torque_bias is not None:
        model = model - np.asarray(est.torque_bias)
    if est.inertial_torque is not None:
        model = model - _inertial_windows(est.inertial_torque, tg, w, tt, k) / span
    meas = (T[k:] - T[:-k]) / span
    ok = span[:, 0] < 1.5 * width + 1e-9          # windows spanning a gap are meaningless
    return 0.5 * (tg[k:] + tg[:-k])[ok], meas[ok], model[ok]


def _inertial_windows(d: np.ndarray, tg: np.ndarray, w: np.ndarray, tt: np.ndarray,
                      k: int) -> np.ndarray:
    """Angular impulse (K, 3) [N m s] of the torque ``d`` fixed in inertial axes over the
    windows of ``k`` gyro steps: ``int R(s)' ds`` per window (:mod:`.attitude`, integrated
    over the plotted gyro samples) times ``d``, turned from the estimate's frame (body axes at
    its first gyro sample, taken as the first at or after the first torque stamp) to that of
    the plot's first sample."""
    from inertia_ros.core.estimation.attitude import attitude_integral

    C, R = attitude_integral(tg, w, rotations=True)
    start = min(int(np.searchsorted(tg, tt[0])) if len(tt) else 0, len(tg) - 1)
    d_plot = R[start] @ np.asarray(d, dtype=float)
    return (C[k:] - C[:-k]) @ d_plot


def momentum_view(log: LogData, momentum: Any, hold: str = 'zoh') -> LogData:
    """The log as the body alone sees it, for the figure of a ``--wheels``/``--rotors`` run.

    The torque stream becomes the equivalent torque of the momentum form
    (:func:`inertia_ros.core.estimation.momentum.equivalent_torque`): the other known torque
    plus the rotor torques, minus the change of the internal momentum ``h`` and ``w x h``,
    held over each interval of the union of the gyro and momentum stamps; the gyro keeps its
    samples inside the common coverage.  The body's own Euler equation
    ``I dw/dt + w x I w = torque`` holds on it, so the figure's model torque, residual and
    convergence (refitted with ``hold='zoh'``) read as for a torque log.

    Parameters
    ----------
    log : LogData
        The log read for the estimate.
    momentum : Momentum
        The internal momentum (and rotor torque) record the estimate used [N m s], [N m].
    hold : str
        Hold of the log's own torque stream between its samples (``zoh`` or ``linear``).

    Returns
    -------
    LogData
        A copy whose ``omega`` and ``torque`` streams are replaced.
    """
    from dataclasses import replace

    from inertia_ros.core.estimation.momentum import as_momentum, equivalent_torque

    mom = as_momentum(momentum)
    tg, w = log.omega.t, log.omega.values
    grid, tq, inside = equivalent_torque(tg, w, mom.t, mom.h, log.torque.t, log.torque.values,
                                         hold, mom.torque)
    omega = replace(log.omega, t=tg[inside], values=w[inside])
    torque = replace(log.torque, t=grid, values=tq)
    return replace(log, omega=omega, torque=torque)


@dataclass(frozen=True)
class Convergence:
    """The estimate on growing prefixes of the log, as deviations from a reference.

    Attributes
    ----------
    seconds : numpy.ndarray, shape (P,)
        Data used by each prefix [s].
    theta : numpy.ndarray, shape (P, 6)
        Elements ``[ixx, iyy, izz, ixy, ixz, iyz]`` of each prefix's estimate [kg m^2], or of
        its ratios inertia / trace [-] when ``ratios`` is true.
    theta_std : numpy.ndarray, shape (P, 6)
        Their one-sigma standard errors (NaN where unknown).
    reference : numpy.ndarray, shape (6,)
        The recorded truth when the log has one, else the estimate on the whole log.
    reference_name : str
        ``'truth'`` or ``'final estimate'``.
    scale : float
        Tensor scale the deviations are divided by: trace / 3 of the reference [kg m^2] (or
        1/3 for ratios).
    ratios : bool
        Whether the series are ratios (scale unobservable).
    """

    seconds: np.ndarray
    theta: np.ndarray
    theta_std: np.ndarray
    reference: np.ndarray
    reference_name: str
    scale: float
    ratios: bool

    @property
    def relative(self) -> np.ndarray:
        """Deviation from the reference per tensor scale, shape (P, 6) [-]."""
        return (self.theta - self.reference) / self.scale

    @property
    def relative_std(self) -> np.ndarray:
        """One-sigma standard error per tensor scale, shape (P, 6) [-]."""
        return self.theta_std / self.scale


def _prefix_theta(e: InertiaEstimate, ratios: bool) -> tuple[np.ndarray, np.ndarray] | None:
    """``(theta, theta_std)`` of one prefix estimate, or None when it has no tensor."""
    if not ratios and e.inertia is not None:
        sd = e.theta_std if e.theta_std is not None else np.full(6, np.nan)
        return np.asarray(e.theta, dtype=float), np.asarray(sd, dtype=float)
    if ratios and e.ratios is not None:
        sd = (matrix_to_theta(e.ratios_std) if e.ratios_std is not None
              else np.full(6, np.nan))
        return matrix_to_theta(e.ratios), sd
    return None


def convergence(est: InertiaEstimate, log: LogData,
                run: Callable[..., InertiaEstimate] | None = None,
                fractions: tuple[float, ...] = (0.1, 0.2, 0.35, 0.5, 0.75, 1.0),
                **options: Any) -> Convergence | None:
    """Re-estimate on growing prefixes of the log (the last one is ``est`` itself).

    Parameters
    ----------
    est : InertiaEstimate
        The estimate on the whole log.
    log : LogData
    run : callable, optional
        The estimator (default :func:`~inertia_ros.core.estimation.estimate`).
    fractions : tuple of float
        Prefix lengths as shares of the log's time span.
    **options
        Passed to ``run`` (method, model, torque_bias, hold, symmetry_axis).

    Returns
    -------
    Convergence or None
        None when no prefix gave a tensor (or ratios).
    """
    run = estimate if run is None else run
    ratios = est.inertia is None
    tg, w, tt, tau = log.omega.t, log.omega.values, log.torque.t, log.torque.values
    rows = []
    for f in fractions:
        t_end = tg[0] + f * (tg[-1] - tg[0])
        mg, mt = tg <= t_end, tt <= t_end
        if mg.sum() < MIN_GYRO_SAMPLES or (len(tt) and mt.sum() < 2):
            continue
        try:
            e = est if f == 1.0 else run(tg[mg], w[mg], tt[mt], tau[mt], **options)
        except ValueError:
            continue
        got = _prefix_theta(e, ratios)
        if got is not None:
            rows.append((t_end - tg[0], *got))
    if not rows:
        return None
    if log.truth:
        truth = np.asarray(log.truth[0][1], dtype=float)
        ref = matrix_to_theta(truth / np.trace(truth) if ratios else truth)
        name = 'truth'
    else:
        ref, name = rows[-1][1], 'final estimate'
    scale = float(np.sum(ref[:3]) / 3.0) or 1.0
    return Convergence(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                       np.array([r[2] for r in rows]), ref, name, abs(scale), ratios)
