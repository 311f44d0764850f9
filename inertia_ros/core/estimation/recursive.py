"""Recursive (online) inertia estimation for the ROS node: :class:`RecursiveEstimator`.

The same anchored momentum equations as the batch ``integral`` method,
``I w_b + int w x (I w) dt - d t_b - h0 = int tau dt``, accumulated in information form:
exponentially weighted means and centred Gram matrices of the 13 per-sample variables
``v_b = [w, m, t, T]`` (angular velocity, integrated squared rates, time, integrated torque)
from which every equation block is a fixed linear map.  The record is cut into anchored
segments (``segment`` seconds), each with its own momentum intercept ``h0``, so removing the
segment's weighted mean is the exact elimination of ``h0`` and a momentum jump (payload
release) only disturbs one segment.  Statistics are merged block by block (the parallel
update of Chan, Golub and LeVeque): the cost per sample is a few small matrix products
amortised over the block, and ``estimate()`` projects the same 13 x 13 statistics onto any
parameter set, with the batch estimator's identifiability, model selection and covariance
(white gyro noise plus the integrated torque noise of each segment).  The gyro-noise
correction of the squared-rate integrals is linear in ``v`` and applied at ``estimate()`` with
the running noise estimate, so the answer does not depend on how the streams were cut into
blocks.  Forgetting (``window`` time constant or per-sample ``forgetting`` factor) lets the
estimate follow a changing tensor.

Everything ``estimate()`` needs is kept up to date as samples are merged, so its cost does not
grow with the record: closed segments are folded into fixed sums, and the open segment's
torque-noise statistics (:func:`.statistics.torque_stats` of its demeaned variables) are
accumulated per torque interval in closed form (see :meth:`.accumulator.OnlineStats.walk_add`)
instead of being recomputed from the segment's samples, which are no longer stored.  The
statistics live in :class:`.accumulator.OnlineStats`, which owns its state; this class aligns
the streams into the variables and concludes.
Torque-free data (:func:`.homogeneous.is_torque_free`, the batch rule) gives
``scale_unobservable`` with the ratios and principal axes from the null vector of the same
statistics, as the batch estimator does.

The two streams arrive asynchronously: gyro samples are buffered until torque covering them
has arrived (a torque sample at or after the gyro time), then integrated exactly under the
zero-order hold (or linear interpolation) of the torque samples; with ``hold='auto'`` both,
into two accumulators, and the batch rule chooses between them (:mod:`.online_hold`).

With ``inertial_torque`` on or ``auto`` the rows carry the attitude integral's nine variables
too (22, the batch's wide layout) and the torque fixed in inertial axes is selected and fitted
as the batch's (:mod:`.online_inertial`).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import MAX_TIME_S, as_noise_std, as_sample_block, require_after
from .accumulator import OnlineStats
from .adequacy import Adequacy
from .align import OnlineAligner
from .assemble import status_only
from .config import require, unapplied
from .fit import Fit
from .homogeneous import homogeneous_estimate, is_torque_free
from .model import symmetry_axis as unit_axis
from .noise import StreamingNoise
from .online_hold import AutoHold
from .online_inertial import AttitudeState, check_inertial, effective_policy, online_fits
from .online_shift import ShiftRows, online_checks
from .options import (
    ALPHA,
    HOLDS,
    MIN_EQUATIONS,
    MIN_GYRO_SAMPLES,
)
from .result import InertiaEstimate
from .schedule import Reselection
from .selection import SelectionPolicy
from .statistics import SufficientStats

__all__ = ['RecursiveEstimator']

_MAX_BUFFER = 400_000                      # gyro samples kept waiting for torque
_F64 = np.dtype(np.float64)


def _one_sample(t: Any, v: Any, last: float | None, name: str) -> float | None:
    """The time [s] of one sample ``t``, ``v`` (3,) checked as a block would be (the node's
    common case); None for a block."""
    if not isinstance(t, (float, int)):
        return None
    if type(v) is np.ndarray and v.dtype is _F64:    # the node's case, checked at once
        if v.shape != (3,):
            return None
        x, y, z = v.tolist()
    elif len(v) == 3 and np.ndim(v) == 1:
        x, y, z = float(v[0]), float(v[1]), float(v[2])
    else:
        return None
    tf = float(t)
    if abs(tf) > MAX_TIME_S:        # the one-sample form of refuse_nanoseconds
        raise ValueError(f'time {tf!r} looks like nanoseconds; give seconds')
    if not (math.isfinite(tf) and math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f'{name}: contains NaN or inf')
    if last is not None and tf <= last:
        require_after(tf, last, name)       # (raises)
    return tf


class RecursiveEstimator:
    """Online inertia estimator with forgetting, fed sample by sample or in blocks.

    Parameters
    ----------
    model : {'full', 'diagonal', 'axisymmetric', 'auto'}
        Parameter set (``auto``: the batch estimator's selection, :func:`.assemble.conclude`).
    torque_bias : bool or {'auto', 'on', 'off'}
        Estimate a constant disturbance torque [N m].
    forgetting : float
        Per-sample forgetting factor ``lambda`` in (0, 1]; 1 keeps everything.
    window : float, optional
        Memory time constant [s]: sample weights decay as ``exp(-age / window)``.  Takes
        precedence over ``forgetting``.
    hold : {'zoh', 'linear', 'auto'}
        Torque between samples; ``auto``: both holds' statistics are kept on the same rows
        and the batch rule (:func:`.selection.select_hold`) chooses at each re-selection
        (:mod:`.online_hold`), reported in ``diagnostics['hold_selection']``.
    symmetry_axis : {'x', 'y', 'z'} or array_like (3,), optional
        For the axisymmetric model.
    gyro_noise : float or array_like (3,), optional
        Gyro white-noise std [rad/s]; estimated from the stream when omitted.
    alpha : float
        Level of the torque bias's test (the parameter set's: the batch's MSE test at 5 %).
    block : int
        Gyro samples buffered before an update of the statistics (``estimate`` always flushes).
    segment : float, optional
        Anchored-segment length [s]: each segment has its own momentum intercept, so a
        momentum jump (payload change) only affects one segment.  Default ``window`` or 10 s.
    reselect_every : int
        With ``model`` or ``torque_bias`` ``'auto'``: run the model-selection tests on every
        ``reselect_every``-th call of :meth:`estimate` and reuse the parameter set they chose
        in between (one fit instead of two or more per call; the node re-selects about once
        a second).  1 (default) selects on every call.
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainty of the torque and the gyro (0.01 = 1 %),
        propagated into the standard errors as by :func:`~.batch.estimate`.
    defer_adequacy : bool
        A test estimate (every ``reselect_every``-th) reports the previous adequacy verdict and
        leaves its own test to :meth:`refresh` (the node: after publishing), for the estimates
        that follow (the tensor unchanged).  Default False.  The first test, one not refreshed
        and one whose verdict is stale (:data:`.schedule.STALE_FRACTION`) run in estimate().
    nuisance : str
        Only ``'off'``: any other value is refused by :func:`.config.require` (one line).
    inertial_torque : {'off', 'auto', 'on'}
        A torque constant in inertial axes beside the bias (:mod:`.online_inertial`).
    """

    #: White noise in the equations' right-hand side besides the gyro's (a momentum input's,
    #: set by :class:`.recursive_momentum.MomentumRecursiveEstimator`) [N^2 m^2 s^2].
    _white_y_cov: np.ndarray | None = None

    def __init__(self, model: str = 'full', torque_bias: bool | str = False,
                 forgetting: float = 1.0, window: float | None = None, hold: str = 'zoh',
                 symmetry_axis: Any = None, gyro_noise: Any = None, alpha: float = ALPHA,
                 block: int = 256, segment: float | None = None,
                 reselect_every: int = 1, torque_scale_std: float = 0.0,
                 gyro_scale_std: float = 0.0, defer_adequacy: bool = False,
                 nuisance: Any = 'off', inertial_torque: str = 'off') -> None:
        opts = require('recursive', 'torque', dict(
            model=model, torque_bias=torque_bias, hold=hold, symmetry_axis=symmetry_axis,
            alpha=alpha, torque_scale_std=torque_scale_std, gyro_scale_std=gyro_scale_std,
            nuisance=nuisance))
        torque_bias = opts.torque_bias
        if not (0.0 < forgetting <= 1.0):
            raise ValueError(f'forgetting: must be in (0, 1], got {forgetting!r}')
        if window is not None and not window > 0:
            raise ValueError(f'window: must be > 0 s, got {window!r}')
        self.policy = SelectionPolicy(alpha, torque_scale_std=torque_scale_std,
                                      gyro_scale_std=gyro_scale_std,
                                      inertial_torque=check_inertial(inertial_torque))
        if segment is not None and not segment > 0:
            raise ValueError(f'segment: must be > 0 s, got {segment!r}')
        self.segment = float(segment if segment is not None else (window or 10.0))
        if int(block) < 1:
            raise ValueError(f'block: must be >= 1, got {block!r}')
        self._schedule = Reselection(reselect_every, defer_adequacy)   # validates
        self.reselect_every = self._schedule.every
        self.defer_adequacy = self._schedule.defer
        self.model = model
        self.torque_bias = torque_bias
        self.forgetting = float(forgetting)
        self.window = window
        self.hold = hold
        self.axis = unit_axis(symmetry_axis)
        self.block = int(block)
        self._gyro_noise = None if gyro_noise is None else as_noise_std(gyro_noise,
                                                                          'gyro_noise')
        self.reset()

    # -----------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget everything (clock jump, new run)."""
        self._pt: list[np.ndarray] = []      # pending torque blocks
        self._ptau: list[np.ndarray] = []
        self._palt: list[np.ndarray] = []    # pending second torque (OnlineAligner.tau_alt)
        self._single_t: list[float] = []
        self._single_w: list[Any] = []
        self._n_buf = 0                     # samples in self._gt
        self._new_torque = False            # torque arrived since the last _process
        self._gt: list[np.ndarray] = []
        self._gw: list[np.ndarray] = []
        self._align = OnlineAligner()    # the held torque, intervals, monomial integral
        wide = self.policy.inertial_torque != 'off'      # (and the attitude: 22 variables)
        self._align.attitude = AttitudeState() if wide else None
        # the statistics of the merged equations, owning their state (one per hold kept)
        self._accs = {h: OnlineStats(self.segment, self.window, self.forgetting,
                                     width=22 if wide else 13)
                      for h in (HOLDS if self.hold == 'auto' else (self.hold,))}
        self._auto = AutoHold(wide) if self.hold == 'auto' else None
        self._shift_rows = ShiftRows(self.segment, self.window is None and self.forgetting == 1)
        self._set_active('zoh' if self.hold == 'auto' else self.hold)   # the hold estimated
        self._tau_var: np.ndarray | None = None
        self._schedule.reset()            # the re-selection schedule's verdicts
        self._tf_memo: dict[str, Any] = {}   # the torque-free checks' (OnlineTorqueFreeChecks)
        self.gaps = 0                    # gaps that ended a segment holding data
        self._last_t_in: float | None = None
        self._last_tau_in: float | None = None
        self._gyro_nv = StreamingNoise(floor=True)      # gyro noise (unless given)
        self._tau_nv = StreamingNoise(floor=False)     # torque noise
        self.samples_used = 0
        self.samples_dropped = 0

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples.

        Parameters
        ----------
        t : float or array_like, shape (n,)
            Sample times [s], increasing across calls.
        omega : array_like, shape (3,) or (n, 3)
            Angular velocity [rad/s].
        """
        tf = _one_sample(t, omega, self._last_t_in, 'omega')
        if tf is not None:              # fast path for one sample
            self._last_t_in = tf
            self._single_t.append(tf)
            self._single_w.append(omega)
            if len(self._single_t) + self._n_buf >= self.block and self._new_torque:
                self._process()
            return
        self._flush_single()
        ta, wa = as_sample_block(t, omega, 'omega')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_t_in, 'omega')
        self._last_t_in = float(ta[-1])
        self._gt.append(ta)
        self._gw.append(wa)
        self._n_buf += len(ta)
        if self._n_buf + len(self._single_t) >= self.block and self._new_torque:
            self._process()
        elif self._n_buf > _MAX_BUFFER:
            # torque stream stalled: keep the newest samples only
            t = np.concatenate(self._gt)
            w = np.concatenate(self._gw)
            self.samples_dropped += len(t) - _MAX_BUFFER // 2
            self._gt, self._gw = [t[-(_MAX_BUFFER // 2):]], [w[-(_MAX_BUFFER // 2):]]
            self._n_buf = len(self._gt[0])

    def _flush_single(self) -> None:
        """Move single gyro samples into the block buffer."""
        if self._single_t:
            self._gt.append(np.array(self._single_t, dtype=float))
            self._gw.append(np.array(self._single_w, dtype=float).reshape(-1, 3))
            self._n_buf += len(self._single_t)
            self._single_t, self._single_w = [], []

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add torque samples.

        Parameters
        ----------
        t : float or array_like, shape (n,)
            Sample times [s], increasing across calls.
        tau : array_like, shape (3,) or (n, 3)
            Torque about the centre of mass [N m].
        """
        tf = _one_sample(t, tau, self._last_tau_in, 'torque')
        if tf is not None:
            self._last_tau_in = tf
            self._new_torque = True
            self._pt.append(np.array([tf]))
            self._ptau.append(np.asarray(tau, dtype=float).reshape(1, 3))
            return
        ta, xa = as_sample_block(t, tau, 'torque')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_tau_in, 'torque')
        self._last_tau_in = float(ta[-1])
        self._new_torque = True
        self._pt.append(ta)
        self._ptau.append(xa)

    def merge(self) -> None:
        """Merge the buffered samples the torque covers now (:meth:`estimate` then has less to
        do); the statistics, so the estimate, do not depend on the cut (up to rounding)."""
        self._process()

    def _process(self) -> None:
        """Turn buffered gyro samples covered by torque into equations and merge them."""
        self._flush_single()
        self._new_torque = False
        if self._pt:
            self._take_torque()
        if not self._gt:
            return
        t, w, breaks = self._ready_gyro()
        if len(t) == 0:
            return
        if self._gyro_noise is None:
            self._gyro_nv.add(w)
        held = 'zoh' if self._auto is not None else self.hold
        V = self._align.variables(t, w, held)       # [w, m, t, T] (n, 13), [.., c] (n, 22)
        Vs = {held: V} if self._auto is None else self._auto.rows(self._align, t, V)
        # a gap starts a new anchored segment: the wrongly held torque and the trapezoid across
        # the gap shift T and M by constants, which the new segment's momentum absorbs
        for h, acc in self._accs.items():
            acc.add_motion(w)                 # mean(w w'): the gyroscopic noise walk
            lo = 0
            for k in breaks:
                if k > lo:
                    acc.merge(t[lo:k], Vs[h][lo:k], self._align.ts)
                if h == held:          # a break ending a segment with data
                    acc.flush()
                    self.gaps += acc.w0 > 0
                acc.close(float(t[k]))
                lo = k
            acc.merge(t[lo:], Vs[h][lo:], self._align.ts)
        self._shift_rows.merge(t, V, breaks)
        self.samples_used += len(t)
        if self._auto is not None:
            self._auto.fold(self._align, float(t[-1]))
        self._align.trim(float(t[-1]), held)

    def _set_active(self, hold: str) -> None:
        """Estimate ``hold``; the other hold's accumulator (``hold='auto'``), read only at the
        hold choice and after a failed adequacy test, merges lazily (its blocks in runs)."""
        self._active = hold
        for h, acc in self._accs.items():
            acc.lazy = h != hold

    @property
    def _acc(self) -> OnlineStats:
        """The statistics of the hold estimated (the chosen one with ``hold='auto'``)."""
        return self._accs[self._active]

    def _take_torque(self) -> None:
        """Move the pending torque samples into the held stream; update the torque noise."""
        new_t = np.concatenate(self._pt)
        new_tau = np.concatenate(self._ptau)     # (n, 3) and any extra held columns
        alt = np.concatenate(self._palt) if self._palt else None
        self._pt, self._ptau, self._palt = [], [], []
        self._align.take(new_t, new_tau, alt)
        tau = np.ascontiguousarray(new_tau[:, :3])
        for h, acc in self._accs.items():
            acc.add_torque_power(alt if h == 'linear' and alt is not None else tau)
        # the same robust estimator as batch, on the recent samples whatever the block size
        # (the variance itself is taken in estimate())
        self._tau_nv.add(tau)

    def _ready_gyro(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """Buffered gyro samples now covered by torque (the rest stays buffered), with gaps.

        Returns the samples ``t`` (n,), ``w`` (n, 3) and the indices where a gap starts a
        new segment (:meth:`.align.OnlineAligner.gaps`).
        """
        t, w, t_wait, w_wait, dropped, covered = self._align.ready(np.concatenate(self._gt),
                                                                   np.concatenate(self._gw))
        self.samples_dropped += dropped
        self._gt, self._gw = ([t_wait], [w_wait]) if len(t_wait) else ([], [])
        self._n_buf = len(t_wait)
        if not covered:
            return t, w, []
        t, w, breaks, dropped = self._align.gaps(t, w)
        self.samples_dropped += dropped
        return t, w, breaks

    def _test_adequacy(self, f: Fit, nv: np.ndarray, tv: np.ndarray) -> Adequacy:
        """The window tests of ``f`` (:meth:`.accumulator.OnlineStats.window_test`)."""
        a = self._acc.window_test(f, nv, tv, **self._context())
        if self._acc.short is not None and self._acc.short.lazy:
            for acc in self._accs.values():       # past the bias split: the other hold's too
                if acc.short is not None:
                    acc.short.lazy = True
        if self._auto is not None and not a.ok:   # the other hold's fit may pass: kept next
            self._auto.check_other(self._active, self._accs, f, nv, tv,
                                   self._tau_var is not None, self._context())
        return a

    def refresh(self) -> bool:
        """Run the adequacy test the last estimate deferred (``defer_adequacy``), if any: call
        it before new samples are merged, so that it tests that estimate's statistics and fit.
        Returns True when a test ran.
        """
        return self._schedule.refresh(self._test_adequacy)

    def _gyro_dt(self) -> float:
        """Median recent gyro sample interval [s] (0 before two samples)."""
        return self._align.g_dt      # kept by the gap rule

    def _gyro_var(self) -> np.ndarray:
        """Gyro white-noise variance per axis [rad^2/s^2]: given, or the streaming estimate."""
        if self._gyro_noise is not None:
            return self._gyro_noise ** 2
        return self._gyro_nv.variance()

    def _torque_variance(self) -> np.ndarray | None:
        """Torque white-noise variance per axis (None while not
        :meth:`~.noise.StreamingNoise.known`); the hook where a momentum input states its
        own (:mod:`.recursive_momentum`)."""
        return self._tau_nv.variance() if self._tau_nv.known() else None

    def _context(self) -> dict[str, Any]:
        """The noise model's stream figures for the statistics: intervals, white y noise."""
        return {'torque_dt': self._align.tau_dt, 'gyro_dt': self._gyro_dt(),
                'white_y_cov': self._white_y_cov}

    def _stats(self, nv: np.ndarray, n_eff: float, gyro_scale: float = 1.0) -> SufficientStats:
        """The weighted statistics of everything merged (:meth:`.OnlineStats.stats`)."""
        return self._acc.stats(nv, n_eff, self._tau_var is not None, gyro_scale=gyro_scale,
                               **self._context())

    def _choose_hold(self, nv: np.ndarray, torque_free: bool, diag: dict[str, Any],
                     inertial: str = 'off') -> None:
        """``hold='auto'``: the hold by the batch rule at each re-selection (reused between);
        a change drops the verdicts of the other hold's statistics."""
        assert self._auto is not None
        due = (self._schedule.estimates - 1) % self.reselect_every == 0
        tv = self._tau_var if self._tau_var is not None else np.zeros(3)
        n_eff = self._acc.n_eff()
        changed, diag['hold_selection'] = self._auto.select(
            due, torque_free, lambda h: self._accs[h].stats(
                nv, n_eff, self._tau_var is not None, **self._context()),
            self.torque_bias != 'off', nv, tv, self.samples_used, inertial)
        if changed:
            self._set_active(self._auto.chosen)
            self._schedule.reset_verdicts()
        diag['hold'] = self._active

    def estimate(self) -> InertiaEstimate:
        """Current estimate from everything merged so far (flushes covered samples first).

        Returns
        -------
        InertiaEstimate
            ``method='recursive'``; standard errors from the same noise model as the batch
            method (white gyro noise, integrated torque noise per segment), scaled up by the
            residual variance when that is larger.
        """
        self._process()
        self._schedule.tick()
        base = dict(method='recursive', samples_used=self.samples_used,
                    samples_dropped=self.samples_dropped)
        nv = self._gyro_var()
        diag: dict[str, Any] = {'gyro_noise_std': np.sqrt(nv), 'warnings': [],
                                'effective_samples': self._acc.w0 + self._acc.wc}
        if self.gaps:
            diag['warnings'].append(f'{self.gaps} gap(s) in the streams: each started a new '
                                    'segment; gyro samples inside torque gaps were dropped')
        n_eff = self._acc.n_eff()
        self._tau_var = self._torque_variance()
        if self.samples_used < MIN_GYRO_SAMPLES or n_eff < MIN_EQUATIONS:
            diag['reason'] = f'only {self.samples_used} gyro samples covered by torque so far'
            return status_only('insufficient_data', diag, base)
        # torque-free data (the batch rule): the scale is unobservable, the ratios and the
        # principal axes come from the null vector of the homogeneous problem
        torque_rms = self._acc.torque_rms()
        diag['torque_rms'] = torque_rms
        tq_std = np.sqrt(self._tau_var) if self._tau_var is not None else np.zeros(3)
        diag['torque_noise_std'] = tq_std
        policy = effective_policy(self.policy, self._align.attitude, diag)
        if self._auto is not None:     # (the linear hold keeps the held fit's inertial torque)
            self._choose_hold(nv, is_torque_free(torque_rms, tq_std), diag, policy.inertial_torque)
            policy = self._auto.held_inertial(policy, self._active)
        st = self._stats(nv, n_eff)
        # the meat of weighted sums scales by w^2 / w
        ratio = (self._acc.w00 + self._acc.w00c) / (self._acc.w0 + self._acc.wc)
        if is_torque_free(torque_rms, tq_std):
            diag['warnings'] += unapplied('recursive', self.policy)
            return homogeneous_estimate(st, nv, diag, base, cov_scale=ratio,
                                        checks=online_checks(self, nv, n_eff, st))
        tv = self._tau_var if self._tau_var is not None else np.zeros(3)
        # fit(basis, bias, offset, theta0, inertial), the adequacy test, d beta / d g
        fit, adequacy, gyro_sensitivity = online_fits(self, st, nv, tv, n_eff, ratio)
        return self._schedule.decide(fit, self.model, self.torque_bias, self.axis, policy,
                                     diag, base, adequacy, gyro_sensitivity, self.samples_used)
