"""An independent reference simulator for honesty checks: fixed-step RK4 with quaternions.

Written apart from :mod:`inertia_ros.core.simulation` and the estimators on purpose: it shares
no code with them (no regressors, no scene schema, no event merging), so a calibration check
against it cannot pass because both sides make the same mistake.  It integrates

    I w_dot + w x (I w) = tau_applied + d(t, q)           (body axes)
    q_dot = 1/2 q (x) [w, 0]                              (q = [x, y, z, w], body -> inertial)

with the classical fourth-order Runge-Kutta scheme at a fixed step ``h`` much smaller than the
sample periods (``h = 1 / (substeps * gcd rate)``), for ``S`` seeds at once (every state is an
``(S, 3)`` array), and samples the sensors on the integration grid:

- gyro: ``(1 + scale) * lowpass(w) + bias + noise``, optionally quantised;
- torque: the applied torque at the torque instants, ``(1 + scale) * tau + noise``, stamped
  ``delay`` later than it acted.

The applied torque is either held between torque samples (``'zoh'``: a command), a smooth
function of time sampled by the torque stream (``'continuous'``; ``'sine'``: one tone per
axis at its own frequency, weighted by ``sine_axes``), or ``'constant'``.  An
unmeasured disturbance ``d`` can be constant in body axes, a slow sinusoid, or constant in the
inertial frame (rotating in body axes).  A payload change switches the tensor at ``t_change``
conserving angular momentum (the payload is attached without impulse).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import gcd

import numpy as np

__all__ = ['TruthCase', 'TruthRecord', 'simulate_truth', 'NOMINAL_INERTIA']

#: The reference body [kg m^2]: distinct moments and products of inertia.
NOMINAL_INERTIA = np.array([[1.00, 0.05, -0.03],
                            [0.05, 1.20, 0.02],
                            [-0.03, 0.02, 0.90]])


@dataclass(frozen=True)
class TruthCase:
    """One scenario for the reference simulator (SI units throughout).

    Attributes
    ----------
    inertia : numpy.ndarray, shape (3, 3)
        True tensor about the centre of mass, body axes [kg m^2].
    duration : float
        Record length [s].
    gyro_rate, torque_rate : float
        Sample rates [Hz] (integers in Hz, so that both fall on the integration grid).
    gyro_noise, torque_noise : float
        White-noise standard deviation per axis [rad/s], [N m].
    torque_kind : {'zoh', 'continuous', 'sine', 'constant'}
        How the applied torque varies (see the module docstring).
    sine_axes : tuple of float
        ``'sine'``: the amplitude share of each axis (``(1, 1, 1)`` all axes, ``(1, 0, 0)`` x).
    sine_freq : float
        ``'sine'``: the x tone's frequency [Hz]; y and z at 1.3 and 1.7 times it (a random
        phase per axis and seed).
    amplitude : float
        Torque amplitude per axis [N m].
    omega0 : tuple of float
        Initial angular velocity [rad/s].
    gyro_bias : tuple of float
        Constant gyro bias [rad/s].
    gyro_scale, torque_scale : float
        Relative scale errors of the sensors (0.01 = reads 1 % high).
    disturbance : tuple of float
        Unmeasured disturbance amplitude per axis [N m].
    disturbance_kind : {'body', 'sine', 'inertial'}
        Constant in body axes, a sinusoid of period ``disturbance_period``, or constant in the
        inertial frame.
    disturbance_period : float
        Period of the ``'sine'`` disturbance [s].
    t_change : float or None
        Time of a payload change [s]: the whole tensor grows by the factor ``1 + change``.
    change : float
        Relative change of the tensor at ``t_change``.
    drift_per_s : float
        Relative drift of the tensor per second (fuel use); 0 for a constant body.
    delay : float
        Torque-stamp delay [s]: a torque sample is stamped this much after it acted.
    gyro_tau : float
        Time constant of a first-order low-pass in the gyro [s] (0: none).
    substeps : int
        Integration steps per base period ``1 / gcd(gyro_rate, torque_rate)``; at least 4 per
        gyro sample are used.
    """

    inertia: np.ndarray = field(default_factory=lambda: NOMINAL_INERTIA.copy())
    duration: float = 60.0
    gyro_rate: int = 200
    torque_rate: int = 50
    gyro_noise: float = 2e-3
    torque_noise: float = 5e-3
    torque_kind: str = 'zoh'
    sine_axes: tuple[float, float, float] = (1.0, 1.0, 1.0)
    sine_freq: float = 0.2
    amplitude: float = 0.2
    omega0: tuple[float, float, float] = (0.1, -0.05, 0.08)
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_scale: float = 0.0
    torque_scale: float = 0.0
    disturbance: tuple[float, float, float] = (0.0, 0.0, 0.0)
    disturbance_kind: str = 'body'
    disturbance_period: float = 30.0
    t_change: float | None = None
    change: float = 0.0
    drift_per_s: float = 0.0
    delay: float = 0.0
    gyro_tau: float = 0.0
    substeps: int = 4

    def with_(self, **kw: object) -> TruthCase:
        """A copy with some fields replaced."""
        return replace(self, **kw)


@dataclass(frozen=True, eq=False)
class TruthRecord:
    """What the sensors recorded for one seed, and the truth.

    Attributes
    ----------
    t_gyro : numpy.ndarray, shape (N,)
        Gyro stamps [s].
    omega : numpy.ndarray, shape (N, 3)
        Measured angular velocity [rad/s].
    t_torque : numpy.ndarray, shape (M,)
        Torque stamps [s].
    torque : numpy.ndarray, shape (M, 3)
        Measured torque [N m].
    inertia : numpy.ndarray, shape (3, 3)
        The true tensor at t = 0 [kg m^2].
    inertia_end : numpy.ndarray, shape (3, 3)
        The true tensor at the end of the record [kg m^2].
    seed : int
        The seed of this record.
    """

    t_gyro: np.ndarray
    omega: np.ndarray
    t_torque: np.ndarray
    torque: np.ndarray
    inertia: np.ndarray
    inertia_end: np.ndarray
    seed: int


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (S, 3) arrays (np.cross costs ~10 us a call)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def _qmul_omega(q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``1/2 q (x) [w, 0]`` for quaternions ``[x, y, z, w]``; q (S, 4), w (S, 3) -> (S, 4)."""
    qv, qw = q[:, :3], q[:, 3:]
    dv = qw * w + _cross(qv, w)
    dw = -np.einsum('si,si->s', qv, w)[:, None]
    return 0.5 * np.concatenate([dv, dw], axis=1)


def _rotate_to_body(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Inertial vector ``v`` (3,) in body axes for attitudes ``q`` (S, 4): ``R(q)^T v``."""
    qv, qw = q[:, :3], q[:, 3:]
    t = 2.0 * _cross(qv, np.broadcast_to(v, qv.shape))
    # R^T v = v - qw t + qv x t  (inverse rotation of the usual v + qw t + qv x t)
    return v - qw * t + _cross(qv, t)


class _Torques:
    """Applied torque profiles for S seeds: a multisine per axis with random phases."""

    def __init__(self, case: TruthCase, rng: np.random.Generator, S: int) -> None:
        self.case = case
        k = np.arange(1, 6)                                  # 5 tones per axis
        self.freqs = 0.05 * k[None, :] * np.array([1.0, 1.3, 1.7])[:, None]   # (3, 5) Hz
        self.phase = rng.uniform(0, 2 * np.pi, size=(S, 3, 5))
        self.const = rng.uniform(0.5, 1.0, size=(S, 3)) * rng.choice([-1.0, 1.0], (S, 3))

    def at(self, t: float) -> np.ndarray:
        """The smooth profile at time ``t`` [s] -> (S, 3) [N m]."""
        c = self.case
        if c.torque_kind == 'constant':
            return c.amplitude * self.const
        if c.torque_kind == 'sine':
            f = c.sine_freq * np.array([1.0, 1.3, 1.7])
            ph = self.phase[:, :, 0]
            return c.amplitude * np.asarray(c.sine_axes) * np.sin(2 * np.pi * f * t + ph)
        arg = 2 * np.pi * self.freqs[None] * t + self.phase
        return c.amplitude * np.sin(arg).sum(axis=2) / np.sqrt(5.0 / 2.0)   # RMS = amplitude


def _inertia_at(case: TruthCase, t: float) -> np.ndarray:
    """True tensor at time ``t`` [s]: ``I0 * (1 + drift * t + change [t >= t_change])``."""
    f = 1.0 + case.drift_per_s * t
    if case.t_change is not None and t >= case.t_change:
        f += case.change
    return case.inertia * f


def _disturbance(case: TruthCase, t: float, q: np.ndarray) -> np.ndarray | float:
    d = np.asarray(case.disturbance, dtype=float)
    if not d.any():
        return 0.0
    if case.disturbance_kind == 'inertial':
        return _rotate_to_body(q, d)
    if case.disturbance_kind == 'sine':
        return np.broadcast_to(d * np.sin(2 * np.pi * t / case.disturbance_period), (len(q), 3))
    return np.broadcast_to(d, (len(q), 3))


def _grid(case: TruthCase) -> tuple[float, int, int, int]:
    """Integration step [s], step count, and the steps between gyro and torque samples."""
    base = gcd(int(case.gyro_rate), int(case.torque_rate))
    steps_per_base = max(case.substeps, 4 * int(case.gyro_rate) // base)
    h = 1.0 / (base * steps_per_base)
    return (h, int(round(case.duration / h)), int(round(1.0 / (case.gyro_rate * h))),
            int(round(1.0 / (case.torque_rate * h))))


def _integrate(case: TruthCase, torques: _Torques, S: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """RK4 of Euler's equations (and the attitude when a disturbance needs it) for S records.

    Returns
    -------
    t_gyro : numpy.ndarray, shape (N,)
    omega : numpy.ndarray, shape (S, N, 3)
        Noise-free gyro samples (low-passed when ``case.gyro_tau > 0``) [rad/s].
    t_torque : numpy.ndarray, shape (M,)
    torque : numpy.ndarray, shape (S, M, 3)
        Held (commanded) torque samples [N m].
    """
    h, n, g_every, t_every = _grid(case)
    w = np.tile(np.asarray(case.omega0, dtype=float), (S, 1))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (S, 1))
    wf = w.copy()                                       # low-passed gyro state
    I = _inertia_at(case, 0.0)
    held = torques.at(0.0)
    tg, wg, tt, tq = [], [], [], []
    # the attitude only matters to a disturbance fixed in the inertial frame
    need_q = case.disturbance_kind == 'inertial' and any(case.disturbance)

    def deriv(tk: float, wk: np.ndarray, qk: np.ndarray, tau: np.ndarray,
              Ik: np.ndarray, Iinv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Lk = wk @ Ik.T
        wd = (tau + _disturbance(case, tk, qk) - _cross(wk, Lk)) @ Iinv.T
        return wd, (_qmul_omega(qk, wk) if need_q else qk)

    for k in range(n + 1):
        t = k * h
        Ik = _inertia_at(case, t)
        if not np.array_equal(Ik, I):
            if case.t_change is not None and abs(t - case.t_change) < h:
                w = (w @ I.T) @ np.linalg.inv(Ik).T      # L conserved at the payload step
            I = Ik
        if k % t_every == 0:
            held = torques.at(t)
            tt.append(t)
            tq.append(held.copy())
        if k % g_every == 0:
            tg.append(t)
            wg.append(wf.copy() if case.gyro_tau > 0 else w.copy())
        if k == n:
            break
        Iinv = np.linalg.inv(I)
        if case.torque_kind in ('continuous', 'sine'):
            tau1, tau2, tau4 = torques.at(t), torques.at(t + h / 2), torques.at(t + h)
        else:
            tau1 = tau2 = tau4 = held
        k1w, k1q = deriv(t, w, q, tau1, I, Iinv)
        k2w, k2q = deriv(t + h / 2, w + h / 2 * k1w, q + h / 2 * k1q, tau2, I, Iinv)
        k3w, k3q = deriv(t + h / 2, w + h / 2 * k2w, q + h / 2 * k2q, tau2, I, Iinv)
        k4w, k4q = deriv(t + h, w + h * k3w, q + h * k3q, tau4, I, Iinv)
        w_new = w + h / 6 * (k1w + 2 * k2w + 2 * k3w + k4w)
        if need_q:
            q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            q /= np.linalg.norm(q, axis=1, keepdims=True)
        if case.gyro_tau > 0:                           # exact first-order hold update
            a = np.exp(-h / case.gyro_tau)
            wf = a * wf + (1 - a) * 0.5 * (w + w_new)
        w = w_new
    return np.asarray(tg), np.stack(wg, axis=1), np.asarray(tt), np.stack(tq, axis=1)


def simulate_truth(case: TruthCase, seeds: list[int] | range) -> list[TruthRecord]:
    """Simulate ``case`` for every seed at once; one record per seed.

    Parameters
    ----------
    case : TruthCase
        The scenario.
    seeds : sequence of int
        Seeds; seed ``s`` draws the torque phases and the noise of record ``s`` from
        ``numpy.random.default_rng(s)`` (a record does not depend on the other seeds).

    Returns
    -------
    list of TruthRecord
        One per seed, in order.
    """
    seeds = list(seeds)
    rngs = [np.random.default_rng(s) for s in seeds]
    prof = [_Torques(case, r, 1) for r in rngs]
    torques = _Torques(case, np.random.default_rng(0), len(seeds))
    torques.phase = np.concatenate([p.phase for p in prof])
    torques.const = np.concatenate([p.const for p in prof])
    tg_a, W, tt_a, T = _integrate(case, torques, len(seeds))
    out = []
    for i, (s, rng) in enumerate(zip(seeds, rngs, strict=True)):
        om = ((1 + case.gyro_scale) * W[i] + np.asarray(case.gyro_bias)
              + rng.normal(0.0, case.gyro_noise, W[i].shape))
        tau = (1 + case.torque_scale) * T[i] + rng.normal(0.0, case.torque_noise, T[i].shape)
        out.append(TruthRecord(t_gyro=tg_a.copy(), omega=om, t_torque=tt_a + case.delay,
                               torque=tau, inertia=_inertia_at(case, 0.0),
                               inertia_end=_inertia_at(case, case.duration), seed=s))
    return out
