"""The figure of ``python -m inertia_ros estimate --plot FILE.png`` (all of its matplotlib).

Panels: measured torque (markers) under the model torque (line) per axis, their difference
(residual), the angular velocity, the convergence of the six tensor elements as deviation from
the truth (or the final estimate) per tensor scale with their +-2 sigma bands, and the
principal axes.  The numbers come from :mod:`inertia_ros.cli.report`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np

from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.io.logs import LogData

from .report import THETA_NAMES, Convergence, window_torques

__all__ = ['epoch_text', 'plot_report']

#: One colour per tensor element, in the order of THETA_NAMES.
ELEMENT_COLOURS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:red', 'tab:purple', 'tab:brown')
#: One colour per body axis (x, y, z).
AXIS_COLOURS = ('tab:blue', 'tab:orange', 'tab:green')
#: Most points drawn per line (the figure stays light on long logs).
MAX_POINTS = 20_000
#: Most measured markers per torque panel (few enough to see the line through them).
MAX_MARKERS = 250


def _stride(n: int, most: int) -> int:
    """Step that keeps at most ``most`` of ``n`` points."""
    return max(1, -(-n // most))


def _torque_panels(axes: list[Any], est: InertiaEstimate, log: LogData, hold: str,
                   what: str = 'torque') -> None:
    """Three torque panels (measured markers under the model line) and the residual panel;
    ``what`` names the torque drawn (``'equivalent torque'`` with wheels or rotors)."""
    tg, w = log.omega.t, log.omega.values
    tt, tau = log.torque.t, log.torque.values
    have_model = est.inertia is not None and bool(np.isfinite(est.inertia).all())
    if not have_model:
        st = _stride(len(tt), MAX_POINTS)
        for k, ax in enumerate(axes[:3]):
            ax.plot(tt[::st], tau[::st, k], '.', ms=2, color='0.35', label='measured')
            ax.set_ylabel(f'torque {"xyz"[k]} [N m]')
        axes[0].set_title(f'measured {what} (no model torque: status {est.status})')
        axes[3].text(0.5, 0.5, 'no residual without a tensor', ha='center',
                     transform=axes[3].transAxes)
        if len(tt):
            axes[0].legend(loc='upper right', fontsize=8)
        return
    width = float(np.clip((tg[-1] - tg[0]) / 60.0, 0.25, 2.0))
    t_mid, meas, model = window_torques(est, tg, w, tt, tau, hold, width)
    line_st = _stride(len(t_mid), MAX_POINTS)
    mark_st = _stride(len(t_mid), MAX_MARKERS)
    for k, ax in enumerate(axes[:3]):
        ax.plot(t_mid[::mark_st], meas[::mark_st, k], 'o', ms=3.5, mfc='none', mew=0.8,
                color='0.35', label='measured', zorder=2)
        ax.plot(t_mid[::line_st], model[::line_st, k], lw=1.0, color=AXIS_COLOURS[k],
                label='model', zorder=3)
        ax.set_ylabel(f'torque {"xyz"[k]} [N m]')
    axes[0].set_title(f'{what}, {width:.3g} s window means: measured (circles) and model '
                      '(I dw/dt + w x I w' + (' - bias' if est.torque_bias is not None else '')
                      + (" - R' d" if est.inertial_torque is not None else '') + ', line)')
    axes[0].legend(loc='upper right', fontsize=8)
    resid = meas - model
    for k in range(3):
        axes[3].plot(t_mid[::line_st], resid[::line_st, k], lw=0.7, color=AXIS_COLOURS[k],
                     label=f'{"xyz"[k]}')
    axes[3].axhline(0.0, color='k', lw=0.6)
    rms = np.sqrt(np.mean(resid ** 2, axis=0)) if len(resid) else np.full(3, np.nan)
    axes[3].set_title('residual, measured - model (RMS x y z: '
                      + ' '.join(f'{v:.2g}' for v in rms) + ' N m)', fontsize=9)
    axes[3].set_ylabel('residual [N m]')
    axes[3].legend(loc='upper right', fontsize=8, ncol=3)


#: Stamps before this [ns] (1971) are a simulation's clock, not a calendar time.
_CALENDAR_FROM_NS = 365 * 86400 * 10 ** 9


def epoch_text(epoch_ns: int) -> str:
    """The log's time origin, readable: ``'2024-01-01 00:00:00.000 UTC'``.

    Parameters
    ----------
    epoch_ns : int
        Stamp of the log's time zero [ns since the Unix epoch].

    Returns
    -------
    str
        A UTC date and time to the millisecond; ``'stamp 12.500 s'`` for a clock that starts
        near zero (simulation time) or one out of the calendar's range.
    """
    from datetime import UTC, datetime

    if abs(int(epoch_ns)) >= _CALENDAR_FROM_NS:
        try:
            when = datetime.fromtimestamp(int(epoch_ns) // 10 ** 9, tz=UTC)
            ms = int(epoch_ns) % 10 ** 9 // 10 ** 6
            return f'{when:%Y-%m-%d %H:%M:%S}.{ms:03d} UTC'
        except (OverflowError, ValueError, OSError):
            pass
    return f'stamp {int(epoch_ns) * 1e-9:.3f} s'


def _omega_panel(ax: Any, log: LogData) -> None:
    """Angular velocity against time."""
    tg, w = log.omega.t, log.omega.values
    st = _stride(len(tg), MAX_POINTS)
    for k in range(3):
        ax.plot(tg[::st], w[::st, k], lw=0.8, color=AXIS_COLOURS[k], label=f'w{"xyz"[k]}')
    ax.set_ylabel('omega [rad/s]')
    ax.set_xlabel(f'time [s] since {epoch_text(log.epoch_ns)}')
    ax.legend(loc='upper right', fontsize=8)


def _convergence_panel(ax: Any, conv: Convergence | None, status: str) -> None:
    """Deviation of each element from the reference per tensor scale, +-2 sigma bands [%]."""
    if conv is None:
        ax.text(0.5, 0.5, f'no tensor estimate (status {status})', ha='center',
                transform=ax.transAxes)
        ax.set_title('convergence over the log')
        return
    rel, sd = 100.0 * conv.relative, 100.0 * conv.relative_std
    for k, name in enumerate(THETA_NAMES):
        c = ELEMENT_COLOURS[k]
        ax.plot(conv.seconds, rel[:, k], marker='o', ms=3, color=c, label=name)
        ax.fill_between(conv.seconds, rel[:, k] - 2 * sd[:, k], rel[:, k] + 2 * sd[:, k],
                        color=c, alpha=0.18, lw=0)
    ax.axhline(0.0, color='k', lw=0.8, ls=':')
    # zoom on the second half of the log, where the bands matter; early prefixes may leave
    late = conv.seconds >= 0.5 * conv.seconds[-1]
    reach = np.abs(rel[late]) + 2 * np.nan_to_num(sd[late])
    top = float(np.nanmax(reach)) if np.isfinite(reach).any() else 1.0
    top = top if top > 0 else 1.0
    ax.set_ylim(-1.3 * top, 1.3 * top)
    what = 'inertia / trace' if conv.ratios else 'element'
    ax.set_title(f'convergence: ({what} - {conv.reference_name}) / (trace/3) '
                 f'[%], band ±2 sigma', fontsize=9)
    ax.set_xlabel('data used [s]')
    ax.set_ylabel('deviation [% of trace/3]')
    ax.legend(fontsize=7, ncol=3, loc='upper right')


def _axes_panel(ax: Any, est: InertiaEstimate, frame_id: str) -> None:
    """Principal axes as arrows whose length follows the moment."""
    if est.principal_axes is not None:
        axes = np.asarray(est.principal_axes)
        mom = (np.asarray(est.principal_moments) if est.principal_moments is not None
               else np.ones(3))
        scale = mom / mom.max() if np.all(np.isfinite(mom)) and mom.max() > 0 else np.ones(3)
        for k, c in enumerate(AXIS_COLOURS):
            v = axes[:, k] * scale[k]
            ax.quiver(0, 0, 0, *v, color=c, lw=2,
                      label=f'axis {k + 1}' + (f' (I{k + 1}={mom[k]:.4g})'
                                               if est.principal_moments is not None else ''))
        ax.legend(fontsize=7)
    else:
        ax.text2D(0.5, 0.5, 'principal axes unknown', ha='center', transform=ax.transAxes)
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-1, 1)
    ax.set_xlabel('x')
    ax.set_ylabel('y')
    ax.set_zlabel('z')
    ax.set_title(f'principal axes in frame {frame_id!r} (length ~ moment)', fontsize=9)


def plot_report(path: Path | None, est: InertiaEstimate, log: LogData, hold: str,
                conv: Convergence | None, *, fmt: str = 'png',
                torque_what: str = 'torque') -> bytes:
    """Draw the estimate's figure; return its bytes (and write them to ``path`` if given).

    Parameters
    ----------
    path : Path or None
        Output file (replaced), or None to only return the image.
    est : InertiaEstimate
        The estimate on the whole log.
    log : LogData
        The streams it came from.
    hold : str
        Torque hold used by the estimate (``zoh`` or ``linear``).
    conv : Convergence or None
        From :func:`inertia_ros.cli.report.convergence`.
    fmt : str
        Image format matplotlib writes (``'png'``, ``'svg'``, ``'pdf'``, ...).
    torque_what : str
        Name of the torque drawn in the torque panels' titles.

    Returns
    -------
    bytes
        The image file's content.
    """
    import io

    fig = plt.figure(figsize=(14, 10), layout='constrained')
    gs = fig.add_gridspec(5, 2, width_ratios=[1.6, 1])
    left = [fig.add_subplot(gs[0, 0])]
    left += [fig.add_subplot(gs[k, 0], sharex=left[0]) for k in range(1, 5)]
    _torque_panels(left[:4], est, log, hold, torque_what)
    _omega_panel(left[4], log)
    _convergence_panel(fig.add_subplot(gs[0:3, 1]), conv, est.status)
    _axes_panel(fig.add_subplot(gs[3:5, 1], projection='3d'), est, log.omega.frame_id)
    fig.suptitle(f'{Path(log.paths[0]).name}: status {est.status}, model {est.model}, '
                 f'method {est.method}')
    buf = io.BytesIO()
    try:
        fig.savefig(buf, format=fmt, dpi=110)
    finally:
        plt.close(fig)
    image = buf.getvalue()
    if path is not None:
        Path(path).write_bytes(image)
    return image
