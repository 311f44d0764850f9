"""Online estimation with wheel, flywheel or rotor input: :class:`MomentumRecursiveEstimator`.

The online form of :func:`.momentum.estimate_with_momentum`. The internal angular momentum
``h`` (wheels, rotors) and a known torque on the same stamps (rotor thrust and drag) arrive
as blocks (:meth:`MomentumRecursiveEstimator.add_momentum`, or
:meth:`~MomentumRecursiveEstimator.add_wheels` with ``h`` alone), next to the gyro and,
optionally, another torque stream. They are turned, as they become covered, into the exactly
equivalent piecewise-constant torque on the union grid of gyro and momentum stamps (the
batch rule of :func:`.momentum.equivalent_torque`: its held integral is ``int tau - (h - h0)
- int w x h``, ``h`` by cubic Hermite interpolation with the slopes of ``np.gradient``, ``w
x h`` by the trapezoid on the grid), which feeds the :class:`~.recursive.RecursiveEstimator`
this class extends: nothing is differentiated and ``h0`` joins each segment's intercept.

A grid interval is emitted once everything it needs has arrived: the momentum sample after
its end (the Hermite slope there), a gyro sample at or after its end, and (with another
torque stream) the torque sample holding over it.  The noise model is the batch one: the
momentum noise (estimated from the recent ``h`` samples' high-order differences, per axis)
is white noise in the right-hand side (``white_y_cov``), and the gyro noise ``n x h``, the
momentum noise ``w x e`` in the ``w x h`` integral and the torques' own noise are white
torque noise held over each grid interval (:meth:`_torque_variance`); the first two, whose
covariance follows ``|h(t)|`` and ``|w(t)|``, weighted per grid interval as the batch
weights them (:mod:`.online_walk`: each interval's weights by the batch's functions, read
at the current noise levels by the accumulator).

Stated inputs (wheel inertias, rotor coefficients: ``names`` at construction, one-sigma
changes of ``h`` and of the torque with every block; ``torque_scale_std`` of the other torque;
``gyro_scale_std``) are profiled under their prior as the batch does (:mod:`.stated`): the
equivalent torque of each input's change (for the gyro scale the ``w x h`` part) is held over
the same grid intervals and carried as extra columns of the same equations
(:class:`.align.OnlineAligner`'s extra columns), so their cross products accumulate with the same
forgetting; each estimate fits them with the tensor under the prior, reads the statistics with
the inputs corrected by the posterior mean and adds ``D cov_u D'``
(:mod:`.online_stated`, ``diagnostics['input_uncertainty']``).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._numeric import psd_part
from .._validate import as_sample_block, require_after
from ..tensor import theta_to_matrix
from .align import OnlineAligner, gap_starts, hermite, run_slopes
from .config import require, substitutions
from .fit import walk_bases
from .momentum import Momentum, held_over, interval_torque, walk_sums, walk_variance
from .noise import StreamingNoise
from .online_stated import StatedInputs
from .online_walk import FeatureStore, walk_deviation, walk_model
from .options import HOLDS
from .recursive import RecursiveEstimator
from .regressors import gyroscopic_matrix, momentum_matrix
from .result import InertiaEstimate
from .selection import hold_not_compared
from .tracking import TrackingEstimator
from .tracking_hold import HoldChoice
from .tracking_input import StreamInput

__all__ = ['MomentumInput', 'MomentumRecursiveEstimator', 'MomentumTrackingEstimator']

_MAX_BUFFER = 400_000        # samples a stream may wait for the others (then half are dropped)


class _Buffer:
    """Samples of one stream not yet consumed: times (n,) and any number of value arrays."""

    def __init__(self, *widths: tuple[int, ...]) -> None:
        self.t = np.empty(0)
        # (0, c) for per-sample rows, (p, 0, c) for p stacked series
        self.v = [np.empty((0, w[0])) if len(w) == 1 else np.empty((w[0], 0, w[1]))
                  for w in widths]

    def add(self, t: np.ndarray, *values: np.ndarray) -> None:
        self.t = np.concatenate([self.t, t])
        self.v = [np.concatenate([a, b], axis=-2 if a.ndim == 3 else 0)
                  for a, b in zip(self.v, values, strict=True)]

    def keep_from(self, i: int) -> None:
        """Drop the samples before index ``i``."""
        if i > 0:
            self.t = self.t[i:]
            self.v = [a[:, i:] if a.ndim == 3 else a[i:] for a in self.v]


class MomentumInput:
    """The one reduction of the momentum input, shared by the online estimators (a mixin).

    Buffers the gyro, the momentum input and the other torque, and emits every covered
    grid interval's equivalent torque (with the other torque's hold applied, and the
    stated inputs' one-sigma changes as extra columns) to ``self._take(grid, tau, alt, x,
    t_gyro, w_gyro)``: :class:`MomentumRecursiveEstimator` (its accumulator) and
    :class:`MomentumTrackingEstimator` (its Kalman filter) differ only there.  The
    equivalent torque's noise is :meth:`_reduced_noise`.
    """

    _choice: Any = None     # the tracker's hold-'auto' twin and judge, fed the same blocks

    def _options(self, mode: str, names: Sequence[str], other_torque: bool, hold: str,
                 kwargs: dict[str, Any]) -> dict[str, Any]:
        """Check the options against the table (``mode``), keep the momentum input's and
        return the others without the scales (stated inputs here, never a scale of y)."""
        self._opts = require(mode, 'wheels_torque' if other_torque else 'wheels',
                             dict({'model': 'full', 'torque_bias': False}, **kwargs, hold=hold))
        # the stated inputs' columns take the places after the 13 variables: no inertial
        # torque here ('on' refused by the table; 'auto' runs without it; the tracker has none)
        kwargs = {k: v for k, v in kwargs.items() if k != 'inertial_torque'}
        if mode == 'recursive':
            kwargs['inertial_torque'] = 'off'
        scale = kwargs.pop('torque_scale_std', 0.0)
        # the gyro's scales the measured rate in both sides, w x h included: a stated input
        # like the others (:mod:`.online_stated`), not a scale of y
        gscale = kwargs.pop('gyro_scale_std', 0.0)
        self.names = tuple(names)
        self.other_torque = bool(other_torque)
        self._requested = hold
        self.torque_hold = hold if self.other_torque else HOLDS[0]
        self.torque_scale_std = float(scale) if self.other_torque else 0.0
        self.gyro_scale_std = float(gscale)
        return kwargs

    def reset(self) -> None:
        """Forget everything: the estimator's state, the buffers, the stated inputs'."""
        super().reset()
        p = len(getattr(self, 'names', ()))
        self._g = _Buffer((3,))                       # gyro: w
        self._m = _Buffer((3,), (3,), (p, 3), (p, 3))  # momentum: h, torque, dh, dtorque
        self._o = _Buffer((3,))                       # other torque
        self._cursor: float | None = None             # start of the next grid interval [s]
        # the stated inputs' impulse changes: extra columns of the same equations
        st = StatedInputs(getattr(self, 'names', ()), getattr(self, 'torque_scale_std', 0.0),
                          getattr(self, 'gyro_scale_std', 0.0))
        self._stated = st if len(st.names) else None
        self._h_noise = StreamingNoise(floor=False)
        self._tr_noise = StreamingNoise(floor=False)
        self._o_noise = StreamingNoise(floor=False)
        self._o_dt: list[float] = []
        self._m_dt: list[float] = []
        self._walk_h = np.zeros((3, 3))          # sum over the grid of [h]x_ij^2
        self._walk_w = np.zeros((3, 3, 3))       # sum over the grid of [w]x_ij [w]x_ik
        self._walk_n = 0
        self.momentum_samples = 0

    # ------------------------------------------------------------------ input
    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples (as :meth:`.RecursiveEstimator.add_gyro`)."""
        ta, wa = as_sample_block(np.atleast_1d(np.asarray(t, dtype=float)),
                                 np.asarray(omega, dtype=float).reshape(-1, 3), 'omega')
        if len(ta) == 0:
            return
        require_after(ta[0], self._g.t[-1] if len(self._g.t) else None, 'omega')
        self._g.add(ta, wa)
        self._advance()
        self._cap(self._g)
        if self._choice is not None:
            self._choice.add_gyro(t, omega)

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add samples of the other known torque [N m] (``other_torque=True`` only)."""
        if not self.other_torque:
            raise ValueError('torque: this estimator was built with other_torque=False (the '
                             'momentum input is the only known torque)')
        ta, xa = as_sample_block(np.atleast_1d(np.asarray(t, dtype=float)),
                                 np.asarray(tau, dtype=float).reshape(-1, 3), 'torque')
        if len(ta) == 0:
            return
        require_after(ta[0], self._o.t[-1] if len(self._o.t) else None, 'torque')
        self._o.add(ta, xa)
        self._o_noise.add(xa)
        self._o_dt = (self._o_dt + np.diff(self._o.t[-len(ta) - 1:]).tolist())[-64:]
        self._advance()
        if self._choice is not None:
            self._choice.add_torque(t, tau)

    def add_wheels(self, t: Any, h: Any) -> None:
        """Add internal angular momentum samples ``h`` (n, 3) [N m s], body frame, at ``t``
        (n,) [s] (no torque, no uncertain inputs; see :meth:`add_momentum`)."""
        h = np.asarray(h, dtype=float).reshape(-1, 3)
        self.add_momentum(Momentum(np.atleast_1d(np.asarray(t, dtype=float)), h,
                                   np.zeros((len(self.names), len(h), 3)), self.names))

    def add_momentum(self, m: Momentum) -> None:
        """Add a block of the momentum input (:func:`.momentum.wheel_inputs`,
        :meth:`.rotors.RotorSet.inputs`): stamps, ``h``, optional torque and the one-sigma
        changes of both for each of ``names`` (in that order)."""
        t = np.atleast_1d(np.asarray(m.t, dtype=float))
        k, p = len(t), len(self.names)
        h = np.asarray(m.h, dtype=float).reshape(k, 3)
        tq = np.zeros((k, 3)) if m.torque is None else np.asarray(m.torque, float).reshape(k, 3)
        dh = np.asarray(m.h_std, dtype=float).reshape(p, k, 3)
        dt = np.zeros((p, k, 3)) if m.torque_std is None else \
            np.asarray(m.torque_std, dtype=float).reshape(p, k, 3)
        if tuple(m.names) != self.names and p:
            raise ValueError(f'momentum: uncertain inputs {list(m.names)} differ from the '
                             f'estimator\'s {list(self.names)}')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(h)) and np.all(np.isfinite(tq))):
            raise ValueError('momentum: contains NaN or inf')
        if np.any(np.diff(t) <= 0) or (len(self._m.t) and k and t[0] <= self._m.t[-1]):
            raise ValueError('momentum: times must be strictly increasing across blocks (call '
                             'reset() after a clock jump)')
        if k == 0:
            return
        self._m.add(t, h, tq, dh, dt)
        if self._stated is not None:
            self._stated.observe(h, tq, dh, dt)
        self._h_noise.add(h)
        if m.torque is not None:
            self._tr_noise.add(tq)
        self._m_dt = (self._m_dt + np.diff(self._m.t[-k - 1:]).tolist())[-64:]
        self.momentum_samples += k
        self._advance()
        self._cap(self._m)
        if self._choice is not None:
            self._choice.add_momentum(m)

    # ------------------------------------------------------------------ the grid
    def _horizon(self) -> float | None:
        """Latest grid time whose interval can be emitted, or None."""
        if len(self._m.t) < 3 or len(self._g.t) == 0:
            return None
        hi = min(float(self._m.t[-2]), float(self._g.t[-1]))
        if self.other_torque:
            if len(self._o.t) == 0:
                return None
            hi = min(hi, float(self._o.t[-1]) if self.torque_hold != 'zoh' else np.inf)
        return hi

    def _advance(self) -> None:
        """Emit the equivalent torque of every grid interval now covered (and its gyro)."""
        hi = self._horizon()
        if hi is None:
            return
        if self._cursor is None and not self._start():
            return
        while True:                   # run by run: a block may reach past momentum gaps
            c, end = self._skip_gaps(float(self._cursor), hi)
            tg, tm = self._g.t, self._m.t
            grid = np.union1d(tg[(tg >= c) & (tg <= end)], tm[(tm >= c) & (tm <= end)])
            grid = np.union1d([c], grid)
            if self.other_torque and self.torque_hold != 'linear':
                # zero-order hold: interval [g_i, g_i+1) needs the torque sample at or before
                # g_i to be the last one: a torque sample at or after g_i has arrived
                grid = grid[:int(np.searchsorted(grid, self._o.t[-1], side='right')) + 1]
                grid = grid[grid <= end]
            if len(grid) < 2:
                return
            self._emit(grid)
            if end >= hi:
                return

    def _skip_gaps(self, c: float, hi: float) -> tuple[float, float]:
        """Momentum gaps (an interval over ``GAP_FACTOR`` nominal ones): nothing known of
        ``h`` inside.  A cursor in a gap jumps to its end (the gyro samples skipped are
        dropped; the jump of the emitted torque stamps starts a new anchored segment, whose
        intercept takes the unknown change); the grid stops at the next gap.  Returns the
        cursor and the horizon."""
        tm = self._m.t
        for i in self._momentum_gaps():
            if tm[i] <= c < tm[i + 1]:
                skipped = (self._g.t > c) & (self._g.t < tm[i + 1])
                self.samples_dropped += int(np.sum(skipped))
                self.gaps += 1
                c = float(tm[i + 1])
                self._cursor = c
            elif tm[i] >= c:
                return c, min(hi, float(tm[i]))
        return c, hi

    def _momentum_gaps(self) -> np.ndarray:
        """Gaps of the buffered momentum samples (:func:`.align.gap_starts`, the batch rule,
        on the nominal interval of the recent samples); none before two intervals."""
        if len(self._m_dt) < 2:
            return np.zeros(0, dtype=int)
        return gap_starts(self._m.t, float(np.median(self._m_dt)))

    def _start(self) -> bool:
        """Set the first grid time (the batch's common coverage start); drop earlier gyro."""
        lo = max(float(self._g.t[0]), float(self._m.t[0]))
        if self.other_torque:
            lo = max(lo, float(self._o.t[0]))
        if lo > self._g.t[-1] or lo > self._m.t[-1]:
            return False
        early = int(np.searchsorted(self._g.t, lo, side='left'))
        self.samples_dropped += early
        self._g.keep_from(early - 1)      # one earlier sample stays for interpolation at lo
        self._cursor = lo
        return True

    def _emit(self, grid: np.ndarray) -> None:
        """Feed the equivalent torque on ``grid`` (and the gyro samples it covers)."""
        tm = self._m.t
        h, tq, dh, dtq = self._m.v
        gaps = self._momentum_gaps()
        hg = hermite(tm, h, run_slopes(tm, h, gaps), grid)
        wg = np.column_stack([np.interp(grid, self._g.t, self._g.v[0][:, k])
                              for k in range(3)])
        has_tr = self._tr_noise.count > 0

        def lin(y: np.ndarray) -> np.ndarray:
            return np.column_stack([np.interp(grid, tm, y[:, k]) for k in range(3)])
        own = interval_torque(grid, wg, hg, lin(tq) if has_tr else None)
        other, other_lin = self._other_on(grid) if self.other_torque else (None, None)
        x = None
        if self._stated is not None:  # the stated inputs' one-sigma changes, held alike
            x = [interval_torque(grid, wg, hermite(tm, dh[i], run_slopes(tm, dh[i], gaps),
                                                   grid), lin(dtq[i]) if has_tr else None)
                 for i in range(len(self.names))]
            if self.torque_scale_std:
                x.append(self.torque_scale_std * (other if other is not None else 0 * own))
            if self._stated.gscale:
                c = np.cross(wg, hg)
                x.append(-0.5 * (c[1:] + c[:-1]))
            x = np.concatenate(x, axis=1)
        H, W, n = walk_sums(hg[:-1], wg[:-1])    # the n x h and w x e torque-noise walks
        self._walk_h += H
        self._walk_w += W
        self._walk_n += n
        self._walk_intervals(grid, hg, wg)
        gi = (self._g.t >= grid[0]) & (self._g.t <= grid[-1])
        t_in, w_in = self._g.t[gi], self._g.v[0][gi]
        fresh = t_in > (self._last_t_in if self._last_t_in is not None else -np.inf)
        self._take(grid, own if other is None else own + other,
                   None if other_lin is None else own + other_lin, x, t_in[fresh], w_in[fresh])
        self._cursor = float(grid[-1])
        self._trim()

    def _walk_intervals(self, grid: np.ndarray, hg: np.ndarray, wg: np.ndarray) -> None:
        """The grid intervals' walk as the estimator carries it (here: only its record
        sums, :meth:`_walk_terms`)."""

    def _cap(self, buf: _Buffer) -> None:
        """A stalled stream: keep the newest half of a buffer grown past :data:`_MAX_BUFFER`
        (the dropped gyro samples counted) and restart the grid after them; the jump of the
        emitted torque stamps is a gap, which starts a new anchored segment."""
        if len(buf.t) <= _MAX_BUFFER:
            return
        drop = len(buf.t) - _MAX_BUFFER // 2
        if buf is self._g:
            self.samples_dropped += drop
        buf.keep_from(drop)
        self._cursor = None

    def _other_on(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The other torque over each grid interval (G - 1, 3): the batch rule
        (:func:`.momentum.held_over`) with the other torque's hold (``auto``: held), and
        with ``hold='auto'`` also linear (else None)."""
        o = (self._o.t, self._o.v[0])
        if self.torque_hold != 'auto':
            return held_over(grid, *o, self.torque_hold), None
        return held_over(grid, *o, 'zoh'), held_over(grid, *o, 'linear')

    def _trim(self) -> None:
        """Drop the consumed samples (keeping what interpolation at the cursor needs)."""
        c = self._cursor
        gi = max(int(np.searchsorted(self._g.t, c, side='right')) - 1, 0)
        self._g.keep_from(gi)
        # the momentum interval holding the cursor and the sample before it (its slope)
        mi = max(int(np.searchsorted(self._m.t, c, side='right')) - 2, 0)
        self._m.keep_from(mi)
        if self.other_torque:
            oi = max(int(np.searchsorted(self._o.t, c, side='right')) - 1, 0)
            self._o.keep_from(oi)

    # ------------------------------------------------------------------ noise and estimate
    def _record(self, diag: dict[str, Any]) -> None:
        """The momentum input's record in ``diag`` (``diagnostics['momentum']``) and, with
        ``hold='auto'`` and no other torque, the hold that was not chosen."""
        diag['momentum'] = {'samples': self.momentum_samples,
                            'h_noise_std': self._h_noise.std(),
                            'gyro_per_wheel_sample': self._share(),
                            'other_torque': self.other_torque}
        if self._requested == 'auto' and not self.other_torque:
            diag['hold'] = 'zoh'
            diag['hold_selection'] = {'requested': 'auto', **hold_not_compared(
                'no other torque: the momentum input is not held (known at its samples), so '
                'there is no hold to choose')}

    def _share(self) -> float:
        """Gyro samples per momentum sample (those sharing one momentum sample's noise)."""
        if not self._m_dt or self._gyro_dt() <= 0:
            return 1.0
        return max(1.0, float(np.median(self._m_dt)) / self._gyro_dt())

    def _reduced_noise(self, tau_dt: float
                       ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """The equivalent torque's white-noise variance (3,) [N^2 m^2] on grid intervals of
        ``tau_dt`` [s] (the batch's), the white noise (3, 3) [N^2 m^2 s^2] of each
        equation's right-hand side (the momentum samples' own, shared by ``share`` gyro
        samples) and the walk's levels per grid interval at the same noise levels
        (:func:`.online_walk.walk_model`)."""
        gv, cov, share, mean = self._walk_terms()
        var = np.zeros(3)
        for nv, dts in ((self._o_noise, self._o_dt), (self._tr_noise, self._m_dt)):
            if nv.known() and dts:
                var = var + nv.variance() * float(np.median(dts)) / tau_dt
        return var + mean, cov * share, walk_model(gv, cov, share, mean)

    def _walk_terms(self) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """The walk's noise levels: the gyro variance (3,) [rad^2/s^2], the momentum
        noise covariance (3, 3) [N^2 m^2 s^2] shared by ``share`` gyro samples, and the
        walk's record-mean variance (3,) [N^2 m^2] (:func:`.momentum.walk_variance`)."""
        share, gv = self._share(), self._gyro_var()
        cov = np.diag(self._h_noise.variance()) if self._h_noise.known() else np.zeros((3, 3))
        return gv, cov, share, walk_variance(self._walk_h, self._walk_w, self._walk_n, gv,
                                             cov, share)

class MomentumRecursiveEstimator(MomentumInput, RecursiveEstimator):
    """:class:`~.recursive.RecursiveEstimator` with internal momentum (wheels, rotors) input.

    Parameters
    ----------
    names : sequence of str
        The uncertain inputs whose one-sigma changes every :meth:`add_momentum` block gives
        (e.g. ``inertia:rw1``, ``k_f:m1``); empty: none.
    other_torque : bool
        True: another known torque arrives through :meth:`add_torque` and the equations wait
        for it; False: the momentum input is the only known torque.
    hold : {'zoh', 'linear', 'auto'}
        Hold of the other torque between its samples (``torque_hold``).  The equivalent
        torque fed to the :class:`~.recursive.RecursiveEstimator` is always held over its
        grid intervals: the other torque's hold is applied once, when it is reduced.
        ``auto``: both reductions (the other torque held, and linear) on the same rows, as
        the base estimator's two accumulators (:mod:`.online_hold`, the second as
        ``OnlineAligner.tau_alt``), chosen by the batch rule (:func:`.selection.select_hold`)
        in ``diagnostics['hold_selection']``; without another torque nothing is held (the
        momentum is known at its samples), so there is nothing to choose.
    **kwargs
        The other options of :class:`~.recursive.RecursiveEstimator`.  ``torque_scale_std``
        scales the other torque only, never the momentum: it is one more stated input
        (``torque_scale``); ``gyro_scale_std`` too (``gyro_scale``: the rate in both sides).
    """

    def __init__(self, names: Sequence[str] = (), other_torque: bool = True,
                 hold: str = 'zoh', **kwargs: Any) -> None:
        kwargs = self._options('recursive', names, other_torque, hold, kwargs)
        # the equivalent torque is held over each grid interval: integrated as held, whatever
        # the other torque's hold (which _other_on has applied already); 'auto' keeps both
        self._kwargs = dict(kwargs, hold='auto' if self.torque_hold == 'auto' else HOLDS[0])
        super().__init__(**self._kwargs)

    def reset(self) -> None:
        """Forget everything (also the stated inputs' posterior)."""
        super().reset()
        if self._stated is not None:
            self._align = OnlineAligner(3 * len(self._stated.names))
            for acc in self._accs.values():
                acc.widen(13 + 3 * len(self._stated.names))
        # the walk per grid interval, as the batch's (:mod:`.online_walk`)
        self._features = FeatureStore()
        for acc in self._accs.values():
            acc.track_walk(self._features.lookup)

    def _walk_intervals(self, grid: np.ndarray, hg: np.ndarray, wg: np.ndarray) -> None:
        """Keep the grid intervals' walk weights (:func:`.online_walk.interval_features`)
        for the accumulators' lookups."""
        ts = self._align.ts
        self._features.add(grid, hg, wg, float(ts[0]) if len(ts) else None)

    def _take(self, grid: np.ndarray, tau: np.ndarray, alt: np.ndarray | None,
              x: np.ndarray | None, t_in: np.ndarray, w_in: np.ndarray) -> None:
        """One reduced run: the equivalent torque (G - 1, 3) held from ``grid[:-1]``, its
        linear-hold twin ``alt`` (hold 'auto'), the stated columns ``x`` and the gyro."""
        self._pt.append(grid[:-1])         # the stated columns held alike, after the torque
        self._ptau.append(tau if x is None else np.hstack([tau, x]))
        self._last_tau_in, self._new_torque = float(grid[-2]), True
        if alt is not None:             # hold 'auto': the other torque linear too
            self._palt.append(alt)
        if len(t_in):
            RecursiveEstimator.add_gyro(self, t_in, w_in)

    def _torque_variance(self) -> np.ndarray | None:
        """The equivalent torque's white-noise variance (3,) [N^2 m^2], as the batch's."""
        if self._walk_n == 0 or self._align.tau_dt <= 0:
            return None
        var, self._white_y_cov, model = self._reduced_noise(self._align.tau_dt)
        for acc in self._accs.values():
            acc.walk_model = model
        return var

    def estimate(self) -> InertiaEstimate:
        """The current estimate (see :meth:`.RecursiveEstimator.estimate`), with the momentum
        input's record in ``diagnostics['momentum']`` and its stated inputs profiled
        (:mod:`.online_stated`)."""
        if self._stated is not None:
            self._stated.update(self)
        est = super().estimate()
        diag = est.diagnostics
        self._record(diag)
        if est.status == 'insufficient_data' and self.other_torque and len(self._o.t) == 0:
            diag['reason'] = ('no other torque sample yet: the momentum input waits for it '
                              '(build with other_torque=False when there is none)')
        if self._stated is not None:
            est = self._stated.widen(self, est)
        return est


class MomentumTrackingEstimator(MomentumInput, TrackingEstimator):
    """:class:`~.tracking.TrackingEstimator` with internal momentum (wheels, rotors) input.

    The momentum input is reduced as for :class:`MomentumRecursiveEstimator` (the one road,
    :class:`MomentumInput`): its equivalent torque, held over the grid intervals, is the
    filter's torque stream, and its noise the filter's: the momentum samples' own white noise
    in every equation (added to ``R``; the filter's momentum is the body's less the anchor
    sample's momentum error, so the errors do not walk) and the equivalent torque's white
    noise in the momentum's walk, each block's from its grid intervals' ``n x h`` and ``w x
    e`` walks as the batch weights them (:meth:`_block_walk`).  The stated inputs
    (``names``; ``torque_scale`` of the other torque; ``gyro_scale``) are filter states with
    the prior N(0, 1) [stated sigmas], never forgotten: their one-sigma changes of the
    impulse are columns of the equations (the gyro scale's linearised at the current tensor,
    as :mod:`.online_stated`'s), so the covariance carries them, whole
    (``diagnostics['input_uncertainty']``).

    Parameters
    ----------
    names, other_torque, hold
        As :class:`MomentumRecursiveEstimator`'s (``hold='auto'``: a twin filter under the
        linear hold of the other torque and a :class:`MomentumRecursiveEstimator` judge).
    **kwargs
        The other options of :class:`~.tracking.TrackingEstimator`.
    """

    def __init__(self, names: Sequence[str] = (), other_torque: bool = True,
                 hold: str = 'zoh', **kwargs: Any) -> None:
        self._kind = 'wheels_torque' if other_torque else 'wheels'
        self._mconfig = dict(kwargs, names=names, other_torque=other_torque)
        kwargs = self._options('tracking', names, other_torque, hold, kwargs)
        self.nu = len(StatedInputs(names, self.torque_scale_std, self.gyro_scale_std).names)
        self._learnt = self._nl = int(self.gyro_scale_std > 0)     # the gyro scale learnt
        # the equivalent torque is held over the grid intervals ('auto': the other torque's)
        super().__init__(**kwargs, hold='auto' if self.torque_hold == 'auto' else 'zoh')
        self._substituted = substitutions('tracking', self._kind, self._opts)

    def _hold_choice(self) -> HoldChoice:
        """Hold 'auto': the twin under the other torque's linear hold; the judge reduces it
        both ways (:class:`MomentumRecursiveEstimator`, ``hold='auto'``)."""
        judge = MomentumRecursiveEstimator(
            names=self._mconfig['names'], other_torque=True, hold='auto',
            gyro_noise=self._config['gyro_noise'],
            torque_bias='on' if self.torque_bias == 'on' else 'off')
        return HoldChoice(MomentumTrackingEstimator(**self._mconfig, hold='linear'),
                          self.torque_bias, self._config['gyro_noise'], judge)

    def reset(self) -> None:
        """Forget everything (also the grid intervals' walk weights)."""
        super().reset()
        self._features = FeatureStore()
        self._walk_levels: tuple[np.ndarray, np.ndarray] | None = None
        self._walk_bases: tuple[float, np.ndarray | None] = (math.nan, None)  # (at, bases)

    def _walk_intervals(self, grid: np.ndarray, hg: np.ndarray, wg: np.ndarray) -> None:
        """Keep the grid intervals' walk weights (:func:`.online_walk.interval_features`)
        for the blocks' walk (:meth:`_block_walk`), from the first anchor still to come."""
        warm = self._warm
        keep = (self._prev[0] if self._prev is not None else None) if warm is None else (
            float(warm[0][0][0]) if warm else None)
        self._features.add(grid, hg, wg, keep)

    def _block_walk(self, start: float, end: float) -> np.ndarray:
        """The block's momentum variance rate (3, 3) [N^2 m^2 s]: the stationary one with the
        momentum input's record-mean walk (in the torque noise variance) replaced by the walk
        of the block's grid intervals, as the batch and the recursive estimator weight it
        (:func:`.online_walk.walk_deviation`: ``n x h`` and ``w x e`` follow ``|h(t)|`` and
        ``|w(t)|``; with the record mean the products' RMS z read 1.2-1.9, issue 27,
        ``scripts/measure/wheels_node_z.py``)."""
        f = self._features.mean(start, end)
        if f is None or self._walk_levels is None or self._tdt <= 0:
            return self._walk_rate
        if self._walk_bases[0] != self._R_at:      # with the weights (:meth:`_cached`)
            I = theta_to_matrix(self.basis @ self.x[:self.k], check_finite=False)
            q = len(self._walk_levels[1])            # the batch's fifteen weights
            self._walk_bases = (self._R_at, walk_bases(q, I, self._nv_R, self._gdt, self._tdt)
                                if np.all(np.isfinite(I)) else None)
        if self._walk_bases[1] is None:
            return self._walk_rate
        W = self._walk_rate + self._tdt * walk_deviation(f, self._walk_levels,
                                                         self._walk_bases[1])
        return psd_part(W)                         # a covariance rate: never negative

    def _take(self, grid: np.ndarray, tau: np.ndarray, alt: np.ndarray | None,
              x: np.ndarray | None, t_in: np.ndarray, w_in: np.ndarray) -> None:
        """One reduced run: the equivalent torque (and the stated columns) held from
        ``grid[:-1]`` into the filter's torque stream, then the gyro samples it covers."""
        self._tq_dts = np.concatenate([self._tq_dts, np.diff(grid)])[-64:]
        self._ts = np.concatenate([self._ts, grid[:-1]])
        self._tau = np.concatenate([self._tau, tau if x is None else np.hstack([tau, x])])
        self._last_tau_in = float(grid[-2])
        if len(t_in):
            StreamInput.add_gyro(self, t_in, w_in)
        else:
            self._process()

    def _gyro_var(self) -> np.ndarray:
        """The gyro white-noise variance (3,) [rad^2/s^2] the filter uses."""
        return self._nv if self._nv is not None else np.zeros(3)

    def _gyro_dt(self) -> float:
        """The nominal gyro interval [s]."""
        return float(np.median(self._g_dts)) if len(self._g_dts) else 0.0

    def _refresh_noise(self) -> None:
        """The filter's noise levels; the torque's is the reduction's (:meth:`_reduced_noise`),
        which also gives each equation's white noise."""
        super()._refresh_noise()
        tdt = float(np.median(self._tq_dts)) if len(self._tq_dts) else 0.0
        if self._noise_at == self.samples_used and self._walk_n and tdt > 0:
            # and the levels the blocks' walk is read at, with the record mean _tv holds
            self._tv, self._white_y_cov, self._walk_levels = self._reduced_noise(tdt)

    def _u_columns(self, w: np.ndarray, m: np.ndarray, S: np.ndarray) -> np.ndarray:
        """The stated inputs' columns (3, nu) of a block's equation: ``-S_j`` (the block
        mean of each input's one-sigma impulse change since the anchor), for the gyro scale
        ``-g (L(w) theta + 2 Q(m) theta - Wc)`` (:mod:`.online_stated`'s, at the estimate)."""
        C = -S.reshape(-1, 3).T
        if self.gyro_scale_std:
            th = self.basis @ self.x[:self.k]
            C[:, -1] = -self.gyro_scale_std * ((momentum_matrix(w) + 2.0 * gyroscopic_matrix(m))
                                               @ th + C[:, -1])
        return C

    def _gyro_column(self, w: np.ndarray, M: np.ndarray, Wc: np.ndarray, theta: np.ndarray
                     ) -> np.ndarray:
        """The gyro scale's column (n, 3) of the start-up equations at ``theta`` (6,), from
        their rates ``w`` (n, 3), monomial integrals ``M`` (n, 6) and ``Wc`` (n, 3)."""
        return -self.gyro_scale_std * ((momentum_matrix(w) + 2.0 * gyroscopic_matrix(M))
                                       @ theta - Wc)

    def _u_propagation(self, m_end: np.ndarray, S_end: np.ndarray) -> np.ndarray:
        """The momentum's change (3, nu) per stated input over a block: ``S_j``, for the
        gyro scale ``g (2 Q(m) theta - Wc)``."""
        F = S_end.reshape(-1, 3).T.copy()
        if self.gyro_scale_std:
            th = self.basis @ self.x[:self.k]
            F[:, -1] = self.gyro_scale_std * (2.0 * gyroscopic_matrix(m_end) @ th - F[:, -1])
        return F

    def estimate(self) -> InertiaEstimate:
        """:meth:`.TrackingEstimator.estimate` with the momentum input's record and the
        stated inputs' posterior (``diagnostics['input_uncertainty']``)."""
        est = super().estimate()
        diag = est.diagnostics
        self._record(diag)
        if self._stated is not None and self._warm is None:
            u = slice(self.k + self.nb, self.n - 3)     # d theta (6,) per stated sigma
            D = self.basis @ self.P[:self.k, u] @ np.linalg.inv(self.P[u, u])
            sd = np.sqrt(np.maximum(np.diag(self.P[u, u]), 0.0))
            # the batch and recursive record's form (:func:`.stated.widened`): the share of
            # the tensor's covariance the considered inputs carry, D P_uu D'
            diag['input_uncertainty'] = diag['wheel_inertia'] = {
                'inputs': {nm: {'theta_change': D[:, j], 'profiled_sigmas': float(self.x[u][j]),
                                'posterior_sigmas': float(sd[j])}
                           for j, nm in enumerate(self._stated.names)},
                'theta_std_added': np.sqrt(np.maximum(np.diag(D @ self.P[u, u] @ D.T), 0.0)),
                'posterior_cov': self.P[u, u].copy(),
                'rule': 'stated inputs as considered filter states under their N(0, stated '
                        "sigma) prior; D P D' is their share of the tensor's covariance"}
            diag['calibration'] = {'torque_scale_std': self.torque_scale_std,
                                   'gyro_scale_std': self.gyro_scale_std,
                                   'gyro_sensitivity': 'a filter state (learnt)'}
        return est
