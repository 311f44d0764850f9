"""Fleet report: a trend plot per vehicle, the outlier table and the status counts.

``write_report(rows, DIR)`` writes ``DIR/fleet_report.md`` (status counts, outliers, one line
per vehicle, every log without an estimate and why, the plots) and ``DIR/trend_<vehicle>.png``
for each vehicle with a tensor (principal moments against log start time, or against the log
number when the start times do not tell the logs apart, with one- and three-sigma bands;
outliers circled in red, failed logs as grey ticks).

Outliers
--------
Logs of one vehicle are taken in order of their start time; each log with a tensor is
compared with the vehicle's previous log with a tensor.  For each tensor element known in
both (``theta = [ixx, iyy, izz, ixy, ixz, iyz]``, k of them),

    z_i = (theta_i - theta_prev_i) / sqrt(sigma_i^2 + sigma_prev_i^2).

The log is an outlier when the largest ``|z_i|`` is less likely than a 3-sigma normal
deviation once the k looks are paid for (Sidak: ``p = 1 - (1 - 2 Q(max |z|))^k < 0.0027``, Q
the normal tail), and ``sigma`` reports that p-value as a normal deviation.  Sidak's bound
holds whatever the correlation between the elements' errors, which the reports do not give
(their diagonal-element errors are strongly correlated: a chi-square treating them as
independent flags ordinary logs).  A payload change or damage is flagged once (at the first
log after it); one bad log is flagged twice (entering it and leaving it).
"""
from __future__ import annotations

import math
import re
from collections import Counter, defaultdict
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from inertia_ros.core.tensor import THETA_NAMES
from inertia_ros.fleet.run import ERROR, FAILED

__all__ = ['THRESHOLD_SIGMA', 'find_outliers', 'status_counts', 'write_report']

#: Outlier threshold in equivalent normal sigmas.
THRESHOLD_SIGMA = 3.0
#: Statuses whose tensor is usable for the trend (a tensor with at least one element).
_WITH_TENSOR = ('ok', 'model_mismatch', 'partially_identifiable')


def _vehicle(row: dict[str, Any]) -> str:
    return row.get('vehicle') or '(unknown)'


def _order(row: dict[str, Any]) -> tuple[int, str]:
    t = row.get('log_start_ns')
    return (t if t is not None else 2 ** 63 - 1, row.get('path') or '')


def _has_tensor(row: dict[str, Any]) -> bool:
    return row.get('status') in _WITH_TENSOR and any(row.get(n) is not None
                                                     for n in THETA_NAMES)


def _sigma_equivalent(zmax: float, k: int) -> float:
    """The two-sided normal deviation with the Sidak-adjusted p-value of ``max |z|`` of k."""
    from scipy import stats

    log_p = math.log(2.0) + float(stats.norm.logsf(zmax))  # log P(|Z| > zmax)
    if log_p < -700:  # beyond double precision: P_adj ~ k P, and the deviation ~ zmax
        log_adj = math.log(k) + log_p
        return float(zmax) if log_adj < -700 else float(stats.norm.isf(math.exp(log_adj) / 2))
    p = math.exp(log_p)
    if p >= 1.0:
        return 0.0
    p_adj = -math.expm1(k * math.log1p(-p))
    return float(stats.norm.isf(min(p_adj, 1.0) / 2))


def compare(prev: dict[str, Any], cur: dict[str, Any]) -> dict[str, Any] | None:
    """How far ``cur``'s tensor is from ``prev``'s in sigmas; None if nothing comparable.

    Returns
    -------
    dict or None
        ``k`` (elements compared), ``sigma`` (the Sidak-adjusted equivalent normal
        deviation), ``worst`` (element with the largest ``|z|``), ``z`` (that ``|z|``).
    """
    z: dict[str, float] = {}
    for n in THETA_NAMES:
        a, b = prev.get(n), cur.get(n)
        sa, sb = prev.get(n + '_std'), cur.get(n + '_std')
        if None in (a, b, sa, sb):
            continue
        s = math.hypot(sa, sb)
        if not (s > 0 and math.isfinite(s)):
            continue
        z[n] = (b - a) / s
    if not z:
        return None
    worst = max(z, key=lambda n: abs(z[n]))
    return {'k': len(z), 'sigma': _sigma_equivalent(abs(z[worst]), len(z)),
            'worst': worst, 'z': abs(z[worst])}


def find_outliers(rows: Iterable[dict[str, Any]], threshold: float = THRESHOLD_SIGMA
                  ) -> list[dict[str, Any]]:
    """Logs whose tensor differs from their vehicle's previous one by more than ``threshold``.

    The previous one is the latest earlier log with status ``ok`` (the first log's successor
    compares with it whatever its status): a ``model_mismatch`` log (a payload change inside
    it) carries a sigma widened by its own window scatter, so it hides the jump as a reference;
    the next ``ok`` log is then compared with the last ``ok`` one before the change.

    Parameters
    ----------
    rows : iterable of dict
        Fleet rows (:data:`inertia_ros.fleet.table.COLUMNS`).
    threshold : float, optional
        In equivalent normal sigmas (default 3).

    Returns
    -------
    list of dict
        ``vehicle, path, log_start, previous, sigma, worst, z, dI`` (change of the principal
        moments [kg m^2], or None), ordered by vehicle and time.
    """
    by_vehicle: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        if _has_tensor(r):
            by_vehicle[_vehicle(r)].append(r)
    out = []
    for v in sorted(by_vehicle):
        seq = sorted(by_vehicle[v], key=_order)
        prev = seq[0]
        for cur in seq[1:]:
            record = _outlier(v, prev, cur, threshold)
            if record is not None:
                out.append(record)
            if cur.get('status') == 'ok' or prev.get('status') != 'ok':
                prev = cur
    return out


def _outlier(vehicle: str, prev: dict[str, Any], cur: dict[str, Any], threshold: float
             ) -> dict[str, Any] | None:
    """The outlier record of ``cur`` against ``prev`` (:func:`find_outliers`), or None."""
    c = compare(prev, cur)
    if c is None or c['sigma'] <= threshold:
        return None
    dI = None
    if all(cur.get(f'I{k}') is not None and prev.get(f'I{k}') is not None for k in (1, 2, 3)):
        dI = [cur[f'I{k}'] - prev[f'I{k}'] for k in (1, 2, 3)]
    return {'vehicle': vehicle, 'path': cur['path'], 'log_start': cur.get('log_start'),
            'previous': prev['path'], 'sigma': c['sigma'], 'worst': c['worst'], 'z': c['z'],
            'dI': dI}


def status_counts(rows: Iterable[dict[str, Any]]) -> Counter[str]:
    """Number of rows per status."""
    return Counter(str(r.get('status')) for r in rows)


def _safe_name(vehicle: str) -> str:
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', vehicle).strip('._') or 'vehicle'


def _distinct_times(rows: Sequence[dict[str, Any]]) -> bool:
    """True when the logs' start times tell them apart (all known and all different)."""
    times = [r.get('log_start_ns') for r in rows]
    return None not in times and len(set(times)) == len(times)


def _plot_vehicle(path: Path, vehicle: str, rows: Sequence[dict[str, Any]],
                  outliers: Sequence[dict[str, Any]]) -> None:
    """The trend PNG of one vehicle's logs (``rows`` in report order, at least one with its
    three principal moments).

    The x axis is the log start time (UTC) when the logs with a tensor have distinct start
    times; otherwise (copies of one log, or logs whose clocks all start at the same instant)
    it is the log's number in report order (start time, then path), as the axis says.
    """
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.dates as mdates
    import matplotlib.pyplot as plt
    import numpy as np

    good = [r for r in rows if _has_tensor(r)
            and all(r.get(f'I{k}') is not None for k in (1, 2, 3))]
    by_time = _distinct_times(good)
    number = {r['path']: i for i, r in enumerate(rows, start=1)}

    def where(r: dict[str, Any]) -> Any:
        return np.datetime64(int(r['log_start_ns']), 'ns') if by_time else number[r['path']]

    bad = [r for r in rows if r.get('status') in (ERROR, FAILED)
           and (not by_time or r.get('log_start_ns') is not None)]
    flagged = {o['path'] for o in outliers}
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True, layout='constrained')
    colors = ('tab:blue', 'tab:orange', 'tab:green')
    t = np.array([where(r) for r in good])
    fl = np.array([r['path'] in flagged for r in good], dtype=bool)
    for k, (ax, c) in enumerate(zip(axes, colors, strict=True), start=1):
        m = np.array([r[f'I{k}'] for r in good], dtype=float)
        s = np.array([r.get(f'I{k}_std') or 0.0 for r in good], dtype=float)
        ax.fill_between(t, m - 3 * s, m + 3 * s, color=c, alpha=0.15, lw=0, label='3 sigma')
        ax.fill_between(t, m - s, m + s, color=c, alpha=0.35, lw=0, label='1 sigma')
        ax.plot(t, m, '.-', color=c, lw=0.8, ms=4, label=f'I{k}')
        if fl.any():
            ax.plot(t[fl], m[fl], 'o', mfc='none', mec='tab:red', ms=10, mew=1.5,
                    label='outlier (> 3 sigma from the previous log)')
        for i, r in enumerate(bad):
            ax.axvline(where(r), color='0.5', lw=0.8, ls=':',
                       label=f'{r["status"]} (no estimate)' if i == 0 else None)
        ax.set_ylabel(f'I{k} [kg m^2]')
        ax.legend(loc='best', fontsize=7)
    n_bad = sum(1 for r in rows if not _has_tensor(r))
    axes[0].set_title(f'{vehicle}: principal moments per log with 1 and 3 sigma bands '
                      f'({len(rows)} logs, {n_bad} without a tensor)')
    if by_time:
        axes[-1].set_xlabel('log start (UTC)')
        axes[-1].xaxis.set_major_formatter(
            mdates.ConciseDateFormatter(mdates.AutoDateLocator()))
    else:
        axes[-1].set_xlabel('log number, in order of start time then path (the start times '
                            'do not tell the logs apart)')
        axes[-1].xaxis.get_major_locator().set_params(integer=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _cell(v: Any) -> str:
    if v is None:
        return ''
    return str(v).replace('|', '\\|').replace('\n', ' ')


def _n(count: int, noun: str) -> str:
    """``'1 outlier'``, ``'2 outliers'``."""
    return f'{count} {noun}{"" if count == 1 else "s"}'


def _outlier_lines(outliers: Sequence[dict[str, Any]]) -> list[str]:
    if not outliers:
        return ['None.']
    lines = ['| vehicle | log | start (UTC) | previous log | sigma | largest change | '
             'dI1, dI2, dI3 [kg m^2] |', '| --- | --- | --- | --- | ---: | --- | --- |']
    for o in outliers:
        dI = '' if o['dI'] is None else ', '.join(f'{x:+.4g}' for x in o['dI'])
        lines.append(f'| {_cell(o["vehicle"])} | {_cell(o["path"])} | '
                     f'{_cell(o["log_start"])} | {_cell(o["previous"])} | '
                     f'{o["sigma"]:.1f} | {o["worst"]} ({o["z"]:.1f} sigma) | {dI} |')
    return lines


def _png_names(vehicles: Sequence[str]) -> dict[str, str]:
    """A distinct, filesystem-safe ``trend_*.png`` name per vehicle."""
    pngs: dict[str, str] = {}
    for v in vehicles:
        name = _safe_name(v)
        while f'trend_{name}.png' in pngs.values():
            name += '_'
        pngs[v] = f'trend_{name}.png'
    return pngs


def _without_estimate(vehicle: str, rows: Sequence[dict[str, Any]]) -> list[str]:
    """Table lines of the logs that gave no tensor: errors, failures and the estimates that
    identified nothing (insufficient_excitation, scale_unobservable, ...), with why."""
    return [f'| {_cell(vehicle)} | {_cell(r.get("path"))} | {_cell(r.get("status"))} | '
            f'{_cell(r.get("error") or r.get("reason"))} |'
            for r in rows if not _has_tensor(r)]


def write_report(rows: Sequence[dict[str, Any]], out_dir: str | Path,
                 threshold: float = THRESHOLD_SIGMA) -> Path:
    """Write the Markdown report and a trend PNG per vehicle with a tensor; return the
    Markdown path.

    Each vehicle's logs are in order of start time, then path (logs that share a start
    time, such as copies of one log, are ordered by path, and their plot is against the
    log number; the report says so).  A vehicle none of whose logs gave a tensor has no
    plot.

    Parameters
    ----------
    rows : sequence of dict
        Fleet rows.
    out_dir : str or Path
        Created if missing.
    threshold : float, optional
        Outlier threshold in sigmas.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    outliers = find_outliers(rows, threshold)
    counts = status_counts(rows)
    by_vehicle: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        by_vehicle[_vehicle(r)].append(r)
    lines = ['# Fleet report', '',
             f'{_n(len(rows), "log")}, {_n(len(by_vehicle), "vehicle")}, '
             f'{_n(len(outliers), "outlier")} (a tensor more than {threshold:g} sigma from '
             f'the vehicle\'s previous one; each vehicle\'s logs in order of start time, '
             f'then path).', '',
             '## Status counts', '', '| status | logs |', '| --- | ---: |']
    lines += [f'| {s} | {n} |' for s, n in sorted(counts.items(), key=lambda x: (-x[1], x[0]))]
    lines += ['', '## Outliers', '', *_outlier_lines(outliers)]
    lines += ['', '## Vehicles', '',
              '| vehicle | logs | with a tensor | errors | outliers | latest I1, I2, I3 '
              '[kg m^2] | trend |', '| --- | ---: | ---: | ---: | ---: | --- | --- |']
    missing: list[str] = []
    pngs = _png_names(sorted(by_vehicle))
    plotted: list[str] = []
    same_time: list[str] = []
    for v in sorted(by_vehicle):
        vr = sorted(by_vehicle[v], key=_order)
        tens = [r for r in vr if _has_tensor(r)]
        full = [r for r in tens if all(r.get(f'I{k}') is not None for k in (1, 2, 3))]
        trend = 'none (no log with a tensor)'
        if full:
            _plot_vehicle(out / pngs[v], v, vr, [o for o in outliers if o['vehicle'] == v])
            plotted.append(v)
            trend = f'[{pngs[v]}]({pngs[v]})'
            if not _distinct_times(full):
                same_time.append(v)
        latest = ', '.join(f'{full[-1][f"I{k}"]:.4g}' for k in (1, 2, 3)) \
            if full and full[-1] is tens[-1] else ''
        errs = [r for r in vr if r.get('status') in (ERROR, FAILED)]
        missing += _without_estimate(v, vr)
        lines.append(f'| {_cell(v)} | {len(vr)} | {len(tens)} | {len(errs)} | '
                     f'{sum(o["vehicle"] == v for o in outliers)} | {latest} | {trend} |')
    if same_time:
        lines += ['', f'Logs of {", ".join(_cell(v) for v in same_time)} share start times '
                      '(copies of one log, or clocks that all start at the same instant): '
                      'they are ordered by path, and plotted against their number in that '
                      'order.']
    lines += ['', '## Logs without an estimate', '']
    lines += (['| vehicle | log | status | why |', '| --- | --- | --- | --- |', *missing]
              if missing else ['None.'])
    lines += ['', '## Trends', '', *(f'![{_cell(v)}]({pngs[v]})' for v in plotted)]
    md = out / 'fleet_report.md'
    md.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    return md
