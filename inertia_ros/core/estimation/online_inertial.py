"""The torque fixed in inertial axes in the recursive estimator (issue 27, design step 6).

With ``inertial_torque`` on or ``auto``, :class:`.recursive.RecursiveEstimator` carries the
nine attitude-integral variables ``c = vec C``, ``C(t) = int_t0^t R(s)' ds`` (:mod:`.attitude`),
after the 13 ``[w, m, t, T]``: rows of 22 variables, the batch's wide layout
(:data:`.regressors.VARIABLE_MAP_WIDE`), so the statistics, the fits, the selection
(:func:`.selection.select_disturbance` in :func:`.assemble.conclude`) and the adequacy tests
are the batch's at the wide width.

:class:`AttitudeState` continues :func:`.attitude.attitude_integral` block by block from the
last sample it integrated (its rotation ``R`` and integral ``C`` carried: a block integrated
from ``R = 1, C = 0`` at the carried sample is ``C_prev + C_block R_prev'``), over every
covered gyro sample (also those the torque gap rule drops, as the batch integrates over
every gyro sample).  A gyro gap (a step over :data:`.options.GAP_FACTOR` nominal steps) is
bridged at the mean rate of its end samples when ``|w_after - w_before| h / 2`` is within
:data:`.options.ATTITUDE_BRIDGE_RAD`, as the batch does; beyond it (v1, as the batch) the
term is stopped for the rest of the run: the estimator fits without it and says so in
``diagnostics['disturbance']['skipped']``.

:func:`online_fits` holds the estimator's fit, adequacy and gyro-sensitivity callables of
one estimate (the batch's ``fit(basis, bias, offset, theta0, inertial)`` signature).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .attitude import attitude_integral
from .fit import Fit, fit_two_pass
from .options import ATTITUDE_BRIDGE_RAD, GAP_FACTOR, INERTIAL_TORQUE, check_choice
from .selection import SelectionPolicy

__all__ = ['AttitudeState', 'check_inertial', 'effective_policy', 'online_fits']

def check_inertial(value: Any) -> str:
    """``inertial_torque`` checked (one ``ValueError`` line): ``'off'``, ``'auto'`` or
    ``'on'`` (a momentum input is refused by the capability table, :func:`.config.require`)."""
    return check_choice('inertial_torque', value, INERTIAL_TORQUE)


class AttitudeState:
    """The attitude ``R`` (3, 3) and its integral ``C`` (3, 3) [s] carried across blocks.

    Body axes at the first sample integrated are the disturbance's frame (``R = 1``,
    ``C = 0`` there).  :attr:`skipped` is the reason the term stopped (an unbridgeable
    gap), else None; :attr:`gaps` and :attr:`bridge_error_rad` record the gaps bridged.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.last: tuple[float, np.ndarray] | None = None    # last sample integrated
        self.R = np.eye(3)
        self.C = np.zeros((3, 3))
        self.skipped: str | None = None
        self.gaps = 0
        self.bridge_error_rad = 0.0

    def advance(self, t: np.ndarray, w: np.ndarray, nominal: float | None) -> np.ndarray:
        """``vec C`` (n, 9) [s] at the gyro samples ``t`` (n,) [s], ``w`` (n, 3) [rad/s],
        continuing from the carried sample; ``nominal``: the gyro's nominal interval [s] for
        the gap rule (None: none yet).  Zeros once :attr:`skipped`."""
        n = len(t)
        if n == 0 or self.skipped is not None:
            return np.zeros((n, 9))
        if self.last is None:
            tt, ww = t, w
        else:
            tt = np.concatenate([[self.last[0]], t])
            ww = np.concatenate([self.last[1][None, :], w])
        if nominal and len(tt) >= 2:
            h = np.diff(tt)
            big = np.flatnonzero(h > GAP_FACTOR * nominal)
            if len(big):
                err = float(np.max(np.linalg.norm(ww[big + 1] - ww[big], axis=1) * h[big]
                                   / 2.0))
                if err > ATTITUDE_BRIDGE_RAD:
                    self.skipped = (f'a gyro gap is too long to carry the attitude over (error '
                                    f'bound {err:.3g} rad > {ATTITUDE_BRIDGE_RAD:g}): the '
                                    'inertial torque is not fitted')
                    return np.zeros((n, 9))
                self.gaps += len(big)
                self.bridge_error_rad = max(self.bridge_error_rad, err)
        C, R = attitude_integral(tt, ww, rotations=True)
        out = self.C + C @ self.R.T                 # C_prev + C_block R_prev'
        self.R = self.R @ R[-1]
        self.C = out[-1].copy()
        self.last = (float(tt[-1]), ww[-1].copy())
        return out[len(tt) - n:].reshape(n, 9)


def effective_policy(policy: SelectionPolicy, attitude: AttitudeState | None,
                     diag: dict[str, Any]) -> SelectionPolicy:
    """``policy`` for this estimate: with the inertial torque off when its attitude stopped
    (``diag['disturbance']`` then says why, in the batch's form), else as given; the gyro
    gaps bridged, if any, in ``diag['attitude']``."""
    if attitude is None:
        return policy
    if attitude.gaps:
        diag['attitude'] = {'gaps': attitude.gaps,
                            'bridge_error_rad': attitude.bridge_error_rad}
    if attitude.skipped is None:
        return policy
    diag['disturbance'] = {'requested': {'inertial_torque': policy.inertial_torque},
                           'chosen': None, 'skipped': attitude.skipped}
    return replace(policy, inertial_torque='off')


def online_fits(est: Any, st: Any, nv: np.ndarray, tv: np.ndarray, n_eff: float,
                ratio: float) -> tuple[Callable[..., Fit], Callable[[Fit, str], Any],
                                       Callable[[Fit], np.ndarray]]:
    """The fit, adequacy and gyro-sensitivity callables of one estimate of ``est``
    (:class:`.recursive.RecursiveEstimator`) on its statistics ``st``: ``nv``, ``tv`` (3,)
    the gyro [rad^2/s^2] and torque [N^2 m^2] noise variances, ``n_eff`` its effective
    equations, ``ratio`` the covariance factor of weighted sums (``w00 / w0``)."""

    def fit(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None,
            theta0: np.ndarray | None = None, inertial: bool = False) -> Fit:
        """Fit on the weighted statistics; the meat of weighted sums scales by w^2/w."""
        f = fit_two_pass(st, basis, bias, nv, tv, offset, theta0, inertial=inertial)
        f.cov = f.cov * ratio
        return f

    def adequacy(f: Fit, chosen: str) -> Any:
        """Window consistency over the kept segments and the residual excess."""
        return est._schedule.window_adequacy(f, nv, tv, est._test_adequacy, est.samples_used)

    def gyro_sensitivity(f: Fit) -> np.ndarray:
        """``d beta / d g``: refit of the statistics of a gyro read 1e-4 larger (the attitude
        integral not recomputed: first order, as the batch's)."""
        k = f.basis.shape[1]
        theta0 = f.basis @ f.beta[:k] + (0.0 if f.offset is None else f.offset)
        b = [fit_two_pass(est._stats(nv, n_eff, s), f.basis, f.bias, nv, tv, f.offset,
                          theta0, inertial=f.inertial).beta for s in (1.0, 1.0 + 1e-4)]
        return (b[1] - b[0]) / 1e-4

    return fit, adequacy, gyro_sensitivity
