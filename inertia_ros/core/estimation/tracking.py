"""Tracking a changing tensor: :class:`TrackingEstimator`, a Kalman filter on the momentum.

The state is ``x = [psi (k), d (3, optional), L (3)]``: the tensor parameters of the chosen
model (``theta = T psi``), an optional constant disturbance torque [N m] and the body's angular
momentum in body axes ``L = I w`` [N m s].  The package's anchored momentum equation,
``I w_b + int_s^b w x (I w) dt - d (t_b - s) - L_s = int_s^b tau dt``, is exactly the
measurement model of this state: every gyro sample after a block's anchor ``s`` (the last
sample of the previous block) gives

    H_b x_s = y_b,  H_b = [(L(w_b) + Q(int_s^b m dt)) T,  -(t_b - s) 1,  -1],  y_b = int_s^b tau,

with the white error ``-I n_b`` of the gyro noise (covariance ``I S_g I``: the weights of the
batch ``integral`` method), the same trapezoid monomial integrals with the gyro-noise
correction ``-sigma^2 (t - s)`` (:func:`.regressors.cumulative_monomials`) and the same held
torque integral (:func:`.regressors.cumulative_torque`).  The equations of a block (``block``
seconds, 0.1 s by default) share the anchor state, so the block enters as their mean, one
3-row Kalman update with the error covariance ``I S_g I / n``: O(state^2) per block plus O(1)
per sample, whatever the memory; nothing is re-solved.

Between blocks the momentum is propagated by the same equation,
``L_e = L_s + int tau + d (e - s) - Q(int m) theta``, with the process noise of the integrated
torque noise and the gyroscopic noise walk (:func:`.noise.gyroscopic_walk_cov`), and the
tensor parameters random-walk with the covariance ``(exp(dt / window) - 1) P_psi``: the
process noise that gives the filter exactly the memory of exponential forgetting with time
constant ``window`` (a forgetting-factor RLS at ``lambda = exp(-dt / window)`` per update), so
the memory setting means what the recursive estimator's ``window`` means.

Errors in variables: the averaged gyro noise in each block's regressor carries its own
"information" ``B`` (the batch fit's ``n B``); the reported estimate removes its first-order
effect with the sum of ``B`` under the same forgetting (:meth:`TrackingEstimator._compensated`).

A change the memory cannot follow (a payload step) is found by the innovation test: the
normalised innovation ``nu' S^-1 nu`` of a block is chi-square with 3 degrees of freedom under
the model; above its ``change_level`` upper quantile the prior covariance of the tensor is
inflated (``change_inflation`` of its scale, one sigma) and the block folded in again, so the
filter re-converges on the new body in about a second instead of one memory time.  The
momentum is kept (a payload attached without impulse conserves it; the rate jumps).  A
persistent excess of the innovations over the noise model gives ``model_mismatch`` with the
covariance inflated by it, as the batch adequacy rule does.

The reported covariance is against the *current* tensor: half the filter's ``P_psi`` (the
noise of exponentially weighted estimates, the sandwich ``sum w^2 / sum w``, as the recursive
estimator reports) plus ``lag lag'``, the lag ``rate * window`` of the exponential memory
behind a tensor changing at the rate the recent estimates show (a slow drift such as fuel
use).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import as_noise_std
from ..tensor import MATRIX_INDEX, theta_to_matrix
from .config import require, substitutions
from .model import model_basis
from .model import symmetry_axis as unit_axis
from .noise import StreamingNoise, regressor_noise_information
from .options import (
    ALPHA,
)
from .regressors import cumulative_monomials, cumulative_torque, gyroscopic_matrix, momentum_matrix
from .result import InertiaEstimate
from .selection import SelectionPolicy
from .tails import chi2_isf
from .tracking_consistency import InnovationTests, fault_torque
from .tracking_hold import HoldChoice, keep_by_adequacy
from .tracking_input import StreamInput
from .tracking_output import EXCESS_TIME, StateOutput

__all__ = ['TrackingEstimator']

_DIFFUSE = 1e6            # prior variance of the empty filter, in squared scale units
_PRIOR_INFLATION = 100.0  # start-up fit covariance -> the filter's prior


def noise_information(basis: np.ndarray, nv: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The gyro noise's own information (k, k) in one sample's equation for the model basis
    ``T`` (6, k), the gyro variances ``nv`` (3,) [rad^2/s^2] and the equation error covariance
    ``R`` (3, 3) (the blocks' ``B``): :func:`.noise.regressor_noise_information`."""
    Wc = np.linalg.cholesky(np.linalg.inv(R))
    return regressor_noise_information(nv, Wc.T, basis)


def _corrected_wls(H: np.ndarray, y: np.ndarray, R: np.ndarray, B: np.ndarray
                   ) -> tuple[np.ndarray, ...] | None:
    """Weighted least squares of ``H x = y`` (H (n, 3, q), y (n, 3), error covariance ``R``
    (3, 3)) with the regressor noise's own information ``n B`` (k, k, the first ``k``
    columns) taken out of the normal matrix (errors in variables); None when that matrix is
    not positive definite.  Returns ``x`` (q,), its covariance (q, q), the weighted design
    (3n, q) and the weight factor ``Wc`` (``Wc Wc' = R^-1``)."""
    from scipy.linalg import cho_solve  # lazily: scipy.linalg costs start-up time

    Wc = np.linalg.cholesky(np.linalg.inv(R))
    Hw = np.einsum('ij,nik->njk', Wc, H).reshape(-1, H.shape[2])
    A = Hw.T @ Hw
    A[:len(B), :len(B)] -= len(H) * B
    s = np.sqrt(np.maximum(np.diag(A), 1e-300))
    try:
        L = np.linalg.cholesky(A / np.outer(s, s))
    except np.linalg.LinAlgError:
        return None
    x = cho_solve((L, True), Hw.T @ (y @ Wc).reshape(-1) / s) / s
    return x, cho_solve((L, True), np.diag(1.0 / s)) / s[:, None], Hw, Wc


class _Trend:
    """Exponentially weighted straight-line fit of the estimates against time: the rate at
    which the tracked tensor is changing (time constant ``tau`` [s])."""

    def __init__(self, tau: float, p: int) -> None:
        self.tau = tau
        self.W = 0.0
        self.t_mean = 0.0
        self.x_mean = np.zeros(p)
        self.Stt = 0.0
        self.Stx = np.zeros(p)
        self.t0: float | None = None

    def add(self, t: float, x: np.ndarray, dt: float) -> None:
        """One estimate ``x`` (p,) at time ``t`` [s], weighted by its span ``dt`` [s]."""
        if self.t0 is None:
            self.t0 = t
        a = math.exp(-dt / self.tau)
        self.W *= a
        self.Stt *= a
        self.Stx = self.Stx * a
        d = t - self.t_mean
        self.W += dt
        f = dt / self.W
        self.t_mean += f * d
        self.x_mean = self.x_mean + f * (x - self.x_mean)
        self.Stt += dt * d * (t - self.t_mean)
        self.Stx = self.Stx + dt * d * (x - self.x_mean)

    def rate(self, t: float) -> np.ndarray | None:
        """The fitted rate (p,) [units of x per s], or None before one time constant."""
        if self.t0 is None or t - self.t0 < self.tau or self.Stt <= 0:
            return None
        return self.Stx / self.Stt


class TrackingEstimator(StreamInput, StateOutput):
    """Kalman filter on the tensor parameters and the angular momentum (see the module doc).

    The filter (start-up, blocks, prediction, weights, change test) is here; the input side
    (buffering, alignment, gaps, noise levels) is :class:`.tracking_input.StreamInput`, the
    output side (estimate, covariance, status) :class:`.tracking_output.StateOutput`.

    Parameters
    ----------
    window : float
        Memory time constant [s] (> 0): the tensor's random-walk process noise is that of
        exponential forgetting with this time constant.
    model : {'full', 'diagonal', 'axisymmetric', 'auto'}
        Parameter set; ``auto`` tracks the full tensor.
    torque_bias : bool or {'auto', 'on', 'off'}
        Track a constant disturbance torque [N m] (``on``); ``auto`` and ``off`` do not.
    hold : {'zoh', 'linear', 'auto'}
        Torque between samples; ``auto``: a twin filter runs the other hold until the batch
        rule (:func:`.selection.select_hold`) decides between them, then it is dropped
        (:mod:`.tracking_hold`; ``diagnostics['hold_selection']``).
    symmetry_axis : {'x', 'y', 'z'} or array_like (3,), optional
        For the axisymmetric model.
    gyro_noise : float or array_like (3,), optional
        Gyro white-noise std [rad/s]; estimated from the stream when omitted.
    block : float
        Longest block of gyro samples folded in at once [s] (> 0).
    warmup : float, optional
        Start-up length [s]: the first ``warmup`` seconds are filtered twice, the second time
        with the equation weights ``(I S_g I)^-1`` of the first pass (default
        ``min(window / 5, 2)``).
    change_level : float
        False-alarm probability per block of the change (innovation) test; 0 disables it.
    change_inflation : float
        Relative size (one sigma) of the change assumed when the test fires.
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainties added to the covariance, as in the batch.
    alpha : float
        Test level (kept for the selection policy).
    nuisance : str
        Only ``'off'``: any other value is refused by :func:`.config.require` (one line).
    """

    _kind = 'torque'                 # the input kind (the capability table's column)
    nu = 0                           # stated-input states (:class:`.recursive_momentum.
    _white_y_cov = None              # MomentumTrackingEstimator`) and white noise of y
    _learnt = 0                      # the last of them learnt, the others considered
    _nl = 0                          # the last of them non-linear (the gyro scale)

    def __init__(self, window: float = 10.0, model: str = 'full',
                 torque_bias: bool | str = 'off', hold: str = 'zoh', symmetry_axis: Any = None,
                 gyro_noise: Any = None, block: float = 0.1, warmup: float | None = None,
                 change_level: float = 1e-6, change_inflation: float = 0.5,
                 torque_scale_std: float = 0.0, gyro_scale_std: float = 0.0,
                 alpha: float = ALPHA, nuisance: Any = 'off') -> None:
        config = {k: v for k, v in locals().items() if k not in ('self', 'hold')}
        opts = require('tracking', self._kind, dict(
            model=model, torque_bias=torque_bias, hold=hold, symmetry_axis=symmetry_axis,
            alpha=alpha, torque_scale_std=torque_scale_std, gyro_scale_std=gyro_scale_std,
            nuisance=nuisance))
        self._substituted = substitutions('tracking', self._kind, opts)   # for the warnings
        if not (isinstance(window, (int, float)) and math.isfinite(window) and window > 0):
            raise ValueError(f'window: must be a positive number of seconds, got {window!r}')
        torque_bias = opts.torque_bias
        if not block > 0:
            raise ValueError(f'block: must be > 0 s, got {block!r}')
        if warmup is not None and not warmup > 0:
            raise ValueError(f'warmup: must be > 0 s, got {warmup!r}')
        if not 0.0 <= change_level < 0.5:
            raise ValueError(f'change_level: must be in [0, 0.5), got {change_level!r}')
        if not change_inflation > 0:
            raise ValueError(f'change_inflation: must be > 0, got {change_inflation!r}')
        self.policy = SelectionPolicy(alpha, torque_scale_std=torque_scale_std,
                                      gyro_scale_std=gyro_scale_std)
        self.window = float(window)
        self.model = 'full' if model == 'auto' else model
        self.torque_bias = torque_bias
        self.hold = 'zoh' if hold == 'auto' else hold       # the filter's (auto: until locked)
        self._hold_auto, self._config, self._hold_record = hold == 'auto', config, None
        self.axis = unit_axis(symmetry_axis)
        self.basis = model_basis(self.model, self.axis)
        self.k = self.basis.shape[1]
        self.nb = 3 if torque_bias == 'on' else 0
        self.n = self.k + self.nb + self.nu + 3
        self.block = float(block)
        self.warmup = float(warmup) if warmup is not None else min(self.window / 5.0, 2.0)
        self.change_level = float(change_level)
        self.change_inflation = float(change_inflation)
        self._gyro_noise = None if gyro_noise is None else as_noise_std(gyro_noise,
                                                                          'gyro_noise')
        self._thresholds: dict[int, float] = {}
        self.reset()

    # ------------------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget everything (clock jump, new run); the configuration is kept."""
        self._gt: list[np.ndarray] = []
        self._gw: list[np.ndarray] = []
        self._ts = np.empty(0)
        self._tau = np.empty((0, 3 + 3 * self.nu))   # and the stated inputs' columns
        self._g_dts = np.empty(0)
        self._tq_dts = np.empty(0)
        self._gyro_nv = StreamingNoise(floor=True)
        self._tau_nv = StreamingNoise(floor=False)
        self._m2_sum = np.zeros((3, 3))
        self._m2_n = 0.0
        self._last_t_in: float | None = None
        self._last_tau_in: float | None = None
        self.samples_used = 0
        self.samples_dropped = 0
        self.changes: list[float] = []      # times [s] at which the change test fired
        self.updates = 0                    # blocks folded in
        self.gaps = 0                       # gaps that made the momentum unknown again
        self._warm: list[tuple[np.ndarray, np.ndarray]] | None = []   # start-up samples
        self._tried = -math.inf             # last start-up fit attempt [s]
        self._nv: np.ndarray | None = None  # gyro noise variance [rad^2/s^2], refreshed
        self._tv = np.zeros(3)              # torque noise variance [N^2 m^2], refreshed
        self._noise_at = 0
        self._armed = 1 << 62               # blocks before the change test is armed
        self._R_theta: np.ndarray | None = None   # tensor of the weights when held fixed
        self._pend: tuple[np.ndarray, np.ndarray] | None = None  # partial block
        self._R: np.ndarray | None = None  # cached weights (see _cached)
        self._nv_R = np.zeros(3)
        self._R_at = -math.inf
        self._R_for: np.ndarray | None = None
        self._gdt = 0.0                     # nominal gyro interval [s]
        self._tdt = 0.0                     # nominal torque interval [s]
        self._walk = np.zeros((3, 3))       # momentum variance rate [N^2 m^2 s]
        self._B = np.zeros((self.k, self.k))  # gyro noise's own information per block
        self._choice = self._hold_choice() if self._hold_auto else None   # not locked yet
        self._restart()

    def _hold_choice(self) -> HoldChoice | None:
        """Hold 'auto': the twin filter under the linear hold and the judge."""
        return HoldChoice(TrackingEstimator(**self._config, hold='linear'), self.torque_bias,
                          self._config['gyro_noise'])

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples (:meth:`.StreamInput.add_gyro`; the twin's too, hold 'auto')."""
        super().add_gyro(t, omega)
        if self._choice is not None:
            self._choice.add_gyro(t, omega)

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add torque samples (:meth:`.StreamInput.add_torque`; the twin's too)."""
        super().add_torque(t, tau)
        if self._choice is not None:
            self._choice.add_torque(t, tau)

    def estimate(self) -> InertiaEstimate:
        """:meth:`.StateOutput.estimate`; with ``hold='auto'``, of the filter the batch rule
        prefers, the other dropped once the choice is locked (:mod:`.tracking_hold`)."""
        c = self._choice
        if c is not None and c.decide(self._last_t_in):
            record = dict(c.record or {}, locked=True)
            if c.chosen == 'linear':             # the twin's state becomes this filter's
                vars(self).update(vars(c.twin))
            self._choice, self._hold_record, self._hold_auto = None, record, False
        c = self._choice
        est = StateOutput.estimate(c.twin if c is not None and c.chosen == 'linear' else self)
        record = self._hold_record if c is None else dict(
            c.record or {'requested': 'auto', 'chosen': 'zoh', 'reason': 'not judged yet'},
            locked=False)
        if c is not None and est.status == 'model_mismatch':     # before the lock
            est, record = keep_by_adequacy(c.chosen, est, record, (self, c.twin))
        if record is not None:
            est.diagnostics['hold_selection'] = record
            est.diagnostics['hold'] = record['chosen']
        return est

    def _restart(self) -> None:
        """Empty filter state: diffuse prior, no anchor."""
        self.x = np.zeros(self.n)
        self.P = np.eye(self.n) * _DIFFUSE
        self._prev: tuple[float, np.ndarray] | None = None
        self._excess = 1.0
        self._excess_w, self._tests = 0.0, InnovationTests()   # and the adequacy test
        self._Beff = np.zeros((self.k, self.k))  # its sum, forgotten as the information
        self._trend = _Trend(2.0 * self.window, self.k + self.nb)

    def _initialise(self) -> None:
        """Start the filter on the start-up samples.

        The anchored equations of every start-up sample after the first (one segment, its
        momentum a state) are solved by weighted least squares in two passes (unit weights,
        then ``(I S_g I)^-1`` of the first), as the batch ``integral`` method, corrected for
        the gyro noise in the regressors (:func:`_corrected_wls`; uncorrected, 2 s of slow
        rotation gave moments shrunk by up to 85 % at a claimed sigma of 1 %); the filter
        starts from that solution with its covariance times :data:`_PRIOR_INFLATION` (the
        fit ignores the integrated torque noise, and the start-up data are folded in once
        more) and folds the start-up samples in block by block.  Nothing happens while the
        fit leaves a principal-diagonal element undetermined or has no solution.
        """
        t = np.concatenate([x[0] for x in self._warm])
        w = np.concatenate([x[1] for x in self._warm])
        self._prev = (float(t[0]), w[0].copy())
        H, y, M, T = self._equations(t[1:], w[1:], self._nv)
        keep = np.r_[:self.k + self.nb, self.n - 3:self.n]    # the stated inputs at 0
        ui = np.arange(self.k + self.nb, self.n - 3)
        H, Hu = H[:, :, keep], H[:, :, ui]
        theta = None
        for _ in range(2):
            R, _nv = self._weight(theta)
            fit = _corrected_wls(H, y, R, noise_information(self.basis, self._nv, R))
            if fit is None:                      # the rates' changes no larger than their noise
                self._prev = None
                return
            x0, inv, Hw, Wc = fit
            theta = self.basis @ x0[:self.k]
        cov = np.eye(self.n)                                  # the stated inputs' prior
        # the fit weighs white noise only: the momentum's walk over the start-up (the
        # integrated torque noise) inflates it further, by its share of the noise
        walk = float(np.trace(self._momentum_walk(self._nv))) * float(t[-1] - t[0])
        if self._nl:                      # the gyro scale's column at the fitted tensor
            Hu[:, :, -1] = self._gyro_column(w[1:], M, T[1:, -3:] - T[0, -3:], theta)
        # the fit at the stated inputs' 0 moves by D u with them (x - x0 = -D u)
        D = inv @ Hw.T @ np.einsum('ij,nik->njk', Wc, Hu).reshape(len(Hw), len(ui))
        cov[np.ix_(keep, keep)] = inv * _PRIOR_INFLATION * (1.0 + walk / float(np.trace(R))) \
            + D @ D.T
        cov[np.ix_(keep, ui)] = -D
        cov[np.ix_(ui, keep)] = -D.T
        se = np.sqrt(np.maximum(np.diag(self.basis @ cov[:self.k, :self.k] @ self.basis.T),
                                0.0))
        if not (np.all(theta[:3] > 0) and np.all(se[:3] < 0.5 * theta[:3])):
            self._prev = None
            return
        self.x, self.P = np.zeros(self.n), 0.5 * (cov + cov.T)
        self.x[keep] = x0
        self._warm, self._since = None, float(t[0])
        self._run(t[1:], w[1:])
        self._armed = self.updates
        self._trim_torque()

    # ------------------------------------------------------------------------ the filter
    def _weight(self, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Equation error covariance ``R = I S_g I`` (3, 3) at ``theta`` (default: the
        state's; None before any fit: isotropic) and the gyro variance (3,)."""
        nv = self._nv
        if theta is None and self._warm is not None:
            I = np.eye(3)                                # first pass: unit weights
        else:
            if theta is None:
                theta = self._R_theta if self._R_theta is not None else \
                    self.basis @ self.x[:self.k]
            I = theta_to_matrix(np.nan_to_num(theta), check_finite=False)
            lam, V = np.linalg.eigh(I)                   # moments kept within 10x
            top = max(float(lam[-1]), 1e-12)
            I = (V * np.clip(lam, 0.1 * top, top)) @ V.T
        R = I @ np.diag(np.maximum(nv, 1e-30)) @ I
        if self._white_y_cov is not None:               # the momentum input's own noise
            R = R + self._white_y_cov
        return 0.5 * (R + R.T), nv

    def _equations(self, t: np.ndarray, w: np.ndarray, nv: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Equations ``H`` (n, 3, nx), ``y`` (n, 3) of the samples after the anchor, and the
        integrals they come from: monomials (n, 6) and held torque (n + 1, 3 + 3 nu)."""
        s, ws = self._prev
        tt = np.concatenate([[s], t])
        M = cumulative_monomials(tt, np.vstack([ws, w]), nv, end_correction=False)[1:]
        T = self._cum(tt)
        y = T[1:, :3] - T[0, :3]
        n = len(t)
        H = np.zeros((n, 3, self.n))
        H[:, :, :self.k] = (momentum_matrix(w) + gyroscopic_matrix(M)) @ self.basis
        eye = np.eye(3)
        if self.nb:
            H[:, :, self.k:self.k + 3] = -(t - s)[:, None, None] * eye
        H[:, :, self.n - 3:] = -eye
        q = self.nu - self._nl            # the impulse's inputs: minus their impulse changes
        if q:
            H[:, :, self.k + self.nb:self.k + self.nb + q] = -(
                T[1:, 3:3 + 3 * q] - T[0, 3:3 + 3 * q]).reshape(n, q, 3).transpose(0, 2, 1)
        return H, y, M, T

    def _block(self, t: np.ndarray, w: np.ndarray) -> None:
        """Fold one block in, test it, propagate the momentum to its last sample.

        The block's equations share the anchor state, so their mean is one 3-row equation
        ``mean(H_b) x_s = mean(y_b)`` with the error covariance ``R / n`` (the gyro noise of
        ``n`` samples averaged); it carries all the block's information but the tiny spread
        of its regressors over the block, and averages the gyro noise out of the regressor
        (errors in variables) before it can bias the update.
        """
        s, ws = self._prev
        R, nv = self._cached(float(t[-1]))         # and self._walk: the block's
        tt = np.concatenate([[s], t])
        M = cumulative_monomials(tt, np.vstack([ws, w]), nv, end_correction=False)
        T = self._cum(tt)
        n = len(t)
        H = self._regressor(w.mean(axis=0), M[1:].mean(axis=0), float(np.mean(t - s)))
        if self.nu:                      # the stated inputs' columns
            H[:, self.k + self.nb:self.n - 3] = self._u_columns(
                w.mean(axis=0), M[1:].mean(axis=0), T[1:, 3:].mean(axis=0) - T[0, 3:])
        nu = (T[1:, :3].mean(axis=0) - T[0, :3]) - H @ self.x
        # the momentum's walk within the block (integrated torque noise since the anchor):
        # the mean of n walk samples, sum_bc min(tau_b, tau_c) / n^2 times its rate
        R = R / n + self._walk * float((t - s) @ (2.0 * np.arange(n - 1, -1, -1) + 1.0)) / n ** 2
        PH = self.P @ H.T
        S = H @ PH + R
        nis = float(nu @ np.linalg.solve(S, nu))
        if self._changed(nis, 3):
            self.changes.append(float(t[0]))
            self._since = float(t[0])                     # the memory starts again
            self._R_theta, self._armed = self.basis @ self.x[:self.k], 1 << 62   # till settled
            self._trend = _Trend(2.0 * self.window, self.k + self.nb)   # the jump is no trend
            self._inflate()
            self._Beff = np.zeros((self.k, self.k))
            self._tests.restart()
            PH = self.P @ H.T
            S = H @ PH + R
        G = fault_torque(ws, (self.basis @ self.x[:self.k])[MATRIX_INDEX], not self.nb)
        self._tests.sensitivity(H, G, float(np.mean(t - s)), float(t[-1] - s))
        self._tests.add(t[-1], nu, S, self.updates >= self._armed and self.nu == self._learnt)
        K = np.linalg.solve(S, PH.T).T
        K[self.k + self.nb:self.n - 3 - self._learnt] = 0.0   # considered inputs: not learnt
        self._tests.gain(K)
        self.x = self.x + K @ nu
        KHP = K @ PH.T
        P = self.P - KHP - KHP.T + K @ S @ K.T            # any gain (Schmidt-Kalman)
        self.P = 0.5 * (P + P.T)
        self._note_excess(nis / 3.0, float(t[-1] - s))
        self._Beff = self._Beff * math.exp(-float(t[-1] - s) / self.window) + self._B
        C = np.zeros((self.n, 3))          # the walk to the end against the block's mean one
        C[self.n - 3:] = -float(np.mean(t - s)) * self._walk
        self._predict(t, w, T[-1] - T[0], M[-1], (K, C, S, nu))
        self.updates += 1
        self._trend.add(float(t[-1]), self._compensated()[0], float(t[-1] - s))
        if self._armed > self.updates and self.changes and self._settled():
            self._R_theta, self._armed = None, self.updates       # re-converged

    def _regressor(self, w: np.ndarray, m: np.ndarray, dt: float) -> np.ndarray:
        """``H`` (3, nx) of one equation: ``[(L(w) + Q(m)) T, -dt 1, -1]``."""
        H = np.zeros((3, self.n))
        H[:, :self.k] = (momentum_matrix(w) + gyroscopic_matrix(m)) @ self.basis
        if self.nb:
            H[:, self.k:self.k + 3] = -dt * np.eye(3)
        H[:, self.n - 3:] = -np.eye(3)
        return H

    def _cum(self, tt: np.ndarray) -> np.ndarray:
        """Held integral (n, 3 + extra) of the torque stream (and any stated columns)."""
        return cumulative_torque(self._ts, self._tau, tt, self.hold,
                                 out=np.empty((len(tt), self._tau.shape[1])))

    def _changed(self, nis: float, dof: int) -> bool:
        """Whether the block's normalised innovation exceeds its change threshold."""
        if not self.change_level or self.updates < self._armed:
            return False
        q = self._thresholds.get(dof)
        if q is None:
            q = self._thresholds[dof] = chi2_isf(self.change_level, dof)
        return nis > q

    def _inflate(self) -> None:
        """Inflate the prior covariance of the tensor after a change; the momentum is kept (a
        payload attached without impulse conserves it, the rate jumps), unless the change is
        found again within ``EXCESS_TIME``: then the momentum jumped too (a rate kept
        continuous, ``dI w``), and its covariance is inflated by that much.  Nothing is
        inflated at the third change within ``4 EXCESS_TIME``: that is a mismatch."""
        c = self.changes
        if len(c) > 2 and c[-1] - c[-3] < 4.0 * EXCESS_TIME:
            return                 # found again and again: the model fails (a mismatch)
        s = self._scale() * self.change_inflation
        self.P[:self.k, :self.k] += np.eye(self.k) * s ** 2
        if len(self.changes) > 1 and self.changes[-1] - self.changes[-2] < EXCESS_TIME:
            self.P[self.n - 3:, self.n - 3:] += np.eye(3) * float(
                2.0 * s * np.linalg.norm(self._prev[1])) ** 2

    def _predict(self, t: np.ndarray, w: np.ndarray, y_end: np.ndarray, m_end: np.ndarray,
                 corr: tuple[np.ndarray, ...]) -> None:
        """Propagate the momentum to the block's last sample; add the process noise (the
        tensor's only while its largest variance is below the squared scale: an unexcited
        direction does not grow without bound) and take out the update's noise correlated
        with the walk (``corr``: the update's gain, that correlation, innovation covariance
        and innovation)."""
        dt = float(t[-1] - self._prev[0])
        k, nb, L = self.k, self.nb, slice(self.n - 3, self.n)
        F = np.eye(self.n)
        F[L, :k] = -gyroscopic_matrix(m_end) @ self.basis
        if nb:
            F[L, k:k + 3] = dt * np.eye(3)
        if self.nu:
            F[L, k + nb:self.n - 3] = self._u_propagation(m_end, y_end[3:])
        x = self.x.copy()
        x[L] = F[L] @ self.x + y_end[:3]
        P = F @ self.P @ F.T
        if float(np.max(np.diag(self.P)[:k])) < self._scale() ** 2:
            grow = math.expm1(dt / self.window)      # forgetting: P_psi *= exp(dt / window)
            P[:k + nb, :k + nb] += grow * self.P[:k + nb, :k + nb]
        P[L, L] += dt * self._walk
        K, C, S, nu = corr
        x += C @ np.linalg.solve(S, nu)
        SC = np.linalg.solve(S, C.T)
        self._tests.propagate(F, SC.T)
        FKC = F @ K @ C.T
        P -= FKC + FKC.T + C @ SC
        self.x, self.P = x, 0.5 * (P + P.T)
        self._prev = (float(t[-1]), w[-1].copy())
