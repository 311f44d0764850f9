"""The filtered form of Euler's equation: the same low-pass filter on both sides (``filtered``).

Euler's equation ``tau = I w_dot + w x (I w)`` passed through a low-pass filter ``H`` becomes
``H tau = I (s H w) + H (w x I w)``: the derivative is moved onto the filter (``s H`` is a
band-limited differentiator), so the gyro is never differentiated on its own, and the
gyroscopic term stays linear in ``theta`` through the filtered monomials ``H m``.  ``H`` is a
causal fourth-order Butterworth low-pass of cutoff ``fc``: flat in the band, steep above it,
so vibration and sensor noise above the rigid-body motion (a spinning flywheel's imbalance, a
structure's modes) leave both sides alike; the standard remedy for noisy high-rate data.

Construction.  The anchored momentum variables of :func:`.equations.integral_equations`,
``[w, int m dt, t, int tau dt]`` (13 per gyro sample, exact for held or linear torque and for
an internal-momentum input's equivalent torque), satisfy ``I w + int w x I w - d t - int tau
= const`` within a segment.  One discrete linear filter ``D`` with zero gain at DC applied to
every column keeps that relation exactly and removes the constant: with ``D`` the first
difference over ``dt`` followed by ``H``, the columns become ``[s H w, H m, H 1, H tau]``,
the filtered differential equation.  Each segment's filter starts in the steady state of its
first sample, so the filtered relation holds from the first sample on (no start-up transient
to discard).  The filtered equations are band-limited: one in ``q`` is kept, about 16 per
``1 / fc``.

Fit and covariance.  Ordinary least squares on the filtered equations (equal torque weights:
the filtered equations' error is dominated by whatever torque-like error the record carries
as often as by the gyro noise), with the model selection, identifiability, adequacy test and
physical projection of :mod:`.batch`.  The equation error (filtered gyro noise ``I (s H n)``,
filtered torque noise ``H nu`` and any unmodelled torque) is coloured, so the covariance is
the sandwich with the Newey-West (Bartlett) meat of the scores over ``hac_lag`` kept samples,
``1 / fc`` (the filter's autocorrelation has decayed by then); on a short record (at most
:data:`HAC_SMALL_SAMPLE_MAX` kept equations, a few dozen ``1 / fc``) it is corrected for its
small-sample bias under the error's autocorrelation fitted from the residuals as a mix of
the filter's torque-like (``H``) and gyro-like (``s H``) shapes (:func:`.fit.hac_small_sample`;
a 0.5 s simulated throw: RMS z 1.45 -> 0.97).  The gyro noise in the
``s H w`` regressor (errors in variables) is not compensated; its share of the regressor's
power (``sigma^2 g`` over the power of ``s H w``, ``g`` the white-noise gain of ``D``, all
axes together) is kept small instead.

Cutoff.  ``window`` sets ``1 / fc`` [s]; by default ``fc`` is chosen from the data among the
gyro rate over 8, 16, 32, ... (at least ``10 / span``: the Newey-West covariance needs many
lags' worth of equations) by the smallest predicted relative variance of the full model's
tensor, among the cutoffs whose regressor noise share is at most 0.2 % (a fit shrunk by at
most about that much); the choice is recorded in ``info['filter_selection']``.  When none
qualifies the lowest cutoff is used, and a share over the shared 2 % limit of the
differentiating methods gives ``insufficient_excitation``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .equations import Equations, build_equations, integral_equations

__all__ = ['FILTER_DIVISORS', 'MAX_NOISE_SHARE', 'equations_for', 'filter_coefficients',
           'filtered_equations']

#: Candidate cutoffs: the gyro rate divided by these (``window`` not given).
FILTER_DIVISORS: tuple[int, ...] = (8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192)
_ORDER = 4                   # Butterworth order
MAX_NOISE_SHARE = 0.002      # largest gyro-noise share of the s H w regressor chosen by default
_HAC_PERIODS = 1.0           # Newey-West lag [1 / fc]
_KEEP_PER_PERIOD = 16.0      # kept equations per 1 / fc (at least)
_SELECT_MAX_ROWS = 200_000   # gyro samples used by the cutoff search
_MIN_PERIODS = 10.0          # the record spans at least this many 1 / fc (default choice)
#: Kept equations up to which the Newey-West covariance gets its small-sample correction.
HAC_SMALL_SAMPLE_MAX = 600


def filter_coefficients(fc: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``D``: the first difference over ``dt``, then a causal Butterworth low-pass of ``fc``.

    Parameters
    ----------
    fc : float
        Cutoff (-3 dB) [Hz], below the Nyquist frequency ``0.5 / dt``.
    dt : float
        Sample interval [s], > 0.

    Returns
    -------
    b, a : ndarray, shape (5 + 1,), (5,)
        Numerator and denominator (``a[0] = 1``) of ``D(z)``: ``D(1) = 0`` exactly, and a
        ramp of slope 1 settles to 1 (units 1/s on the variables).
    """
    from scipy import signal  # lazily: scipy.signal costs ~0.8 s to import

    b, a = signal.butter(_ORDER, fc, fs=1.0 / dt)
    return np.convolve(b, [1.0 / dt, -1.0 / dt]), np.asarray(a, dtype=float)


def _noise_gain(b: np.ndarray, a: np.ndarray, fc: float, dt: float) -> float:
    """Sum of the squared impulse response of ``D`` [1/s^2]: white-noise variance gain."""
    from scipy import signal

    n = int(min(max(20.0 / (fc * dt), 64), 2_000_000))
    imp = np.zeros(n)
    imp[0] = 1.0
    return float(np.sum(signal.lfilter(b, a, imp) ** 2))


def _error_shapes(fc: float, dt: float, q: int, m: int) -> np.ndarray:
    """Autocorrelations (2, m) at kept lags ``0..m-1`` (every ``q``-th sample) of white noise
    through ``H`` (a torque-like equation error: unmodelled or torque noise) and through
    ``D = s H`` (a gyro-like one: gyro or wheel-speed noise), the candidate shapes of the HAC
    small-sample correction (:func:`.fit.hac_small_sample`)."""
    from scipy import signal

    b, a = filter_coefficients(fc, dt)
    bh = signal.butter(_ORDER, fc, fs=1.0 / dt)[0]
    n = int(min(max(20.0 / (fc * dt), 2 * m * q), 2_000_000))
    imp = np.zeros(n)
    imp[0] = 1.0
    out = np.zeros((2, m))
    for k, num in enumerate((bh, b)):
        h = signal.lfilter(num, a, imp)
        full = signal.fftconvolve(h, h[::-1])[n - 1:]
        r = full[::q][:m] / full[0]
        out[k, :len(r)] = r
    return out


def _filter_segments(V: np.ndarray, starts: np.ndarray, b: np.ndarray, a: np.ndarray
                     ) -> np.ndarray:
    """``D`` on every column of ``V`` (n, q), each segment from its first sample's steady state."""
    from scipy import signal

    zi = signal.lfilter_zi(b, a)
    out = np.empty_like(V)
    bounds = [*starts.tolist(), len(V)]
    for s0, s1 in zip(bounds[:-1], bounds[1:], strict=True):
        seg = V[s0:s1]
        out[s0:s1], _ = signal.lfilter(b, a, seg, axis=0, zi=zi[:, None] * seg[0][None])
    return out


def _build(base: Equations, fc: float, dt: float, gyro_var: np.ndarray) -> Equations:
    """Filtered, decimated equations of the anchored ``base`` with cutoff ``fc`` [Hz]."""
    b, a = filter_coefficients(fc, dt)
    starts = np.flatnonzero(np.r_[True, base.breaks])
    F = _filter_segments(base.V, starts, b, a)
    q = max(1, int(1.0 / (_KEEP_PER_PERIOD * fc * dt)))
    keep = np.arange(0, len(F), q)
    noise = float(np.sum(gyro_var)) * _noise_gain(b, a, fc, dt)
    # of all three axes together: an axis without motion is the identifiability rules' case
    share = noise / max(float(np.sum(np.mean(F[keep, :3] ** 2, axis=0))), 1e-300)
    info: dict[str, Any] = {'filter_cutoff_hz': fc, 'filter_order': _ORDER, 'decimation': q,
                            'filtered_noise_share': share}
    lag = int(np.ceil(_HAC_PERIODS / (fc * q * dt)))
    if len(keep) <= HAC_SMALL_SAMPLE_MAX:
        info['hac_error_shapes'] = _error_shapes(fc, dt, q, 4 * lag + 1)
    return Equations(F[keep], base.t[keep], np.zeros(max(len(keep) - 1, 0), dtype=bool), 'hac',
                     hac_lag=lag, info=info)


def _candidates(dt: float, span: float) -> list[float]:
    """Default cutoffs [Hz], highest first: the gyro rate over 8, 16, ..., >= 10 / span."""
    out = [1.0 / (k * dt) for k in FILTER_DIVISORS if 1.0 / (k * dt) >= _MIN_PERIODS / span]
    return out or [1.0 / (FILTER_DIVISORS[0] * dt)]


def _choose(base: Equations, dt: float, gyro_var: np.ndarray) -> tuple[float, dict[str, Any]]:
    """Cutoff with the smallest predicted relative variance (noise share <= 0.2 %)."""
    from .fit import fit_two_pass
    from .statistics import sufficient_stats

    sub = base.head(_SELECT_MAX_ROWS) if len(base.t) > _SELECT_MAX_ROWS else base
    span = float(sub.t[-1] - sub.t[0])
    scores: dict[str, float] = {}
    shares: dict[str, float] = {}
    best, best_score = None, np.inf
    cands = _candidates(dt, span)
    for fc in cands:
        eq = _build(sub, fc, dt, gyro_var)
        share = eq.info['filtered_noise_share']
        shares[f'{fc:.6g}'] = share
        if len(eq.t) < 3 * (6 + 3) or share > MAX_NOISE_SHARE:
            continue
        # (the Newey-West covariance of these equations needs no torque-noise model; the
        # choice compares the plain one, without the small-sample correction)
        eq.info.pop('hac_error_shapes', None)
        st = sufficient_stats(eq, None, np.zeros(0), 0.0, np.zeros(3))
        # the general model: the bias, and the inertial torque when its columns are built
        f = fit_two_pass(st, np.eye(6), True, gyro_var, np.zeros(3),
                         inertial=eq.V.shape[1] > 13)
        scale = float(np.mean(np.abs(f.beta[:3])))
        score = float(np.trace(f.cov[:6, :6])) / scale ** 2 if scale > 0 else np.inf
        scores[f'{fc:.6g}'] = score
        if score < best_score:
            best, best_score = fc, score
    rule = ('minimum predicted relative variance of theta among the cutoffs whose regressor '
            f'noise share is <= {100 * MAX_NOISE_SHARE:g} %')
    if best is None:
        # every candidate too noisy: the lowest cutoff (the shared errors-in-variables rule
        # of the batch estimator judges it by its regressor_noise_share)
        best = cands[-1]
        rule += '; none qualified: the lowest'
    return best, {'candidates_hz': scores, 'noise_share': shares, 'chosen_hz': best,
                  'rule': rule}


def filtered_equations(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                       mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                       window: float | None, inertial: bool = False) -> Equations:
    """Equations of the ``filtered`` method (see the module docstring).

    Parameters
    ----------
    tg, w, ts, tau, mask, breaks, hold, gyro_var
        As :func:`.equations.build_equations`.
    window : float, optional
        ``1 / fc`` [s], the filter's cutoff period (default: chosen from the data).
    inertial : bool
        Also the nine attitude-integral columns of a torque fixed in inertial axes (22
        columns): filtered like the others, ``D C = H R'`` (the relation stays exact).

    Returns
    -------
    Equations
        ``kind='hac'``, unweighted; ``info`` holds the cutoff, the decimation, the regressor
        noise share (also as ``regressor_noise_share``, judged by the shared
        errors-in-variables rule) and the selection (and ``attitude`` with ``inertial``).
    """
    idx: slice | np.ndarray = slice(None) if mask.all() else np.flatnonzero(mask)
    # (the squared rates' noise bias is removed with the gyro variance, as for integral)
    base = integral_equations(tg, w, ts, tau, idx, breaks, hold, gyro_var, inertial=inertial)
    dt = float(np.median(np.diff(base.t)))
    if window is None:
        fc, sel = _choose(base, dt, gyro_var)
    else:
        fc, sel = 1.0 / float(window), None
        if not fc < 0.5 / dt:
            raise ValueError(f'window: the filtered cutoff 1/window = {fc:.6g} Hz must be below '
                             f'the gyro Nyquist frequency {0.5 / dt:.6g} Hz; give a longer window')
    eq = _build(base, fc, dt, gyro_var)
    eq.info.update(base.info)                     # (the attitude's gaps, with ``inertial``)
    eq.info['regressor_noise_share'] = np.full(3, eq.info['filtered_noise_share'])
    if sel is not None:
        eq.info['filter_selection'] = sel
    return eq


def equations_for(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                  mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                  window: float | None, inertial: bool = False) -> Equations:
    """:func:`.equations.build_equations`, with the ``filtered`` method added (``inertial``:
    the inertial-torque columns, of the integral methods and ``filtered``)."""
    if method == 'filtered':
        return filtered_equations(tg, w, ts, tau, mask, breaks, hold, gyro_var, window,
                                  inertial)
    return build_equations(method, tg, w, ts, tau, mask, breaks, hold, gyro_var, window,
                           inertial=inertial)
