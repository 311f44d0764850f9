"""``method='auto'``: the formulation and its band from the data, as an expert would choose.

A real gyro on a body with spinning parts sees what the rigid-body model lacks: a line at each
wheel's or rotor's rotation frequency (its imbalance) and harmonics, structural modes, a
band-limited and coloured sensor.  The ``integral`` and ``ml`` formulations take every gyro
sample at face value (white noise about the rigid-body rate), so there they are biased and
their sigma too small; the ``filtered`` formulation (:mod:`.filtered`) with its band below the
lowest line keeps only the rigid-body motion.  On data the model does describe, ``ml`` (or
``integral`` on long records) is the best there is.  The choice:

1. **Evidence.**  The ``integral`` fit is made first (``ml`` starts from it anyway).  Its
   momentum-equation residual ``r_b = I w_b + int w x I w dt - int tau dt - d t_b`` is white
   gyro noise (``I n_b``) above the slow random walk of the integrated torque noise when the
   model holds.  Its spectrum (Welch, :func:`residual_spectrum`) is searched from
   ``10 / span`` (a usable cutoff's band edge) for lines (bins far above their neighbourhood)
   and excess power: a conforming residual spectrum never rises with frequency (white floors
   of the gyro and the wheel speeds, ``1 / f^2`` walks of the integrated noises, each ending
   at its sensor's band), so a bin far above the lowest smoothed level below it is excess,
   with thresholds from the Welch estimate's own chi-square spread (:func:`spectral_evidence`).
2. **Band.**  The band edge is the lowest line or excess found, and the lowest rotation line
   of the wheels or rotors when their speeds are known (``rotation_hz``).  The filter cutoff
   is at most half of it (a fourth-order Butterworth is 24 dB down there), and lower where
   the gyro's error needs more: the highest cutoff at which it is at most 1/16 of the filtered
   method's own errors-in-variables limit (0.2 %) of the band-limited derivative's power
   (:func:`needed_cutoff`; a strong line is a regressor error whose share shrinks the fit).
   It is at least ``5 / span`` (the filtered method's covariance needs periods: a hand-set
   cutoff of 7.8 periods on 0.5 s throws kept its sigma true); a cutoff too low for the
   motion loses information, which the predicted variances show.
3. **Candidates and one rule.**  Without spectral evidence the choice is today's (``ml`` up
   to :data:`.options.ML_AUTO_MAX_SAMPLES` gyro samples, else ``integral``): the rule below
   would not change it, and the result is then bit-identical to it.  A known rotation line
   counts as a suspect (candidates compared, no whiteness failure) when the integral fit is
   ``model_mismatch`` though the spectrum shows nothing (a record too short to resolve it).
   With evidence the candidates are ``integral``, ``ml`` (up to that many samples) and
   ``filtered`` at the band; each fails the tests it fails: its adequacy tests (status
   ``ok`` or not) and the spectral whiteness test in its own band (the evidence counts
   against ``integral`` and ``ml``, whose band is the whole spectrum, not against
   ``filtered`` below the edge).  The candidate with the fewest failed tests wins; among
   equals the smallest predicted relative variance of the tensor (``trace(cov) /
   scale^2``).  No fixed margin.  When the integral fit keeps a torque fixed in inertial
   axes (``inertial_torque``), ``ml`` is no candidate (its likelihood has no such torque
   yet: the ``ml`` default reports the integral result, ``diagnostics['ml']`` says why) and
   the residual spectrum is that of the fit with it.

The record, in ``diagnostics['method_selection']``: ``requested``, ``chosen``, ``rule`` (as
before), and ``evidence`` (the lines, the excess, the floor, the band edge and cutoff, the
known rotation line) and ``candidates`` (per candidate: status, failed tests, predicted
relative variance).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .._numeric import median, median_rows
from .align import cumtrapz
from .filtered import MAX_NOISE_SHARE as _MAX_NOISE_SHARE
from .options import ML_AUTO_MAX_SAMPLES
from .regressors import cumulative_torque
from .tails import normal_isf

#: Welch segments the residual spectrum averages at most: on longer records an evenly spread
#: subset of them (the 1024-sample segments of 11 min at 200 Hz, 2.2 min at 1 kHz).  The
#: spectrum is an average: with 3 x 256 segments its spread is ~4 % a bin and a bin may lie
#: 1.18x above its reference by chance (:func:`_threshold`; 1.07x with the 1405 segments of
#: an hour at 200 Hz), while the time grows with the segments.
MAX_SEGMENTS = 256

__all__ = ['DEFAULT_RULE', 'choose', 'lowest_rotation_hz', 'residual_spectrum',
           'spectral_evidence']

#: The ``rule`` of the choice without spectral evidence (the record's ``rule`` field).
DEFAULT_RULE = f'ml up to {ML_AUTO_MAX_SAMPLES} gyro samples, integral beyond'
_RULE = ('fewest failed tests (adequacy: status ok; whiteness of the residual spectrum in the '
         "candidate's band), then the smallest predicted relative variance")
_FALSE_ALARM = 1e-3          # chance that a model-conforming spectrum shows a line or excess
_EDGE_TO_CUTOFF = 0.5        # filter cutoff / band edge
_MIN_PERIODS = 5.0           # the record spans at least this many 1 / cutoff
_ORDER = 4                   # the filtered method's Butterworth order
#: Largest gyro-error share of the filtered regressor at the chosen cutoff.  The fit shrinks
#: by about 4x the share (measured on inertia_ros.bench.vibration_sim records, white noise
#: only: 0.36 % share, 1.3 % error): 1/16 of the filtered method's limit keeps it <= 0.05 %
_LEAK_SHARE = _MAX_NOISE_SHARE / 16
_SPINNING_HZ = 1.0           # a wheel or rotor slower than this has no line


def lowest_rotation_hz(speed: Any) -> float | None:
    """The lowest rotation line of spinning wheels or rotors [Hz].

    Parameters
    ----------
    speed : array_like, shape (K, n)
        Joint speeds [rad/s] over the record.

    Returns
    -------
    float or None
        Over the joints whose median speed is above 1 Hz: the smallest 2nd percentile of
        ``|speed| / 2 pi``; None when no joint spins.
    """
    s = np.asarray(speed, dtype=float)
    if not s.size:
        return None
    s = np.abs(s.reshape(len(s), -1)) / (2 * np.pi)
    s = s[:, np.all(np.isfinite(s), axis=0)]
    if not s.size:
        return None
    spinning = np.median(s, axis=0) > _SPINNING_HZ
    if not np.any(spinning):
        return None
    return float(np.min(np.percentile(s[:, spinning], 2.0, axis=0)))


def residual_spectrum(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                      inertia: np.ndarray, bias: Any, hold: str, inertial: Any = None
                      ) -> tuple[np.ndarray, np.ndarray, int]:
    """Welch spectrum of the momentum-equation residual of a fitted tensor.

    Parameters
    ----------
    tg, w : ndarray, shape (N,), (N, 3)
        Gyro stamps [s] and rates [rad/s].
    ts, tau : ndarray, shape (M,), (M, 3)
        Torque stamps [s] and torque [N m] (held or linear, ``hold``).
    inertia : ndarray, shape (3, 3)
        Fitted tensor [kg m^2].
    bias : array_like (3,) or None
        Fitted torque bias [N m].
    hold : str
        ``'zoh'`` or ``'linear'``.
    inertial : array_like (3,), optional
        Fitted torque fixed in inertial axes [N m], in body axes at the first gyro sample in
        the torque coverage: its impulse ``C(t) d`` (:mod:`.attitude`) is removed too.

    Returns
    -------
    f, psd : ndarray, shape (F,)
        Frequencies [Hz] and the residual's one-sided spectral density summed over the axes
        [N^2 m^2 s^2 / Hz].
    segments : int
        Welch segments averaged (the estimate's chi-square spread: ``2 segments`` dof): all
        of them up to :data:`MAX_SEGMENTS`, else that many spread evenly over the record.
    """
    # the gyro samples inside the torque's coverage: one run of the sorted stamps (views)
    a, b = _inside(tg, ts)
    t = tg[a:b]
    fs = 1.0 / median(np.diff(t))
    nper = int(2 ** np.floor(np.log2(max(len(t) / 4.0, 16.0))))
    nper = min(nper, 1024)
    step = max(nper // 2, 1)
    n_seg = max((len(t) - nper) // step + 1, 0)
    impulse = None
    if inertial is not None:                 # C(t) d, (n, 3), over the run from its start
        from .attitude import attitude_integral

        impulse = attitude_integral(t, w[a:b]) @ np.asarray(inertial, dtype=float)
    if n_seg <= MAX_SEGMENTS:
        r = _residual(t, w[a:b], ts, tau, inertia, bias, hold, t[0])
        if impulse is not None:
            r -= impulse
        return _welch(r, fs, nper)
    # a long record: an evenly spread subset of the same segments, each residual from its own
    # start (the integral's constant and the bias's ramp are removed by the detrending)
    first = step * np.round(np.linspace(0, n_seg - 1, MAX_SEGMENTS)).astype(np.intp)
    rows = (a + first)[:, None] + np.arange(nper)                   # (K, nper)
    r = _residual(tg[rows], w[rows], ts, tau, inertia, bias, hold, t[0])
    if impulse is not None:
        r -= impulse[rows - a]
    f, p = _welch_power(r.transpose(2, 0, 1), fs, nper)
    return f, p, MAX_SEGMENTS


def _residual(t: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
              inertia: np.ndarray, bias: Any, hold: str, t0: float) -> np.ndarray:
    """``I w + int w x I w dt - int tau dt - d (t - t0)`` along the last-but-one axis.

    ``t`` (..., n), ``w`` (..., n, 3): one run of samples or (K, n) pieces of runs, each
    piece's gyroscopic integral from its own first sample (trapezoid); returns (..., n, 3).
    """
    h = w @ inertia.T
    gyro = np.empty_like(h)                                # w x (I w), as np.cross
    gyro[..., 0] = w[..., 1] * h[..., 2] - w[..., 2] * h[..., 1]
    gyro[..., 1] = w[..., 2] * h[..., 0] - w[..., 0] * h[..., 2]
    gyro[..., 2] = w[..., 0] * h[..., 1] - w[..., 1] * h[..., 0]
    r = cumtrapz(t, gyro)                                  # int w x I w dt
    r += h
    if len(ts) >= 2:                                       # - int tau dt, held or linear
        r -= cumulative_torque(ts, tau, t.reshape(-1), hold).reshape(r.shape)
    if bias is not None:
        r -= (t - t0)[..., None] * np.asarray(bias, dtype=float)
    return r


def _inside(tg: np.ndarray, ts: np.ndarray) -> tuple[int, int]:
    """The gyro samples ``a:b`` inside ``[ts[0], ts[-1]]`` (all without torque)."""
    if len(ts) < 2:
        return 0, len(tg)
    return (int(np.searchsorted(tg, ts[0], side='left')),
            int(np.searchsorted(tg, ts[-1], side='right')))


def _welch(x: np.ndarray, fs: float, nper: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Welch's one-sided density of ``x`` (n, 3) summed over the columns: Hann windows of
    ``nper`` samples, half overlapping, each linearly detrended (as ``scipy.signal.welch``
    with ``detrend='linear'``, without its ~1 s import on the default path).  All segments
    at once: a strided view of the columns, one detrending product and one ``rfft``."""
    step = max(nper // 2, 1)
    n_seg = max((len(x) - nper) // step + 1, 0)
    xt = np.ascontiguousarray(x.T)                                  # (3, n)
    s0, s1 = xt.strides
    segs = np.lib.stride_tricks.as_strided(xt, (3, n_seg, nper), (s0, step * s1, s1),
                                           writeable=False)         # (3, segments, nper)
    return (*_welch_power(segs, fs, nper), n_seg)


def _welch_power(segs: np.ndarray, fs: float, nper: int) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] and the density of :func:`_welch` from its segments (3, K, nper)."""
    win = np.hanning(nper + 1)[:-1] if nper > 1 else np.ones(1)   # periodic Hann
    u = np.arange(nper) - 0.5 * (nper - 1)
    seg = segs - segs.mean(axis=2, keepdims=True)
    seg -= ((segs @ u) / (u @ u))[..., None] * u
    seg *= win
    spec = np.fft.rfft(seg, axis=2)
    pw = spec.real ** 2
    pw += spec.imag ** 2
    p = np.sum(pw, axis=(0, 1)) / (segs.shape[1] * fs * float(win @ win))
    p[1:-1] *= 2.0                       # one-sided (nper even)
    return np.fft.rfftfreq(nper, 1.0 / fs), p


def _threshold(segments: int, bins: int) -> float:
    """How far above its reference a Welch bin may lie by chance (all ``bins`` together at
    :data:`_FALSE_ALARM`): the chi-square quantile of ``2 segments`` (x3 axes) dof, over
    its mean."""
    dof = 2 * 3 * segments
    # (the tail of the rounded 1 - p, as NormalDist().inv_cdf(1 - p) took it)
    z = normal_isf(1.0 - (1.0 - _FALSE_ALARM / max(bins, 1)))
    # Wilson-Hilferty, kept on purpose (issue 26): the exact quantile (.tails.chi2_isf) is
    # 0.04 % (32 segments) to 4 % (1 segment, 4096 bins) lower: a change of the thresholds
    # beyond rounding, which the folding of the quantiles was not to make
    return float((1.0 - 2.0 / (9 * dof) + z * np.sqrt(2.0 / (9 * dof))) ** 3)


def _percentile(x: np.ndarray, q: float) -> float:
    """``np.percentile(x, q)`` of a finite 1-D ``x`` (linear), bit for bit, by one partition
    (``np.percentile`` imports ``numpy.ma``, ~5 ms of the default path's start-up)."""
    vi = (len(x) - 1) * (q / 100)
    lo = int(math.floor(vi))
    hi = min(lo + 1, len(x) - 1)
    part = np.partition(x, [lo, hi])
    a, b, g = float(part[lo]), float(part[hi]), vi - lo
    return b - (b - a) * (1 - g) if g >= 0.5 else a + (b - a) * g


def spectral_evidence(f: np.ndarray, psd: np.ndarray, segments: int, span: float
                      ) -> dict[str, Any]:
    """Lines and excess high-frequency power in a residual spectrum (module docstring, 1).

    Parameters
    ----------
    f, psd : ndarray, shape (F,)
        From :func:`residual_spectrum`.
    segments : int
        Welch segments.
    span : float
        Record length [s].

    Returns
    -------
    dict
        ``lines_hz`` (peaks above their neighbourhood), ``excess_from_hz`` (the first bin far
        above the lowest smoothed level below it, or None), ``floor`` (the white floor's density),
        ``searched_from_hz``, ``threshold`` (bin / reference ratio that counts), ``edge_hz``
        (the lowest of them, or None), ``found`` (bool) and ``noise`` (``f`` and the
        residual density, the floor below the search: the regressor error of
        :func:`needed_cutoff`; not for the report).
    """
    lo = _MIN_PERIODS / (_EDGE_TO_CUTOFF * span)
    sel = (f >= lo) & (f <= 0.9 * f[-1])
    out: dict[str, Any] = {'searched_from_hz': lo, 'lines_hz': [], 'excess_from_hz': None,
                           'floor': None, 'threshold': None, 'edge_hz': None, 'found': False}
    if np.count_nonzero(sel) < 8:
        return out
    fb, pb = f[sel], psd[sel]
    thr = _threshold(segments, len(pb))
    floor = _percentile(pb, 20.0)
    # a model-conforming residual spectrum never rises with frequency: white floors (gyro,
    # wheel speeds) and 1 / f^2 walks (integrated torque noise), each ending at its sensor's
    # band; a line or a resonance is a rise above the lowest (smoothed) level below it
    padded = np.pad(pb, 4, mode='edge')
    smooth = median_rows(np.lib.stride_tricks.sliding_window_view(padded, 9).T)
    model = np.minimum.accumulate(smooth)
    peak = (pb > thr * smooth) & (pb >= np.r_[0, pb[:-1]]) & (pb >= np.r_[pb[1:], 0])
    far = pb > 2.0 * thr * model
    lines = [float(x) for x in fb[peak & far]]
    excess = float(fb[np.argmax(far)]) if np.any(far) else None
    edges = [x for x in [*lines[:1], excess] if x is not None]
    # below the search the residual is the integrated noises' walk, not a regressor error
    out.update(lines_hz=lines, excess_from_hz=excess, floor=floor, threshold=thr,
               edge_hz=min(edges) if edges else None, found=bool(edges),
               noise=(f, np.where(f >= lo, psd, floor)))
    return out


def needed_cutoff(noise: tuple[np.ndarray, np.ndarray], start: float, lowest: float,
                  tg: np.ndarray, w: np.ndarray, scale: float) -> tuple[float, float]:
    """The highest cutoff at which the gyro's error (noise, lines, coloured noise) is at
    most ``_LEAK_SHARE`` of the filtered regressor's power (errors in variables).

    The momentum residual's density over the tensor scale squared is the gyro's error
    density ``E``; through the filtered method's band-limited differentiator ``s H`` it
    gives ``sum E_k df |H(f_k)|^2 (2 pi f_k)^2`` in the ``s H w`` regressor, whose power
    is that of the filtered gyro.  Cutoffs from ``start`` down by factors of 0.85 to
    ``lowest`` are tried.

    Parameters
    ----------
    noise : (f (F,), density (F,))
        From :func:`spectral_evidence` [Hz], [N^2 m^2 s^2 / Hz].
    start, lowest : float
        Highest and lowest cutoff tried [Hz].
    tg, w : ndarray, shape (N,), (N, 3)
        Gyro stamps [s] and rates [rad/s].
    scale : float
        Tensor scale (mean principal moment) [kg m^2].

    Returns
    -------
    cutoff : float
        [Hz]; ``lowest`` when none qualifies.
    share : float
        The leaked share of the regressor power at that cutoff.
    """
    from scipy import signal

    from .filtered import filter_coefficients

    fk, ek = noise
    df = float(fk[1] - fk[0]) if len(fk) > 1 else 1.0
    gyro_excess = ek * df / max(scale, 1e-300) ** 2 * (2 * np.pi * fk) ** 2
    dt = float(np.median(np.diff(tg)))
    fc, share = max(start, lowest), np.inf
    while True:
        b, a = filter_coefficients(fc, dt)
        reg = signal.lfilter(b, a, w - w[0], axis=0)[int(2.0 / (fc * dt)):]
        power = float(np.sum(np.mean(reg ** 2, axis=0))) if len(reg) else 0.0
        leak = float(np.sum(gyro_excess / (1.0 + (fk / fc) ** (2 * _ORDER))))
        share = leak / power if power > 0 else np.inf
        if share <= _LEAK_SHARE or fc <= lowest:
            return fc, share
        fc = max(0.85 * fc, lowest)


def _relative_variance(res: Any) -> float:
    """``trace(cov(theta)) / scale^2`` of a result (inf when it has no tensor)."""
    if res.inertia is None or res.covariance is None:
        return float('inf')
    cov = np.nan_to_num(np.asarray(res.covariance), nan=np.inf)
    scale = float(np.mean(np.abs(np.diag(np.nan_to_num(res.inertia)))))
    return float(np.trace(cov)) / scale ** 2 if scale > 0 else float('inf')


def choose(first: Any, data: tuple[np.ndarray, ...], hold: str, n_gyro: int,
           refine: Callable[[Any], Any], filtered: Callable[[float], Any],
           rotation_hz: float | None = None) -> Any:
    """The ``method='auto'`` result (module docstring).

    Parameters
    ----------
    first : InertiaEstimate
        The ``integral`` estimate (``method_selection`` not yet set).
    data : (tg, w, ts, tau)
        The data it was fitted on (stamps [s], rates [rad/s], torque stamps [s], [N m]).
    hold : str
        The hold the torque was fitted with.
    n_gyro : int
        Gyro samples of the record (today's rule).
    refine : callable
        ``refine(first)``: the ``ml`` result from the integral one.
    filtered : callable
        ``filtered(cutoff_hz)``: the ``filtered`` result at that cutoff.
    rotation_hz : float, optional
        Lowest rotation line of the known wheels or rotors [Hz].

    Returns
    -------
    InertiaEstimate
        The chosen result, ``diagnostics['method_selection']`` filled.
    """
    default = 'ml' if n_gyro <= ML_AUTO_MAX_SAMPLES else 'integral'
    sel: dict[str, Any] = {'requested': 'auto', 'chosen': default, 'rule': DEFAULT_RULE}
    if default == 'ml' and first.inertial_torque is not None:
        # the likelihood has no inertial torque yet: refine keeps the integral result (its
        # diagnostics say why), and the candidates are integral and filtered
        first, default = refine(first), 'integral'
        sel.update(chosen=default, rule=DEFAULT_RULE + '; integral when a torque fixed in '
                   'inertial axes is kept (the likelihood model has none yet)')
    ev = _evidence(first, data, hold, rotation_hz)
    sel['evidence'] = ev
    if ev['cutoff_hz'] is None:
        res = refine(first) if default == 'ml' else first
        return _with(res, sel)
    cands = {'integral': first}
    if default == 'ml':
        cands['ml'] = refine(first)
    cands['filtered'] = filtered(ev['cutoff_hz'])
    table: dict[str, Any] = {}
    for name, res in cands.items():
        failed = [] if res.status == 'ok' else [f'adequacy ({res.status})']
        if name != 'filtered' and ev['found']:   # the filtered band ends below the edge
            failed.append(f'whiteness: lines or excess from {ev["edge_hz"]:.4g} Hz')
        table[name] = {'status': res.status, 'method': res.method, 'failed': failed,
                       'relative_variance': _relative_variance(res)}
    best = min(table, key=lambda k: (len(table[k]['failed']), table[k]['relative_variance']))
    sel.update(chosen=best, rule=_RULE, candidates=table)
    return _with(cands[best], sel)


def _evidence(first: Any, data: tuple[np.ndarray, ...], hold: str,
              rotation_hz: float | None) -> dict[str, Any]:
    """The spectral evidence of ``first``'s residual and the band it implies."""
    tg, w, ts, tau = data
    span = float(tg[-1] - tg[0])
    ev: dict[str, Any] = {'rotation_hz': rotation_hz, 'found': False, 'edge_hz': None,
                          'cutoff_hz': None}
    a, b = _inside(tg, ts)
    inside = b - a
    if first.inertia is None or not np.all(np.isfinite(first.inertia)) or inside < 64:
        ev['reason'] = ('no integral tensor to take the residual of' if inside >= 64 else
                        f'{inside} gyro samples in the torque coverage: too few for a spectrum')
        return ev
    f, psd, seg = residual_spectrum(tg, w, ts, tau, np.asarray(first.inertia),
                                    first.torque_bias, hold, first.inertial_torque)
    ev.update(spectral_evidence(f, psd, seg, span))
    edges = [x for x in (ev['edge_hz'], rotation_hz) if x is not None]
    # a known rotation line is a suspect when the integral fit fails its adequacy tests,
    # though the (short) record's spectrum does not resolve it
    if edges and (ev['found'] or first.status == 'model_mismatch'):
        edge = min(edges)
        ev['edge_hz'] = edge
        lowest = _MIN_PERIODS / span
        cutoff, share = needed_cutoff(ev['noise'], _EDGE_TO_CUTOFF * edge, lowest, tg, w,
                                      float(np.trace(first.inertia)) / 3.0)
        ev['leakage_share'] = share
        if share > _LEAK_SHARE:
            ev['reason'] = (f'even the lowest usable cutoff {lowest:.4g} Hz ({_MIN_PERIODS:g} '
                            f'/ span) leaves {100 * share:.3g} % of the regressor power as '
                            'excess')
        if cutoff < 0.5 * f[-1]:
            ev['cutoff_hz'] = cutoff
    ev.pop('noise', None)
    return ev


def _with(res: Any, sel: dict[str, Any]) -> Any:
    """``res`` with ``diagnostics['method_selection'] = sel``."""
    diag = dict(res.diagnostics)
    diag['method_selection'] = sel
    from dataclasses import replace

    return replace(res, diagnostics=diag)
