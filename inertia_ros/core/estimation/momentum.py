"""Wheel and flywheel momentum as an input: the momentum form with internal angular momentum.

A body carrying wheels (reaction wheels, flywheels) that spin at speed ``w_k`` about the unit
axes ``a_k`` (body frame) with spin inertia ``J_k`` holds the internal angular momentum
``h = sum_k J_k w_k a_k`` [N m s] (body axes, relative to the body).  Euler's equation becomes
``tau_ext = d/dt (I w + h) + w x (I w + h)`` with ``I`` the tensor of the whole body, wheels
included.  Integrated from the anchor ``t0`` of a segment,

``I w_b + int w x (I w) dt - I w_0 = int tau_ext dt - (h(t_b) - h(t_0)) - int w x h dt``,

so the wheel momentum only changes the right-hand side ``y`` of the anchored equations:
nothing is differentiated, and ``h(t_0)`` joins the segment intercept.

The wheel input is turned into the exactly equivalent piecewise-constant torque on the union
grid of gyro and wheel stamps (:func:`equivalent_torque`): its zero-order-hold integral at
every grid time equals the right-hand side above (``h`` linear between wheel samples, the
``w x h`` integral by the trapezoid rule on the union grid), so every estimator of
:mod:`.batch` uses it unchanged.  The noise model gains three terms: the wheel-speed noise
enters ``y`` as white noise (``white_y_cov``, estimated from the speeds' high-order
differences, scaled by the gyro samples per wheel sample that share it), and the gyro noise
``n x h`` and the wheel noise ``w x e`` in the ``w x h`` integral as white torque noise
(the anchored model's torque random walk), its covariance per grid interval as ``|h(t)|``
and ``|w(t)|`` make it (:func:`walk_cov`), with the cross term of ``n x h`` and the
gyroscopic walk of the same gyro noise.

The stated uncertainties of the input (each wheel's ``J_k``, each rotor's ``k_f``, ``k_m``,
``J``, the gyro and torque-sensor scales) are profiled under their prior by
:func:`.stated.propagate`: the known impulse's sensitivity to each is fitted with the tensor,
the data are corrected by the posterior mean and re-estimated, and the posterior's effect on
every reported quantity is added to its standard error (``diagnostics['input_uncertainty']``,
also ``diagnostics['wheel_inertia']``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._validate import unit_axis

__all__ = ['Momentum', 'Reduction', 'Wheel', 'as_momentum', 'equivalent_torque',
           'estimate_with_momentum', 'held_over', 'interval_torque', 'nonneg', 'speeds',
           'spin_inputs', 'walk_cov',
           'walk_sums', 'walk_variance', 'wheel_inputs', 'wheel_momentum', 'wheels_momentum']


@dataclass(frozen=True)
class Wheel:
    """One wheel or flywheel.

    Attributes
    ----------
    joint : str
        Joint name (``sensor_msgs/JointState.name``).
    axis : ndarray, shape (3,)
        Unit spin axis in the gyro (body) frame; positive speed spins about ``+axis``.
    inertia : float
        Spin inertia about the axis [kg m^2], > 0.
    inertia_std : float
        One-sigma uncertainty of ``inertia`` [kg m^2], >= 0.
    """

    joint: str
    axis: np.ndarray
    inertia: float
    inertia_std: float = 0.0

    def __post_init__(self) -> None:
        """Validate: a named joint, a finite non-zero axis (normalised), J > 0, std >= 0."""
        if not isinstance(self.joint, str) or not self.joint:
            raise ValueError(f'joint: must be a non-empty name, got {self.joint!r}')
        object.__setattr__(self, 'axis', unit_axis(self.axis, f'wheel {self.joint}'))
        for name in ('inertia', 'inertia_std'):
            object.__setattr__(self, name, nonneg(f'wheel {self.joint}', name, getattr(
                self, name), name == 'inertia', ' kg m^2'))


def nonneg(owner: str, name: str, value: Any, positive: bool = False, unit: str = '') -> float:
    """``value`` as a finite float >= 0 (> 0 with ``positive``), or a one-line ValueError
    naming ``owner`` (a wheel, a rotor), the field ``name`` and its ``unit``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{owner}: {name} must be a number, got {value!r}') from None
    if not np.isfinite(v) or v < 0 or (positive and v == 0):
        raise ValueError(f'{owner}: {name} must be {"> 0" if positive else ">= 0"}{unit}, got '
                         f'{value!r}')
    return v


@dataclass(frozen=True)
class Momentum:
    """Sampled internal angular momentum with its input uncertainties.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Strictly increasing sample times [s] (the gyro's clock).
    h : ndarray, shape (K, 3)
        Internal angular momentum in body axes [N m s].
    h_std : ndarray, shape (P, K, 3)
        One-sigma changes of ``h`` from ``P`` independent uncertain inputs (e.g. each wheel's
        inertia), [N m s]; ``P = 0`` when there are none.
    names : tuple of str
        Name of each uncertain input (length P).
    noise_cov : ndarray, shape (3, 3), optional
        Covariance of the white measurement noise of ``h`` [N^2 m^2 s^2]; estimated from the
        samples (high-order differences) when None.
    torque : ndarray, shape (K, 3), optional
        A known torque on the same stamps [N m] (e.g. rotor thrust and drag torques), linear
        between its samples; None: none.
    torque_std : ndarray, shape (P, K, 3), optional
        One-sigma changes of ``torque`` from the same ``P`` uncertain inputs [N m] (None:
        zeros).
    """

    t: np.ndarray
    h: np.ndarray
    h_std: np.ndarray
    names: tuple[str, ...] = ()
    noise_cov: np.ndarray | None = None
    torque: np.ndarray | None = None
    torque_std: np.ndarray | None = None


def speeds(speed: Any, n: int) -> np.ndarray:
    """``speed`` as a float array (K, n) [rad/s], or a one-line ValueError."""
    s = np.asarray(speed, dtype=float)
    if s.ndim != 2 or s.shape[1] != n:
        raise ValueError(f'speed: expected shape (K, {n}), got {s.shape}')
    return s


def wheel_momentum(wheels: list[Wheel], speed: Any) -> np.ndarray:
    """Internal momentum ``h = sum_k J_k w_k a_k`` (K, 3) [N m s] of the wheels (body axes)
    at the speeds (K, n_wheels) [rad/s] relative to the body, columns in ``wheels`` order."""
    return speeds(speed, len(wheels)) @ _wheel_rows(wheels)


def _wheel_rows(wheels: list[Wheel]) -> np.ndarray:
    """``J_k a_k`` (n, 3) [kg m^2]: each wheel's momentum per unit speed."""
    return np.array([wh.inertia * wh.axis for wh in wheels]).reshape(len(wheels), 3)


def spin_inputs(t: Any, s: np.ndarray, h_rows: np.ndarray, tq_rows: np.ndarray | None,
                stated: list[tuple[str, int, Any, Any]]) -> Momentum:
    """The momentum input of spinning parts (wheels, rotors: unvalidated, any K >= 1;
    ``noise_cov`` None).

    Parameters
    ----------
    t : array_like, shape (K,)
        Sample times [s].
    s : ndarray, shape (K, n)
        Speeds [rad/s] (rotors: magnitudes, after any motor lag).
    h_rows : ndarray, shape (n, 3)
        Momentum per unit speed of each part [N m s / (rad/s)]: ``h = s @ h_rows``.
    tq_rows : ndarray, shape (n, 3), optional
        Torque per unit squared speed [N m / (rad/s)^2]: ``torque = s^2 @ tq_rows`` (None:
        no torque).
    stated : list of (name, k, dh (3,) or None, dtq (3,) or None)
        One stated input each: the one-sigma changes ``s_k dh`` of ``h`` and ``s_k^2 dtq``
        of the torque.
    """
    z = np.zeros(3)
    empty = np.zeros((0, len(s), 3))
    dh = [np.outer(s[:, k], z if a is None else a) for _, k, a, _ in stated]
    dt = [np.outer(s[:, k] ** 2, z if b is None else b) for _, k, _, b in stated]
    return Momentum(np.asarray(t, dtype=float).reshape(-1), s @ h_rows,
                    np.array(dh) if dh else empty, tuple(n for n, *_ in stated), None,
                    None if tq_rows is None else (s * s) @ tq_rows,
                    None if tq_rows is None else (np.array(dt) if dt else empty))


def wheel_inputs(t: Any, speed: Any, wheels: list[Wheel]) -> Momentum:
    """The momentum input of a block of wheel speeds (:func:`spin_inputs`; the online
    estimator's form): ``h`` with one stated input per wheel whose ``inertia_std`` is
    positive (named ``inertia:<joint>``).

    Parameters
    ----------
    t : array_like, shape (K,)
        Sample times [s].
    speed : array_like, shape (K, n_wheels)
        Wheel speeds [rad/s], columns in the order of ``wheels``.
    wheels : list of Wheel
    """
    return spin_inputs(t, speeds(speed, len(wheels)), _wheel_rows(wheels), None,
                       [(f'inertia:{wh.joint}', k, wh.inertia_std * wh.axis, None)
                        for k, wh in enumerate(wheels) if wh.inertia_std > 0])


def wheels_momentum(t: Any, speed: Any, wheels: list[Wheel]) -> Momentum:
    """:class:`Momentum` of sampled wheel speeds (:func:`wheel_inputs`, the same
    parameters), validated, with the noise covariance of ``h`` from the speeds' white noise
    (high-order differences per wheel)."""
    from .noise import noise_std_from_differences

    m = wheel_inputs(t, speed, wheels)
    sd = noise_std_from_differences(np.asarray(speed, dtype=float))   # per wheel [rad/s]
    cov = sum(((wh.inertia * sd[k]) ** 2) * np.outer(wh.axis, wh.axis)
              for k, wh in enumerate(wheels))
    return as_momentum(replace(m, noise_cov=np.asarray(cov, dtype=float).reshape(3, 3)))


def as_momentum(momentum: Any) -> Momentum:
    """Validate a :class:`Momentum` or a ``(t (K,), h (K, 3))`` pair.

    Raises
    ------
    ValueError
        Wrong shapes, non-finite values, fewer than 2 samples, times not strictly increasing.
    """
    cov = tq = tq_std = None
    if isinstance(momentum, Momentum):
        t, h, h_std, names = momentum.t, momentum.h, momentum.h_std, momentum.names
        cov, tq, tq_std = momentum.noise_cov, momentum.torque, momentum.torque_std
    else:
        try:
            t, h = momentum
        except (TypeError, ValueError):
            raise ValueError('momentum: expected (t (K,), h (K, 3)) or a Momentum') from None
        h_std, names = None, ()
    t = np.asarray(t, dtype=float).reshape(-1)
    h = np.asarray(h, dtype=float)
    if h.shape != (len(t), 3):
        raise ValueError(f'momentum: h must have shape ({len(t)}, 3) for {len(t)} times, '
                         f'got {h.shape}')
    if len(t) < 2:
        raise ValueError(f'momentum: {len(t)} sample(s); at least 2 are needed')
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(h))):
        raise ValueError('momentum: times and momentum must be finite (NaN/inf found)')
    if np.any(np.diff(t) <= 0):
        raise ValueError('momentum: times must be strictly increasing')
    h_std = np.zeros((0, len(t), 3)) if h_std is None else np.asarray(h_std, dtype=float)
    if h_std.ndim != 3 or h_std.shape[1:] != (len(t), 3) or len(names) != len(h_std):
        raise ValueError(f'momentum: h_std must have shape (P, {len(t)}, 3) with P names')
    if cov is None:
        from .noise import noise_std_from_differences

        cov = np.diag(noise_std_from_differences(h) ** 2)
    cov = np.asarray(cov, dtype=float)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError(f'momentum: noise_cov must be a finite (3, 3) matrix, got {cov.shape}')
    tq, tq_std = _check_torque(tq, tq_std, len(t), len(h_std))
    return Momentum(t, h, h_std, tuple(names), cov, tq, tq_std)


def _check_torque(tq: Any, tq_std: Any, k: int, p: int
                  ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Validate the optional torque (K, 3) of a momentum input and its changes (P, K, 3)."""
    if tq is None:
        if tq_std is not None:
            raise ValueError('momentum: torque_std given without torque')
        return None, None
    tq = np.asarray(tq, dtype=float)
    if tq.shape != (k, 3) or not np.all(np.isfinite(tq)):
        raise ValueError(f'momentum: torque must be finite with shape ({k}, 3), got {tq.shape}')
    tq_std = np.zeros((p, k, 3)) if tq_std is None else np.asarray(tq_std, dtype=float)
    if tq_std.shape != (p, k, 3) or not np.all(np.isfinite(tq_std)):
        raise ValueError(f'momentum: torque_std must be finite with shape ({p}, {k}, 3), got '
                         f'{tq_std.shape}')
    return tq, tq_std


def equivalent_torque(tg: np.ndarray, w: np.ndarray, t_h: np.ndarray, h: np.ndarray,
                      ts: np.ndarray, tau: np.ndarray, hold: str,
                      tq_h: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Piecewise-constant torque whose held integral is ``int tau - dh - int w x h``.

    Parameters
    ----------
    tg, w : ndarray, shape (N,), (N, 3)
        Gyro times [s] and angular velocity [rad/s].
    t_h, h : ndarray, shape (K,), (K, 3)
        Momentum times [s] and internal momentum [N m s].
    ts, tau : ndarray, shape (M,), (M, 3)
        Other known torque (M = 0: none) [s], [N m].
    hold : {'zoh', 'linear'}
        Hold of ``tau`` between its samples.
    tq_h : ndarray, shape (K, 3), optional
        Known torque on the momentum stamps (linear between them) [N m], added.

    Returns
    -------
    grid : ndarray, shape (G,)
        Union of the gyro and momentum stamps inside the common coverage [s].
    torque : ndarray, shape (G, 3)
        Torque held over ``[grid[i], grid[i+1])`` [N m]: at every grid time its integral from
        ``grid[0]`` equals ``int tau dt - (h - h(grid[0])) - int w x h dt`` (trapezoid on the
        grid for ``w x h``; ``h`` and ``w`` linear between their samples).
    inside : ndarray of bool, shape (N,)
        Gyro samples inside the coverage and outside the momentum gaps.

    Notes
    -----
    A momentum interval over ``GAP_FACTOR`` nominal ones is a gap (:func:`.align.gap_starts`,
    the online estimator's rule): the gyro samples strictly inside it are left out, the grid
    spans it with one interval (a torque gap to the estimators, which start a new anchored
    segment after it) and ``h`` is interpolated within each gap-free run only.
    """
    return Reduction(tg, t_h, ts, hold)(w, h, tau, tq_h)


class Reduction:
    """:func:`equivalent_torque` on fixed stamps ``tg``, ``t_h``, ``ts`` and ``hold`` (as
    there) for many inputs (the stated inputs' re-estimations): the coverage, the grid, the
    interpolation weights and the rates on the grid (for the same ``w`` object) are computed
    once; the same numbers, bit for bit.
    """

    def __init__(self, tg: np.ndarray, t_h: np.ndarray, ts: np.ndarray, hold: str) -> None:
        from .align import gap_starts, hermite_basis, inside_gaps

        lo, hi = max(tg[0], t_h[0]), min(tg[-1], t_h[-1])
        if len(ts):
            lo = max(lo, ts[0])
            end = ts[-1] + (float(np.median(np.diff(ts))) if hold == 'zoh' else 0.0)
            hi = min(hi, end)
        self.tg, self.t_h, self.ts, self.hold = tg, t_h, ts, hold
        self.gaps = gap_starts(t_h)
        self.inside = (tg >= lo) & (tg <= hi) & ~inside_gaps(t_h, self.gaps, tg)
        self.grid = np.union1d(tg[self.inside], t_h[(t_h >= lo) & (t_h <= hi)])
        self.basis = (hermite_basis(t_h, self.grid) if len(t_h) >= 3 and len(self.grid) >= 2
                      else None)
        self._rates: tuple[np.ndarray, np.ndarray] | None = None

    def rates(self, w: np.ndarray) -> np.ndarray:
        """``w`` (N, 3) [rad/s] on the grid (G, 3), linear (kept for the same object)."""
        if self._rates is None or self._rates[0] is not w:
            self._rates = (w, np.column_stack([np.interp(self.grid, self.tg, w[:, c])
                                               for c in range(3)]))
        return self._rates[1]

    def __call__(self, w: np.ndarray, h: np.ndarray, tau: np.ndarray,
                 tq_h: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(grid, torque, inside)`` of :func:`equivalent_torque` for these inputs."""
        grid, t_h = self.grid, self.t_h
        if len(grid) < 2:
            return grid, np.zeros((len(grid), 3)), self.inside
        wg = self.rates(w)
        trg = None if tq_h is None else np.column_stack([np.interp(grid, t_h, tq_h[:, k])
                                                         for k in range(3)])
        out = np.empty((len(grid), 3))
        out[:-1] = interval_torque(grid, wg, _interp_h(t_h, h, grid, self.gaps, self.basis),
                                   trg)
        if len(self.ts):
            out[:-1] += held_over(grid, self.ts, tau, self.hold)
        out[-1] = out[-2]
        return grid, out, self.inside


def interval_torque(grid: np.ndarray, wg: np.ndarray, hg: np.ndarray,
                    trg: np.ndarray | None = None) -> np.ndarray:
    """The momentum input's held torque (G - 1, 3) [N m] over the grid intervals:
    ``-dh/dt - trap(w x h) + trap(tr)``, the batch and online reduction alike.

    Parameters
    ----------
    grid : ndarray, shape (G,)
        Grid times [s].
    wg, hg : ndarray, shape (G, 3)
        Angular velocity [rad/s] and internal momentum [N m s] at the grid times.
    trg : ndarray, shape (G, 3), optional
        The momentum input's own torque at the grid times [N m] (linear between them).
    """
    c = np.cross(wg, hg)
    out = -np.diff(hg, axis=0) / np.diff(grid)[:, None] - 0.5 * (c[1:] + c[:-1])
    if trg is not None:
        out += 0.5 * (trg[1:] + trg[:-1])
    return out


def held_over(grid: np.ndarray, ts: np.ndarray, tau: np.ndarray, hold: str) -> np.ndarray:
    """The other torque (M >= 1 samples ``tau`` (M, 3) [N m] at ``ts`` [s]) over each grid
    interval (G - 1, 3) [N m]: the sample holding at its start (``zoh``) or the trapezoid of
    its linear interpolation (``linear``), the batch and online reduction alike.

    Not the exact interval mean ``diff(cumulative_torque(ts, tau, grid)) / diff(grid)``
    when torque samples fall inside grid intervals (issue 26, rule (b)): that fold moved
    wheels + 37 Hz torque estimates (20 s, gyro 100 Hz) by up to 0.17 sigma and their sigma by
    up to 47 % (``zoh``), beyond rounding; on stamps inside the grid the two agree."""
    if hold == 'linear':
        tq = np.column_stack([np.interp(grid, ts, tau[:, k]) for k in range(3)])
        return 0.5 * (tq[1:] + tq[:-1])
    j = np.clip(np.searchsorted(ts, grid[:-1], side='right') - 1, 0, len(ts) - 1)
    return tau[j]


def _interp_h(t_h: np.ndarray, h: np.ndarray, t: np.ndarray,
              gaps: np.ndarray | None = None, basis: Any = None) -> np.ndarray:
    """``h`` at ``t`` (inside ``t_h``) by cubic Hermite interpolation, slopes by
    ``np.gradient`` within each gap-free run (:func:`.align.run_slopes`; the online rule;
    ``basis``: :func:`.align.hermite_basis` of ``t_h`` and ``t``, when known).

    Linear interpolation would leave an error ``h'' dt^2 / 8`` between wheel samples that is
    coherent over the record (a bias of the tensor at 1e-5 relative for a 100 Hz JointState).
    """
    from .align import gap_starts, hermite, run_slopes

    if len(t_h) < 3:
        return np.column_stack([np.interp(t, t_h, h[:, c]) for c in range(3)])
    gaps = gap_starts(t_h) if gaps is None else gaps
    return hermite(t_h, h, run_slopes(t_h, h, gaps), t, basis)


def _noise_terms(red: Reduction, w: np.ndarray, mom: Momentum, ts: np.ndarray,
                 tau: np.ndarray, options: dict[str, Any]
                 ) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Torque-noise std (3,) [N m] of the equivalent torque on ``red``'s grid, the
    wheel-noise share and the ``w x h`` integral's walk covariance about its mean.

    Sets ``options['white_y_cov']`` (the wheel-speed noise in ``y``).  Returns the other
    torque's noise (scaled to the grid) with the record-mean variance of the white torque
    noises ``n x h`` and ``w x e`` of the ``w x h`` integral added (the stationary walk the
    ``ml`` likelihood and the diagnostics use), how many gyro samples share one wheel sample,
    and the walk's covariance (G, 3, 3) [N^2 m^2] at each grid time (the rates and ``h``
    interpolated there as for the torque) less that diagonal mean: time-varying, as
    ``|h(t)|^2`` and ``|w(t)|^2`` are (:func:`walk_cov`), which the anchored fit adds; and
    the products ``w_i h_c`` (G, 9) (index ``3 i + c``) at the grid times, with which the
    fit adds the cross term of ``n x h`` and the gyroscopic walk ``J(w) n`` (the same gyro
    noise; :func:`.fit.walk_bases`).
    """
    from .batch import _noise_levels
    from .noise import noise_std_from_differences

    tg, grid = red.tg, red.grid
    tn = options.pop('torque_noise', None)
    if tn is None:
        tn = noise_std_from_differences(tau) if len(ts) > 2 else np.zeros(3)
    tn = np.broadcast_to(np.asarray(tn, dtype=float), (3,))
    if len(ts) > 1:
        # white torque noise held over the torque's own interval: the same random walk when
        # held over the (finer) grid intervals needs the std scaled by sqrt(ratio)
        tn = tn * np.sqrt(float(np.median(np.diff(ts))) / float(np.median(np.diff(grid))))
    if mom.torque is not None:      # the momentum input's own torque (rotors): the same rule
        tr = noise_std_from_differences(mom.torque) * np.sqrt(
            float(np.median(np.diff(mom.t))) / float(np.median(np.diff(grid))))
        tn = np.sqrt(tn ** 2 + tr ** 2)
    # a wheel sample's noise is shared by the gyro equations around it (interpolated): for
    # the covariance of the fit that is white noise of about that many times the variance
    share = max(1.0, float(np.median(np.diff(mom.t))) / float(np.median(np.diff(tg))))
    options['white_y_cov'] = mom.noise_cov * share
    # the gyro noise n in the w x h integral is a white torque noise n x h held over each
    # grid interval (the torque-noise random walk of the anchored model); so is the wheel
    # noise e in it, w x e (times the gyro samples sharing one wheel sample)
    g_std = _noise_levels(w[red.inside], tau[:0], options.get('gyro_noise'), None)[0]
    hg = _interp_h(mom.t, mom.h, grid, red.gaps, red.basis)
    wg = red.rates(w)
    cov = walk_cov(hg, wg, g_std ** 2, mom.noise_cov, share)
    mean = np.einsum('nii->i', cov) / len(cov)          # = walk_variance(walk_sums(...))
    wh = (wg[:, :, None] * hg[:, None, :]).reshape(len(hg), 9)
    return np.sqrt(tn ** 2 + mean), share, cov - np.diag(mean), wh


def walk_cov(hg: np.ndarray, wg: np.ndarray, gyro_var: np.ndarray, h_cov: np.ndarray,
             share: float) -> np.ndarray:
    """Covariance (G, 3, 3) [N^2 m^2] of the ``w x h`` integral's white torque noise at
    each grid time: the gyro noise (variance ``gyro_var`` (3,) [rad^2/s^2]) as ``n x h``
    and the momentum noise (covariance ``h_cov`` (3, 3), shared by ``share`` gyro samples)
    as ``w x e``, with ``hg``, ``wg`` (G, 3) the momentum [N m s] and rate [rad/s] there.

    Their record means' diagonal is :func:`walk_variance` (the stationary walk of the torque
    noise std).  Both paths keep them per grid interval (the batch by :func:`interval_walk`,
    the online estimator by :mod:`.online_walk`): a
    record-average variance put the walk's noise where ``|h|`` and ``|w|`` are small as
    much as where they are large, and the products' sigma of the wheels' scene read 1.2-1.5x
    low (issue 27, ``scripts/measure/wheels_z.py``).
    """
    from .align import cross_matrices

    hx = cross_matrices(hg)
    wx = cross_matrices(wg)
    # batched 3 x 3 products (a three-operand einsum: 10x the time)
    return ((hx * np.asarray(gyro_var, dtype=float)) @ hx.transpose(0, 2, 1)
            + share * ((wx @ h_cov) @ wx.transpose(0, 2, 1)))


def interval_walk(grid: np.ndarray, cov: np.ndarray, grid_i: np.ndarray) -> np.ndarray:
    """A walk's figures ``cov`` (G, ...) at the times ``grid`` held over each interval of
    ``grid_i`` (G', ...): the mean of its two ends (linear between the ``grid`` times),
    the last row repeated (the equivalent torque's last sample holds nothing)."""
    flat = cov.reshape(len(grid), -1)
    at = flat if grid_i is grid or np.array_equal(grid_i, grid) else np.column_stack(
        [np.interp(grid_i, grid, flat[:, k]) for k in range(flat.shape[1])])
    out = np.empty_like(at)
    out[:-1] = 0.5 * (at[:-1] + at[1:])
    out[-1] = at[-1]
    return out.reshape((len(grid_i),) + cov.shape[1:])


def walk_sums(hg: np.ndarray, wg: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Grid sums of the momentum input's torque-noise walks (batch and online alike).

    Parameters
    ----------
    hg, wg : ndarray, shape (G, 3)
        Internal momentum [N m s] and angular velocity [rad/s] at the grid times.

    Returns
    -------
    H : ndarray, shape (3, 3)
        ``sum_n [h_n]x_ij^2`` (the gyro noise ``n x h``).
    W : ndarray, shape (3, 3, 3)
        ``sum_n [w_n]x_ij [w_n]x_ik`` (the momentum noise ``w x e``).
    n : int
        Grid points summed.
    """
    from .align import cross_matrices

    hx = cross_matrices(hg)
    wx = cross_matrices(wg)
    return (np.einsum('nij,nij->ij', hx, hx), np.einsum('nij,nik->ijk', wx, wx), len(hg))


def walk_variance(H: np.ndarray, W: np.ndarray, n: int, gyro_var: np.ndarray,
                  h_cov: np.ndarray, share: float) -> np.ndarray:
    """White torque-noise variance (3,) [N^2 m^2] of the ``w x h`` integral's noise from
    :func:`walk_sums`: the gyro noise (variance ``gyro_var`` (3,) [rad^2/s^2]) as ``n x h``
    and the momentum noise (covariance ``h_cov`` (3, 3), shared by ``share`` gyro samples)
    as ``w x e``, each held over a grid interval."""
    return (H @ gyro_var + share * np.einsum('ijk,jk->i', W, h_cov)) / n


#: ``diagnostics['disturbance']`` of a momentum input's estimate under ``inertial_torque='auto'``
_NO_INERTIAL = {'requested': {'inertial_torque': 'auto'}, 'chosen': None,
                'skipped': 'the inertial torque is fitted on a torque input only yet (the '
                           'stated wheel/rotor profile has none)'}


def estimate_with_momentum(t_gyro: Any, omega: Any, t_torque: Any, torque: Any,
                           momentum: Any, **options: Any) -> Any:
    """:func:`.batch.estimate` with internal momentum (see the module docstring).

    Parameters
    ----------
    t_gyro, omega, t_torque, torque
        As :func:`.batch.estimate`; the torque (M may be 0) is the other known torque.
    momentum : Momentum or (t (K,), h (K, 3))
        Internal angular momentum in the gyro frame [N m s] on the gyro's clock.
    **options
        The keyword options of :func:`.batch.estimate`.  ``torque_noise`` is the other
        torque's noise (default: from its samples; 0 when there is none).  The stated
        ``gyro_scale_std`` and ``torque_scale_std`` are stated inputs like the wheel
        inertias (:func:`.stated.propagate`).

    Returns
    -------
    InertiaEstimate
        ``diagnostics['momentum']`` records the input; ``diagnostics['input_uncertainty']``
        (also ``diagnostics['wheel_inertia']``) the stated inputs' profile and propagation.
    """
    from .._validate import as_samples, as_times

    mom = as_momentum(momentum)
    tg = as_times(t_gyro, 't_gyro')
    w = as_samples(omega, len(tg), 'omega', 't_gyro')
    ts = as_times(t_torque, 't_torque')
    tau = as_samples(torque, len(ts), 'torque', 't_torque')
    from .batch import estimate_arrays
    from .config import require
    from .options import HOLDS

    hold = options.pop('hold', HOLDS[0])
    kind = 'wheels_torque' if len(ts) else ('rotors' if mom.torque is not None else 'wheels')
    require('batch', kind, dict(options, hold=hold))      # every option validated once
    skipped = {'disturbance': _NO_INERTIAL} if options.get('inertial_torque') != 'off' else {}
    options['inertial_torque'] = 'off'          # ('auto': no term here; 'on' refused above)
    # the torque sensor's scale error scales the other torque only, never the momentum; the
    # gyro's scales the measured rate in both sides, w x h included: both are stated inputs
    # (:func:`.stated.propagate`), not scales of y
    scale = options.pop('torque_scale_std', 0.0)
    gscale = options.pop('gyro_scale_std', 0.0)
    scale = float(scale) if len(ts) else 0.0
    auto = hold == 'auto' and len(ts) > 0            # the holds of the other torque compared
    hold = HOLDS[0] if hold not in HOLDS else hold   # of the other torque; the result is held
    red = Reduction(tg, mom.t, ts, hold)       # the grid and weights, for the noise too
    grid, tq, inside = red(w, mom.h, tau, mom.torque)
    if int(np.sum(inside)) < 6 or len(grid) < 2:
        raise ValueError(f'momentum: its samples [{mom.t[0]:.6g}, {mom.t[-1]:.6g}] s cover '
                         f'{int(np.sum(inside))} gyro samples of [{tg[0]:.6g}, {tg[-1]:.6g}] s '
                         '(and of the torque, if any); the streams must overlap')
    tn, share, walk, wh = _noise_terms(red, w, mom, ts, tau, options)
    info = {'samples': len(mom.t), 'h_rms': np.sqrt(np.mean(mom.h ** 2, axis=0)),
            'h_noise_std': np.sqrt(np.diag(mom.noise_cov)), 'gyro_per_wheel_sample': share,
            'gyro_samples_outside': int(np.sum(~inside))}

    def run(wi: np.ndarray, grid_i: np.ndarray, tq_i: np.ndarray, **opts: Any) -> Any:
        """The estimate on the inside gyro samples ``wi`` and an equivalent torque."""
        base = estimate_arrays(tg[inside], wi, grid_i, tq_i, hold=HOLDS[0], torque_noise=tn,
                               walk_cov=interval_walk(grid, walk, grid_i),
                               walk_wh=interval_walk(grid, wh, grid_i), **opts)
        diag = dict(base.diagnostics, momentum=info, **skipped)
        return replace(base, samples_dropped=base.samples_dropped + int(np.sum(~inside)),
                       diagnostics=diag)

    from .stated import Stated, propagate, rerun

    stated = bool(len(mom.h_std) or scale or gscale)
    # with stated inputs this estimate only centres their profile: the final one runs on the
    # corrected inputs (:func:`.stated.propagate`), so the ml refinement is left to it
    first = dict(options, method='integral') if stated and \
        options.get('method', 'auto') in ('auto', 'ml') else options
    res = run(w[inside], grid, tq, **first)
    if auto:
        res, hold = _hold_auto(res, run, tg[inside], w[inside], mom, ts, tau, first)
    st = Stated(tg[inside], w[inside], ts, tau, mom, hold, scale, gscale)
    if stated and res.inertia is not None and np.all(np.isfinite(res.inertia)):
        return propagate(res, run, st, options)
    return res if first is options else rerun(res, run, st, np.zeros(len(st.names)), options)


def _hold_auto(held: Any, run: Any, tg: np.ndarray, w: np.ndarray, mom: Momentum,
               ts: np.ndarray, tau: np.ndarray, options: dict[str, Any]) -> tuple[Any, str]:
    """``hold='auto'`` with another torque: the held and the linear other torque compared by
    the batch's rule (:func:`.selection.select_hold`: the higher likelihood, the lower
    residual excess of the two whole-record fits), held when a fit has none.

    ``held`` is the estimate with the held other torque; ``tg``, ``w`` the gyro samples inside
    its coverage.  Returns the chosen estimate (``diagnostics['hold_selection']``) and hold.
    """
    from .selection import select_hold

    grid, tq, inside = equivalent_torque(tg, w, mom.t, mom.h, ts, tau, 'linear', mom.torque)
    opts = dict(options)
    if held.diagnostics.get('segment_s') is not None and 'segment' not in opts:
        opts['segment'] = held.diagnostics['segment_s']       # the same segmentation
    lin = run(w, grid, tq, **opts) if int(np.sum(inside)) >= 6 else None
    results = {'zoh': held, 'linear': lin}
    chosen, record = select_hold(*(None if r is None or r.theta is None else
                                   r.diagnostics.get('residual_excess') for r in results.values()))
    est = results[chosen]
    diag = dict(est.diagnostics, hold=chosen)
    diag['hold_selection'] = {'requested': 'auto', **record, 'chosen': chosen,
                              'compared': 'the other torque held or linear, momentum the same'}
    return replace(est, diagnostics=diag), chosen
