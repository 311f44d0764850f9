"""The benchmark charts (matplotlib, Agg backend): speed against accuracy, the stability map."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.ticker import NullFormatter

from .methods import DEFAULT_METHOD, MethodSpec, method_of
from .montecarlo import Bound, Summary, pareto_front
from .stability import SILENT_THRESHOLD, Cell

__all__ = ['METHOD_STYLE', 'PREVIOUS_DEFAULT_SECONDS', 'method_colour', 'plot_speed_vs_accuracy',
           'plot_stability_map', 'setting_markers']

#: The one colour and legend name of each method, in every benchmark chart.  Keys are the
#: ``--method`` names of the package's estimators and the baselines; a setting named
#: ``METHOD/VARIANT`` (``integral_sliding/1s``) takes its method's colour and a marker of its
#: own.  The default setting is drawn larger with a black edge.
METHOD_STYLE: dict[str, tuple[str, str]] = {
    'ml': ('black', 'ml'),
    'integral': ('tab:blue', 'integral'),
    'integral_ls': ('tab:cyan', 'integral_ls'),
    'integral_sliding': ('tab:green', 'integral_sliding'),
    'differential_fd': ('tab:orange', 'differential_fd'),
    'differential_sg': ('tab:olive', 'differential_sg'),
    'filtered': ('tab:pink', 'filtered'),
    'recursive': ('tab:purple', 'recursive'),
    'hand_fd': ('tab:red', 'hand_fd'),
    'pinocchio': ('tab:brown', 'pinocchio'),
}
#: Colour of a method missing from :data:`METHOD_STYLE`.
OTHER_COLOUR = 'tab:gray'
_MARKERS = 'osD^v<>pP*Xhd8H'


def method_colour(name: str) -> str:
    """The chart colour of a setting (by its method, the part of the name before ``/``)."""
    return METHOD_STYLE.get(method_of(name), (OTHER_COLOUR, ''))[0]


def setting_markers(names: Sequence[str]) -> dict[str, str]:
    """A marker per setting: ``o`` for each method's plain setting, others for its variants."""
    out: dict[str, str] = {}
    used: dict[str, int] = {}
    for n in names:
        m = method_of(n)
        k = 0 if n == m else used.get(m, 0) + 1
        used[m] = max(used.get(m, 0), k)
        out[n] = _MARKERS[k % len(_MARKERS)]
    return out


def _scene_panel(ax: Any, scene: str, rows: Sequence[Summary], marker: dict[str, str],
                 bound: Bound | None, handles: dict[str, Any]) -> None:
    """One scene: each setting at (median time, median error) with a bar to p90."""
    pts = [(s.median_seconds, s.median_error) for s in rows]
    failed = []
    for s in rows:
        if not np.isfinite(s.median_error):
            failed.append(s.method)
            continue
        c = method_colour(s.method)
        dflt = s.method == DEFAULT_METHOD
        ax.plot([s.median_seconds] * 2, [s.median_error, s.p90_error], color=c, lw=1.2,
                alpha=0.7)
        h = ax.scatter(s.median_seconds, s.median_error, color=c,
                       marker=marker.get(s.method, 'o'), s=70 if dflt else 40,
                       edgecolor='k' if dflt else 'none', zorder=3, label=s.method)
        handles.setdefault(s.method, h)
    _previous_default(ax, scene, rows)
    front = pareto_front(pts)
    if front:
        ft, fe = [pts[i][0] for i in front], [pts[i][1] for i in front]
        ax.step(ft, fe, where='post', color='0.4', lw=1.0, ls='-', zorder=1)
        ax.scatter(ft, fe, s=160, facecolor='none', edgecolor='0.3', lw=1.0, zorder=2)
    if bound is not None and np.isfinite(bound.rel_frobenius):
        ax.axhline(bound.rel_frobenius, color='k', ls='--', lw=1.0)
        ax.text(0.99, bound.rel_frobenius, 'CRLB', va='top', ha='right', fontsize=8,
                transform=ax.get_yaxis_transform())
    ax.axhline(SILENT_THRESHOLD, color='tab:red', ls=':', lw=0.8)
    ax.set_xscale('log')
    ax.set_yscale('log')
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_title(scene)
    ax.set_xlabel('compute time per estimate [s] (median)')
    ax.set_ylabel('relative Frobenius error (median, bar to p90)')
    ax.grid(True, which='both', alpha=0.25)
    if failed:
        ax.text(0.02, 0.02, 'no ok result: ' + ', '.join(failed), transform=ax.transAxes,
                fontsize=7, color='tab:red', wrap=True)


#: The default method's median time per record [s] on a scene before the speed work of
#: issue 18 item 7 (docs/BENCHMARKS.md at commit f04292c): drawn hollow, with an arrow to
#: where it is now.
PREVIOUS_DEFAULT_SECONDS = {'nominal': 0.132}


def _previous_default(ax: Any, scene: str, rows: Sequence[Summary]) -> None:
    """The default method's earlier time (:data:`PREVIOUS_DEFAULT_SECONDS`) and an arrow."""
    old = PREVIOUS_DEFAULT_SECONDS.get(scene)
    now = next((s for s in rows if s.method == DEFAULT_METHOD), None)
    if old is None or now is None or not np.isfinite(now.median_error):
        return
    c = method_colour(DEFAULT_METHOD)
    ax.scatter(old, now.median_error, facecolor='none', edgecolor=c, s=70, lw=1.2, zorder=3)
    ax.annotate('', xy=(now.median_seconds, now.median_error), xytext=(old, now.median_error),
                arrowprops={'arrowstyle': '->', 'color': c, 'lw': 1.0}, zorder=2)
    ax.text(old, now.median_error * 1.15, f'{DEFAULT_METHOD} before', color=c, fontsize=7,
            ha='center', va='bottom')


def plot_speed_vs_accuracy(summaries: Sequence[Summary], specs: Sequence[MethodSpec],
                           bounds: dict[str, Bound], path: Path) -> None:
    """One panel per scene: median time (log x) against error (log y), Pareto front marked.

    Each setting is a marker at its median relative Frobenius error with a bar up to the
    90th percentile, coloured by its method (:data:`METHOD_STYLE`); the dashed line is the
    Cramer-Rao bound (RMS relative Frobenius error); the grey step line joins the
    Pareto-optimal settings (median error vs median time).  Settings with no ok result are
    listed under the panel.

    Parameters
    ----------
    summaries : sequence of Summary
    specs : sequence of MethodSpec
        For the legend order and the markers.
    bounds : dict of str to Bound
    path : Path
        PNG file to write.
    """
    scenes = list(dict.fromkeys(s.scene for s in summaries))
    marker = setting_markers([s.name for s in specs])
    cols = min(3, len(scenes))
    rows = int(np.ceil(len(scenes) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.3 * rows + 1.4), squeeze=False)
    handles: dict[str, Any] = {}
    for ax, scene in zip(axes.ravel(), scenes, strict=False):
        _scene_panel(ax, scene, [s for s in summaries if s.scene == scene], marker,
                     bounds.get(scene), handles)
    for ax in axes.ravel()[len(scenes):]:
        ax.axis('off')
    order = [s.name for s in specs if s.name in handles]
    fig.legend([handles[n] for n in order], order, loc='lower center',
               ncol=min(6, len(order)), fontsize=8, frameon=False)
    fig.suptitle('Speed against accuracy (colour: method; grey circles and steps: Pareto '
                 'front; dashed: Cramer-Rao bound; dotted red: 10 % error)', fontsize=11)
    fig.tight_layout(rect=(0, 0.09, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_stability_map(cells: Sequence[Cell], path: Path) -> None:
    """Per method and duration: median error over gyro noise x amplitude, failures marked.

    Colour: log10 of the median relative Frobenius error over the seeds (ok and silent
    results).  A black ``x`` marks a cell where the method reported a failure status on at
    least one seed; a red square marks a silent failure (status ok, error > 10 %).

    Parameters
    ----------
    cells : sequence of Cell
    path : Path
        PNG file to write.
    """
    methods = list(dict.fromkeys(c.method for c in cells))
    durations = sorted({c.duration for c in cells})
    noises = sorted({c.gyro_noise for c in cells})
    amps = sorted({c.amplitude for c in cells})
    fig, axes = plt.subplots(len(durations), len(methods),
                             figsize=(2.9 * len(methods) + 1.2, 2.8 * len(durations) + 0.8),
                             squeeze=False)
    norm = LogNorm(vmin=1e-4, vmax=1.0)
    im = None
    for r, dur in enumerate(durations):
        for c, m in enumerate(methods):
            ax = axes[r, c]
            Z = np.full((len(amps), len(noises)), np.nan)
            for i, a in enumerate(amps):
                for j, nz in enumerate(noises):
                    sel = [x for x in cells if x.method == m and x.duration == dur
                           and x.amplitude == a and x.gyro_noise == nz]
                    errs = [x.error for x in sel if x.status == 'ok' and np.isfinite(x.error)]
                    if errs:
                        Z[i, j] = np.clip(np.median(errs), 1e-4, 1.0)
                    if any(x.outcome == 'reported' for x in sel):
                        ax.plot(j, i, 'x', color='k', ms=9, mew=2)
                    if any(x.outcome == 'silent' for x in sel):
                        ax.plot(j, i, 's', mfc='none', mec='red', ms=15, mew=2)
            im = ax.imshow(Z, origin='lower', cmap='viridis', norm=norm, aspect='auto')
            ax.set_xticks(range(len(noises)), [f'{v:g}' for v in noises], fontsize=7,
                          rotation=45)
            ax.set_yticks(range(len(amps)), [f'{v:g}' for v in amps], fontsize=7)
            if r == 0:
                ax.set_title(m, fontsize=10, color=method_colour(m), fontweight='bold')
            if r == len(durations) - 1:
                ax.set_xlabel('gyro noise [rad/s]', fontsize=8)
            if c == 0:
                ax.set_ylabel(f'{dur:g} s record\ntorque amplitude [N m]', fontsize=8)
    if im is not None:
        fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8,
                     label='median relative Frobenius error')
    fig.suptitle('Stability map (nominal body; x: failure status reported; red square: silent '
                 'failure, status ok with error > 10 %)', fontsize=10)
    fig.savefig(path, dpi=100, bbox_inches='tight')
    plt.close(fig)
