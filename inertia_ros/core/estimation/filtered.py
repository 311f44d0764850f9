"""The filtered form of Euler's equation: the same low-pass filter on both sides (``filtered``).

Euler's equation ``tau = I w_dot + w x (I w)`` passed through a low-pass filter ``H(s)``
becomes ``H tau = I (s H w) + H (w x I w)``: the derivative is moved onto the filter
(``s H`` is a band-limited differentiator), so the gyro is never differentiated numerically,
and the gyroscopic term stays linear in ``theta`` through the filtered monomials ``H m``.
The filter here is the critically damped second-order low-pass

``H(s) = 1 / (1 + s T)^2``  (time constant ``T`` [s], -3 dB at ``0.10 / T`` Hz),

the standard remedy for noisy high-rate data (it also removes the need to model what the
gyro's own anti-alias filter did above the band).

Construction.  The anchored momentum variables of :func:`.equations.integral_equations`,
``[w, int m dt, t, int tau dt]`` (13 per gyro sample, exact for held or linear torque and for
an internal-momentum input's equivalent torque), satisfy ``I w + int w x I w - d t - int tau
= const`` within a segment.  Applying one discrete linear filter ``D`` with zero gain at DC
to every column keeps that relation exactly and removes the constant:  with ``D`` the
bilinear (Tustin) image of ``s H(s)``, the filtered columns are ``[s H w, H m, H 1, H tau]``,
i.e. the filtered differential equation, built without a numerical derivative.  Each
segment's filter starts in the steady state of its first sample, so the filtered relation
holds from the first sample on (no start-up transient to discard).  The filtered equations
are band-limited: they are kept every ``q`` samples, ``q`` chosen so that about ten are kept
per time constant's worth of bandwidth (``q dt <= T / 1.6``).

Noise and covariance.  The equation error is the filtered gyro noise ``I (s H n)`` plus the
filtered torque noise ``H nu``: coloured, so the covariance is the sandwich with the
Newey-West (Bartlett) meat of the scores over ``hac_lag`` kept samples, about ten time
constants (the filter's autocorrelation has decayed to 1e-3 by then).  The gyro noise in the
``s H w`` regressor (errors in variables; variance ``sigma^2 g`` per sample with ``g`` the
white-noise gain of ``D``) and in the filtered squared rates (removed with the gyro variance
in the cumulative monomials) is compensated as in the ``integral`` method, and the equations
are weighted by ``(I S_g I)^-1`` from a first pass.

Time constant.  ``window`` sets ``T`` [s]; by default ``T`` is chosen from the data among
2, 4, 8, ... gyro intervals (up to a hundredth of the record: the Newey-West covariance
needs many lags' worth of equations) by the smallest predicted relative variance of the full
model's tensor, among those whose regressor noise share (gyro noise power in ``s H w`` over
its total power, all axes together) is at most 0.5 % (above it the compensated noise still
shifts the scores' mean and the covariance turns conservative); the choice is recorded in
``info['filter_selection']``.  When none qualifies the slowest is used, and a share over the
shared 2 % limit gives ``insufficient_excitation``.  Status rules, model selection, the
adequacy (window consistency) test and the physical projection are the shared ones of
:mod:`.batch`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .equations import Equations, build_equations, integral_equations

__all__ = ['FILTER_STEPS', 'equations_for', 'filter_coefficients', 'filtered_equations']

#: Candidate time constants, in gyro sample intervals (``window`` not given).
FILTER_STEPS: tuple[int, ...] = (2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048)
_MAX_NOISE_SHARE = 0.005     # largest gyro-noise share of the s H w regressor chosen by default
_HAC_TIME_CONSTANTS = 10.0   # Newey-West lag [time constants]
_KEEP_PER_T = 1.6            # kept equations per time constant (at least)
_SELECT_MAX_ROWS = 200_000   # gyro samples used by the time-constant search
_MIN_SPAN_PER_T = 100.0      # the record spans at least this many time constants (default)


def filter_coefficients(T: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Discrete ``s H(s)``, ``H = 1 / (1 + s T)^2``, by the bilinear transform.

    Parameters
    ----------
    T : float
        Time constant [s], > 0.
    dt : float
        Sample interval [s], > 0.

    Returns
    -------
    b, a : ndarray, shape (3,)
        Numerator and denominator (``a[0] = 1``) of ``D(z)``; ``D(1) = 0`` exactly, and a
        ramp of slope 1 settles to 1 (units 1/s on the variables).
    """
    from scipy import signal  # lazily: scipy.signal costs ~0.8 s to import

    p = 1.0 / T
    b, a = signal.bilinear([p * p, 0.0], [1.0, 2.0 * p, p * p], fs=1.0 / dt)
    b = np.atleast_1d(np.asarray(b, dtype=float))
    b = np.concatenate([b, np.zeros(3 - len(b))])
    b[np.abs(b) < 1e-15 * np.max(np.abs(b))] = 0.0
    # remove the rounding from the DC zero so that D(1) = 0 holds to the last bit
    b -= np.sum(b) / len(b)
    return b, np.asarray(a, dtype=float)


def _noise_gain(b: np.ndarray, a: np.ndarray, T: float, dt: float) -> float:
    """Sum of the squared impulse response of ``D`` [1/s^2]: white-noise variance gain."""
    from scipy import signal

    n = int(min(max(40.0 * T / dt, 64), 2_000_000))
    imp = np.zeros(n)
    imp[0] = 1.0
    return float(np.sum(signal.lfilter(b, a, imp) ** 2))


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


def _build(base: Equations, T: float, dt: float, gyro_var: np.ndarray) -> Equations:
    """Filtered, decimated equations of the anchored ``base`` with time constant ``T``."""
    b, a = filter_coefficients(T, dt)
    starts = np.flatnonzero(np.r_[True, base.breaks])
    F = _filter_segments(base.V, starts, b, a)
    q = max(1, int(T / (_KEEP_PER_T * dt)))
    keep = np.arange(0, len(F), q)
    gain = _noise_gain(b, a, T, dt)
    eiv = gyro_var * gain
    # of all three axes together: an axis without motion is the identifiability rules' case
    share = float(np.sum(eiv) / max(float(np.sum(np.mean(F[keep, :3] ** 2, axis=0))), 1e-300))
    info: dict[str, Any] = {'filter_time_constant_s': T, 'filter_cutoff_hz': 0.1 / T,
                            'decimation': q, 'filtered_noise_share': share}
    lag = int(np.ceil(_HAC_TIME_CONSTANTS * T / (q * dt)))
    return Equations(F[keep], base.t[keep], np.zeros(max(len(keep) - 1, 0), dtype=bool), 'hac',
                     hac_lag=lag, eiv_var=eiv, weighted=True, info=info)


def _candidates(dt: float, span: float) -> list[float]:
    """Default time constants [s]: 2, 4, ... gyro intervals, at most a hundredth of ``span``."""
    out = [k * dt for k in FILTER_STEPS if k * dt <= span / _MIN_SPAN_PER_T]
    return out or [FILTER_STEPS[0] * dt]


def _choose(base: Equations, dt: float, gyro_var: np.ndarray) -> tuple[float, dict[str, Any]]:
    """Time constant with the smallest predicted relative variance (noise share <= 0.5 %)."""
    from .fit import fit_two_pass
    from .statistics import sufficient_stats

    sub = base.head(_SELECT_MAX_ROWS) if len(base.t) > _SELECT_MAX_ROWS else base
    span = float(sub.t[-1] - sub.t[0])
    scores: dict[str, float] = {}
    shares: dict[str, float] = {}
    best, best_score = None, np.inf
    cands = _candidates(dt, span)
    for T in cands:
        eq = _build(sub, T, dt, gyro_var)
        share = eq.info['filtered_noise_share']
        shares[f'{T:.6g}'] = share
        if len(eq.t) < 3 * (6 + 3) or share > _MAX_NOISE_SHARE:
            continue
        # (the Newey-West covariance of these equations needs no torque-noise model)
        st = sufficient_stats(eq, None, np.zeros(0), 0.0, np.zeros(3))
        f = fit_two_pass(st, np.eye(6), True, gyro_var, np.zeros(3))
        scale = float(np.mean(np.abs(f.beta[:3])))
        score = float(np.trace(f.cov[:6, :6])) / scale ** 2 if scale > 0 else np.inf
        scores[f'{T:.6g}'] = score
        if score < best_score:
            best, best_score = T, score
    rule = ('minimum predicted relative variance of theta among time constants whose '
            f'regressor noise share is <= {100 * _MAX_NOISE_SHARE:g} %')
    if best is None:
        # every candidate too noisy: the slowest one, and the shared errors-in-variables rule
        # of the batch estimator reports it (regressor_noise_share)
        best = cands[-1]
        rule += '; none qualified: the slowest one'
    return best, {'candidates_s': scores, 'noise_share': shares, 'chosen_s': best, 'rule': rule}


def filtered_equations(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                       mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                       window: float | None) -> Equations:
    """Equations of the ``filtered`` method (see the module docstring).

    Parameters
    ----------
    tg, w, ts, tau, mask, breaks, hold, gyro_var
        As :func:`.equations.build_equations`.
    window : float, optional
        Filter time constant ``T`` [s] (default: chosen from the data).

    Returns
    -------
    Equations
        ``kind='hac'``, weighted and errors-in-variables compensated; ``info`` holds the
        time constant, the decimation, the regressor noise share and the selection.
    """
    idx: slice | np.ndarray = slice(None) if mask.all() else np.flatnonzero(mask)
    base = integral_equations(tg, w, ts, tau, idx, breaks, hold, gyro_var)
    dt = float(np.median(np.diff(base.t)))
    if window is None:
        T, sel = _choose(base, dt, gyro_var)
    else:
        T, sel = float(window), None
    eq = _build(base, T, dt, gyro_var)
    share = eq.info['filtered_noise_share']
    if share > _MAX_NOISE_SHARE and window is None:
        # the shared rule: a regressor dominated by noise is insufficient_excitation
        eq.info['regressor_noise_share'] = np.full(3, share)
    if sel is not None:
        eq.info['filter_selection'] = sel
    return eq


def equations_for(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                  mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                  window: float | None) -> Equations:
    """:func:`.equations.build_equations`, with the ``filtered`` method added."""
    if method == 'filtered':
        return filtered_equations(tg, w, ts, tau, mask, breaks, hold, gyro_var, window)
    return build_equations(method, tg, w, ts, tau, mask, breaks, hold, gyro_var, window)
