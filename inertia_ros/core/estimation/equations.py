"""Equation builders of the batch methods: the stacked blocks ``y_b = X6_b theta + Xd_b d + e_b``.

Every method's equations are stored as the 13 per-sample variables ``V`` of
:func:`.regressors.variables` (``A = V @ VARIABLE_MAP``); see :mod:`.batch` for the methods.

``integral``, ``integral_ls``
    Momentum form anchored per segment (:func:`integral_equations`; ``kind='anchored'``).
``integral_sliding``
    Overlapping windows of fixed length (:func:`sliding_equations`; ``kind='hac'``).
``differential_fd``, ``differential_sg``
    Euler's equation at each gyro sample with a differentiated gyro
    (:func:`differential_equations`; ``kind='hac'``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._numeric import median
from .attitude import attitude_integral
from .options import GAP_FACTOR
from .regressors import (
    REGRESSOR_COLUMNS_WIDE,
    blocks,
    cumulative_monomials,
    cumulative_torque,
    monomials,
    variables,
)

__all__ = ['Equations', 'build_equations', 'differential_equations', 'integral_equations',
           'is_prefix', 'segment_starts', 'shared_integral_equations', 'sliding_equations',
           'thinned_inertial_equations']


@dataclass
class Equations:
    """Stacked 3-row equation blocks ``y_b = X6_b theta + Xd_b d + e_b``.

    Attributes
    ----------
    V : ndarray, shape (n, 13)
        Per-sample variables; the blocks are ``A = V @ VARIABLE_MAP`` (:attr:`A`); (n, 22)
        with a torque fixed in inertial axes (:data:`.regressors.VARIABLE_MAP_WIDE`).
    t : ndarray, shape (n,)
        Time of each equation [s].
    breaks : ndarray of bool, shape (n - 1,)
        A segment must start after this equation (gaps).
    kind : {'anchored', 'hac'}
        Anchored segments with intercepts and the model covariance, or overlapping /
        differentiated equations with the Newey-West (HAC) covariance.
    hac_lag : int
        HAC lag (``kind='hac'``).
    eiv_var : ndarray, shape (3,), optional
        Gyro-noise variance in the regressor per axis [rad^2/s^2] (errors in variables).
    weighted : bool
        Weighted by ``(I S_g I)^-1`` and bias-compensated (the ``integral`` method).
    info : dict
        Diagnostics of the builder (windows, noise shares).
    raw : dict, optional
        Statistics every segmentation shares (:func:`.statistics.shared_raw`), cached.
    motion : tuple of (ndarray (3, 3), float), optional
        Second moment ``mean(w w')`` of the used gyro samples [rad^2/s^2] and their median
        interval [s]: how much gyro noise the gyroscopic term carries into the equations.
    white_y_cov : ndarray, shape (3, 3), optional
        White noise in ``y`` besides the gyro's [N^2 m^2 s^2] (a momentum input's wheel-speed
        noise, :mod:`.momentum`).
    walk_cov : ndarray, shape (M, 3, 3), optional
        Time-varying covariance [N^2 m^2] of white torque noise held over each torque
        interval (a momentum input's ``n x h`` and ``w x e`` walks, :mod:`.momentum`), on
        the torque samples the statistics are built on (or a prefix of them).
    walk_wh : ndarray, shape (M, 9), optional
        The products ``w_i h_c`` [rad/s N m s] (index ``3 i + c``) over the same intervals:
        the cross term of the gyro noise's ``n x h`` and gyroscopic walks
        (:func:`.fit.walk_bases`).
    centred : bool
        ``V`` has had a constant removed (:func:`.statistics.shared_raw` does it once, in
        place, for conditioning; statistics are invariant to the constant).
    """

    V: np.ndarray
    t: np.ndarray
    breaks: np.ndarray
    kind: str
    hac_lag: int = 0
    eiv_var: np.ndarray | None = None
    weighted: bool = False
    info: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, Any] | None = None
    motion: tuple[np.ndarray, float] | None = None
    white_y_cov: np.ndarray | None = None
    centred: bool = False
    walk_cov: np.ndarray | None = None
    walk_wh: np.ndarray | None = None

    def head(self, n: int) -> Equations:
        """The first ``n`` equations (without the cached statistics)."""
        return self.rows(0, n, dict(self.info))

    def rows(self, a: int, b: int, info: dict[str, Any] | None = None,
             view: bool = False) -> Equations:
        """Equations ``a:b`` as their own set, without the cached statistics.

        A copy of ``V``, or with ``view`` a view of this set's already centred ``V`` (read
        only: its statistics need no second centring and no 13-column copy).
        """
        if view and not self.centred:
            raise ValueError('rows(view=True): V is not centred yet (see shared_raw)')
        return Equations(self.V[a:b] if view else self.V[a:b].copy(), self.t[a:b],
                         self.breaks[a:max(b - 1, a)], self.kind, self.hac_lag, self.eiv_var,
                         self.weighted, {} if info is None else info, motion=self.motion,
                         white_y_cov=self.white_y_cov, centred=view, walk_cov=self.walk_cov,
                         walk_wh=self.walk_wh)

    @property
    def A(self) -> np.ndarray:
        """Equation blocks, shape (n, 3, 10) (or (n, 3, 13) of wide variables)."""
        return blocks(self.V)


def segment_starts(t: np.ndarray, keep_break: np.ndarray, max_len: float | None) -> np.ndarray:
    """Segment start indices: at ``keep_break`` positions and every ``max_len`` seconds.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Equation times [s].
    keep_break : ndarray of bool, shape (n - 1,)
        A segment must start after these equations.
    max_len : float, optional
        Longest segment [s] (segments between breaks are cut into equal parts).

    Returns
    -------
    ndarray of int
        Sorted unique start indices, beginning with 0.
    """
    starts = [0, *(np.flatnonzero(keep_break) + 1).tolist()]
    if max_len is not None and max_len > 0:
        out: list[int] = []
        bounds = [*starts, len(t)]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            n_sub = max(1, int(np.floor((t[b - 1] - t[a]) / max_len + 0.5)))
            edges = np.linspace(t[a], t[b - 1], n_sub + 1)[1:-1]
            out += [a, *(a + np.searchsorted(t[a:b], edges)).tolist()]
        starts = out
    return np.asarray(sorted(set(starts)), dtype=int)      # (np.unique would load numpy.ma)


def integral_equations(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                       idx: slice | np.ndarray, breaks: np.ndarray, hold: str,
                       gyro_var: np.ndarray | None,
                       regressors: np.ndarray | None = None,
                       inertial: bool = False) -> Equations:
    """Anchored momentum equations of the gyro samples ``idx``.

    ``I w_b + int w x (I w) dt - d t_b - h0 = int tau dt`` from the start of the record
    (``h0`` removed per segment later).  With ``gyro_var`` (the ``integral`` method) the
    squared-rate integrals are corrected for the gyro noise and the equations are weighted
    and bias-compensated; without it (``integral_ls``) neither.

    Parameters
    ----------
    tg, w : ndarray, shape (N,), (N, 3)
        Gyro times [s] and angular velocity [rad/s].
    ts, tau : ndarray, shape (M,), (M, 3)
        Torque times [s] and torque [N m].
    idx : slice or ndarray of int
        The gyro samples used.
    breaks : ndarray of bool
        Forced segment starts between the used samples.
    hold : {'zoh', 'linear'}
        Torque between samples.
    gyro_var : ndarray, shape (3,), optional
        Gyro white-noise variance [rad^2/s^2].
    regressors : ndarray, shape (n, 10), optional
        The first 10 columns ``[w, m, s]`` of the same rows from an earlier call with the same
        ``tg, w, idx, breaks, gyro_var`` (they do not depend on the torque or its hold): only
        the torque integrals are computed (``hold='auto'`` builds both holds' equations);
        (n, 19) with ``inertial``: those and the attitude integral's nine.
    inertial : bool
        Also the nine variables ``C = int R' dt`` of a torque fixed in inertial axes (22
        columns; :mod:`.attitude`), the attitude integrated over every gyro sample from the
        first used to the last, across gaps at the mean rate of their end samples
        (``info['attitude']``: the gyro time gaps crossed and the largest ``|w_after -
        w_before| h / 2`` [rad], a bound of that bridge's attitude error).
    """
    rows = _as_range(idx, len(tg))
    sel = idx if rows is None else rows      # a contiguous run as a slice: copies, no gathers
    t = tg[sel]
    # the 13 variables written into one array (as :func:`.regressors.variables` stacks them)
    V = np.empty((len(t), 22 if inertial else 13))
    lo = 10 if regressors is not None else 3           # first column to re-anchor
    info: dict[str, Any] = {}
    if regressors is not None:
        V[:, REGRESSOR_COLUMNS_WIDE if inertial else slice(0, 10)] = regressors
    else:
        if inertial:
            info['attitude'] = _attitude_columns(tg, w, sel, rows, V[:, 13:])
        V[:, :3] = w[sel]
        if rows is not None:      # the usual case: integrated and written in cache-sized blocks
            cumulative_monomials(tg, w, gyro_var, rows=rows, out=V[:, 3:9])
        else:
            V[:, 3:9] = cumulative_monomials(tg, w, gyro_var)[idx]
        np.subtract(t, t[0], out=V[:, 9])
    cumulative_torque(ts, tau, t, hold, out=V[:, 10:13])
    starts = np.flatnonzero(np.r_[True, breaks])
    if len(starts) > 1:
        # re-anchor the integrals at every forced segment start: nothing integrates across a
        # gap (the trapezoid and the held torque over it are constants of the new segment,
        # and a day-long gap would otherwise leave large offsets to cancel); column by column,
        # so the given regressors are already re-anchored
        first = np.repeat(starts, np.diff(np.r_[starts, len(t)]))
        V[:, lo:] -= V[first, lo:]
    return Equations(V, t, breaks, 'anchored', eiv_var=gyro_var,
                     weighted=gyro_var is not None, info=info)


def _attitude_columns(tg: np.ndarray, w: np.ndarray, sel: slice | np.ndarray,
                      rows: slice | None, out: np.ndarray) -> dict[str, Any]:
    """Write ``int R' dt`` (n, 9) of the used gyro samples ``sel`` into ``out``, the attitude
    integrated over every gyro sample from the first used to the last (one run, body axes at
    the first used sample); returns the gyro time gaps crossed (steps over
    :data:`.options.GAP_FACTOR` median steps) and the largest ``|w_after - w_before| h / 2``
    [rad] over them."""
    if rows is not None:
        a, b = rows.start, rows.stop
        attitude_integral(tg[a:b], w[a:b], out=out)
    else:
        a, b = int(sel[0]), int(sel[-1]) + 1
        out[:] = attitude_integral(tg[a:b], w[a:b])[np.asarray(sel) - a].reshape(-1, 9)
    return _bridges(tg[a:b], w[a:b], np.diff(tg[a:b]))


def _bridges(t: np.ndarray, w: np.ndarray, h: np.ndarray) -> dict[str, Any]:
    """The gyro time gaps (steps ``h`` over :data:`.options.GAP_FACTOR` median steps) of the
    run ``t`` (n,), ``w`` (n, 3) the attitude is carried over, and the largest ``|w_after -
    w_before| h / 2`` [rad] over them (a bound of that bridge's attitude error)."""
    gaps = np.flatnonzero(h > GAP_FACTOR * median(h)) if len(h) else np.zeros(0, int)
    return _gap_jumps(w, gaps, h)


def _gap_jumps(w: np.ndarray, gaps: np.ndarray, h: np.ndarray) -> dict[str, Any]:
    """:func:`_bridges`' record from the gap positions ``gaps`` (steps ``h[gaps]`` [s])."""
    jump = np.linalg.norm(w[gaps + 1] - w[gaps], axis=1) * h[gaps] / 2.0
    return {'gaps': len(gaps), 'bridge_error_rad': float(jump.max()) if len(gaps) else 0.0}


def thinned_inertial_equations(eq: Equations, tg: np.ndarray, w: np.ndarray,
                               idx: np.ndarray, step: int) -> Equations:
    """Every ``step``-th of the 13-variable integral equations ``eq`` with the attitude
    integral's nine columns added (22 variables): a cheap screen of the inertial torque.

    The kept rows are exact equations (their integrals run over every sample); the attitude
    is carried between the kept stamps at each interval's mean rate, the trapezoid integral
    of every gyro sample in it (taken at the interval's mean step unless a gap is inside: no
    (N, 3) temporaries; the default rate when ``step`` is 1, the same columns as
    :func:`integral_equations`' up to a constant per segment, which the statistics remove).
    ``idx`` (n,): the gyro samples of ``eq``'s rows.  ``info['attitude']`` as
    :func:`integral_equations`' (gaps crossed, bridge error bound), ``info['thinned_by']``.
    """
    step = max(int(step), 1)
    rows = np.arange(0, len(eq.t), step)
    a, b = int(idx[0]), int(idx[-1]) + 1
    t, wr = tg[a:b], w[a:b]
    s = idx[rows] - a
    h = np.diff(t) if len(idx) != b - a else None     # (a contiguous run: its gaps are
    bridges = (_bridges(t, wr, h) if h is not None    # the equations' breaks)
               else _gap_jumps(wr, np.flatnonzero(eq.breaks), np.diff(eq.t)))
    rates = np.zeros((len(s) - 1, 3))
    if len(s) > 1 and bridges['gaps']:                # the trapezoid int w dt / its span
        inc = wr[1:s[-1] + 1] + wr[:s[-1]]
        inc *= np.diff(t[:s[-1] + 1])[:, None]
        span = np.diff(t[s])
        np.divide(0.5 * np.add.reduceat(inc, s[:-1], axis=0), span[:, None], out=rates,
                  where=span[:, None] > 0)
    elif len(s) > 1 and step > 1:                     # the same at equal steps: no products
        rates[:] = np.add.reduceat(wr[:s[-1]], s[:-1], axis=0)
        rates += 0.5 * (wr[s[1:]] - wr[s[:-1]])
        rates /= np.diff(s)[:, None]
    V = np.empty((len(rows), 22))
    V[:, :13] = eq.V[::step]
    attitude_integral(t[s], wr[s], None if step == 1 and h is None else rates, out=V[:, 13:])
    at = np.flatnonzero(eq.breaks)                    # a break anywhere between kept rows
    crossed = np.searchsorted(at, rows[1:]) > np.searchsorted(at, rows[:-1])
    return Equations(V, eq.t[::step], crossed, eq.kind,
                     eiv_var=eq.eiv_var, weighted=eq.weighted,
                     info={'attitude': bridges, 'thinned_by': step},
                     motion=eq.motion, white_y_cov=eq.white_y_cov, walk_cov=eq.walk_cov,
                     walk_wh=eq.walk_wh)


def _as_range(idx: slice | np.ndarray, n: int) -> slice | None:
    """``idx`` as ``slice(a, b)`` when it selects the contiguous rows ``a:b`` of ``n``, else
    ``None``."""
    if isinstance(idx, slice):
        a, b, step = idx.indices(n)
        return slice(a, max(a, b)) if step == 1 else None
    idx = np.asarray(idx)
    if idx.dtype == bool:
        return None
    if len(idx) == 0 or idx[-1] - idx[0] != len(idx) - 1 or not np.all(np.diff(idx) == 1):
        return None
    return slice(int(idx[0]), int(idx[-1]) + 1)


def sliding_equations(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                      idx: slice | np.ndarray, breaks: np.ndarray, hold: str,
                      window: float | None) -> Equations:
    """Windows ``I (w_b - w_a) + int_a^b w x I w = int_a^b tau`` of ``window`` s (default 2 s),
    a quarter window apart, never across a break; parameters as :func:`integral_equations`.
    """
    t = tg[idx]
    dt = median(np.diff(t))
    wl = max(2, round((window or 2.0) / dt))
    stride = max(1, wl // 4)
    M = cumulative_monomials(tg, w)[idx]
    T = cumulative_torque(ts, tau, t, hold)
    seg = np.cumsum(np.append(0, breaks.astype(int)))
    a = np.arange(0, max(len(t) - wl, 0), stride)
    a = a[seg[a] == seg[a + wl]]
    b = a + wl
    wi = w[idx]
    V = variables(wi[b] - wi[a], M[b] - M[a], t[b] - t[a], T[b] - T[a])
    return Equations(V, t[b], np.zeros(max(len(b) - 1, 0), dtype=bool), 'hac',
                     hac_lag=int(np.ceil(wl / stride)),
                     info={'window_s': wl * dt, 'windows': len(a)})


def _savitzky_golay(t: np.ndarray, w: np.ndarray, tq: np.ndarray, window: float | None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, dict[str, Any], float]:
    """Smoothed gyro, its derivative and the smoothed torque by a cubic Savitzky-Golay filter.

    Returns ``(w_smooth, w_dot, torque, lag, info, noise_gain)``; the noise gain is the
    variance factor of the differentiator on white noise [1/s^2].
    """
    from scipy import signal  # lazily: scipy.signal costs ~0.8 s to import

    dt = median(np.diff(t))
    wl = max(5, round((window or 1.0) / dt))
    wl += 1 - wl % 2
    wl = min(wl, len(t) - (1 - len(t) % 2))
    ws = signal.savgol_filter(w, wl, 3, axis=0)
    wd = signal.savgol_filter(w, wl, 3, deriv=1, delta=dt, axis=0)
    tq = signal.savgol_filter(tq, wl, 3, axis=0)
    noise_gain = float(np.sum(signal.savgol_coeffs(wl, 3, deriv=1, delta=dt) ** 2))
    return ws, wd, tq, wl, {'window_s': wl * dt}, noise_gain


def differential_equations(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                           tau: np.ndarray, idx: slice | np.ndarray, hold: str,
                           gyro_var: np.ndarray, window: float | None) -> Equations:
    """``tau(t_b) = I w_dot_b + w_b x I w_b`` at each used gyro sample.

    ``differential_fd`` differentiates by central differences, ``differential_sg`` by a
    Savitzky-Golay filter of ``window`` s (default 1 s; the same filter smooths the torque).
    ``info['regressor_noise_share']`` is the share of the differentiated gyro's power that
    is gyro noise (errors in variables), per axis.
    """
    t = tg[idx]
    # torque value in effect at each gyro time
    j = np.clip(np.searchsorted(ts, t, side='right') - 1, 0, len(ts) - 1)
    if hold == 'zoh':
        tq = tau[j]
    else:
        tq = np.column_stack([np.interp(t, ts, tau[:, c]) for c in range(3)])
    wi = w[idx]
    if method == 'differential_fd':
        wd = np.gradient(wi, t, axis=0)
        m = monomials(wi)
        lag = 2
        info: dict[str, Any] = {}
        # central difference: var = 2 sigma^2 / (t_{k+1} - t_{k-1})^2 per sample
        span = np.empty(len(t))
        span[1:-1] = t[2:] - t[:-2]
        span[0], span[-1] = 2.0 * (t[1] - t[0]), 2.0 * (t[-1] - t[-2])
        noise_gain = float(np.mean(2.0 / span ** 2))
    else:
        ws, wd, tq, lag, info, noise_gain = _savitzky_golay(t, wi, tq, window)
        m = monomials(ws)
    noise_pow = noise_gain * gyro_var
    info['regressor_noise_share'] = noise_pow / np.maximum(np.mean(wd ** 2, axis=0), 1e-300)
    V = variables(wd, m, np.ones(len(t)), tq)
    return Equations(V, t, np.zeros(len(t) - 1, dtype=bool), 'hac', hac_lag=lag, info=info)


def build_equations(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                    tau: np.ndarray, mask: np.ndarray, breaks: np.ndarray, hold: str,
                    gyro_var: np.ndarray, window: float | None,
                    regressors: np.ndarray | None = None,
                    inertial: bool = False) -> Equations:
    """Equations of ``method`` (a batch method other than ``auto`` and ``ml``) from the gyro
    samples selected by ``mask`` (N,) bool, the samples inside the torque coverage.

    ``tg, w, ts, tau, breaks, hold`` and ``regressors`` (``integral`` and ``integral_ls``
    only) are those of :func:`integral_equations`; ``gyro_var`` (3,) the gyro white-noise
    variance [rad^2/s^2]; ``window`` the window [s] of ``integral_sliding`` and
    ``differential_sg``; ``inertial``: the inertial-torque columns (integral methods only).
    """
    # one contiguous run of samples (the common case: all, or all but the ends outside the
    # torque's coverage): views instead of fancy-indexed copies
    idx: slice | np.ndarray = np.flatnonzero(mask)
    if len(idx) and idx[-1] - idx[0] + 1 == len(idx):
        idx = slice(int(idx[0]), int(idx[-1]) + 1)
    if method in ('integral', 'integral_ls'):
        return integral_equations(tg, w, ts, tau, idx, breaks, hold,
                                  gyro_var if method == 'integral' else None, regressors,
                                  inertial)
    if inertial:
        raise ValueError(f'{method}: the inertial-torque variables are built for the integral '
                         'methods only')
    if method == 'integral_sliding':
        return sliding_equations(tg, w, ts, tau, idx, breaks, hold, window)
    return differential_equations(method, tg, w, ts, tau, idx, hold, gyro_var, window)


def is_prefix(idx: np.ndarray, longer: np.ndarray) -> bool:
    """``idx`` is the start of ``longer`` (both increasing int arrays)."""
    return len(idx) <= len(longer) and np.array_equal(idx, longer[:len(idx)])


def shared_integral_equations(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                              tau: np.ndarray, mask: np.ndarray, breaks: np.ndarray,
                              hold: str, gyro_var: np.ndarray,
                              shared: dict[str, Any], inertial: bool = False) -> Equations:
    """:func:`build_equations` of ``integral`` or ``integral_ls``, sharing work between the
    runs of one ``hold='auto'`` estimate through ``shared`` (a dict, empty at first).

    The regressor columns ``[w, m, s]`` do not depend on the torque's hold: the first run
    keeps a copy of them (before any statistics centre its ``V``) and a later run on the same
    gyro samples, or on their start (the linear hold's coverage ends at the last torque
    sample, the held one's a torque period later), only integrates its torque.  The same
    numbers as a fresh build, bit for bit.
    With ``inertial`` the attitude integral's nine columns are shared too.
    """
    idx = np.flatnonzero(mask)
    reg = shared.get('regressors')
    key = (method, len(tg), inertial)
    reg = reg[:len(idx)] if (reg is not None and shared.get('key') == key
                             and is_prefix(idx, shared['idx'])) else None
    eq = build_equations(method, tg, w, ts, tau, mask, breaks, hold, gyro_var, None, reg,
                         inertial)
    if reg is None:
        cols = REGRESSOR_COLUMNS_WIDE if inertial else slice(0, 10)
        shared.update(key=key, idx=idx, regressors=eq.V[:, cols].copy(),
                      info={k: v for k, v in eq.info.items() if k == 'attitude'})
    else:
        eq.info.update(shared['info'])
    return eq
