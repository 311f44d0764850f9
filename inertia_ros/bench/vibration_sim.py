"""Realistic records with gyro imperfections the estimators' model does not contain.

Independent of :mod:`inertia_ros.core.simulation` and the estimators (no shared code): the
rigid body is integrated with :func:`scipy.integrate.solve_ivp` (DOP853, tight tolerances)
and the sensors are made the way real ones behave on a body with a spinning part:

- a vibration line at the wheel's (or a motor's) rotation frequency from its imbalance, a
  rotating vector across the spin axis, and its second harmonic;
- a structural resonance (a lightly damped second-order mode driven by white noise);
- a band-limited gyro (a second-order Butterworth low-pass of the true rate, as a MEMS
  gyro's internal filter), coloured noise (first-order Gauss-Markov) plus white noise.

Two scenarios:

:func:`wheel_throw`
    A short (0.5-3 s) torque-free throw of a body carrying a flywheel whose speed a motor
    varies (known from a JointState-like speed stream): the wheel momentum is the only input.
:func:`torque_record`
    A body driven by a known held torque command, with a vibration line from a motor running
    at a known speed and its harmonic.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ['VibrationRecord', 'THROW_INERTIA', 'torque_record', 'wheel_throw']

#: True tensor of the thrown body, wheel included [kg m^2].
THROW_INERTIA = np.array([[0.0210, 0.0008, -0.0005],
                          [0.0008, 0.0265, 0.0004],
                          [-0.0005, 0.0004, 0.0320]])


@dataclass(frozen=True)
class VibrationRecord:
    """One simulated record (times in seconds from 0, body axes).

    Attributes
    ----------
    inertia : ndarray, shape (3, 3)
        True tensor [kg m^2].
    t_gyro, omega : ndarray, shape (N,), (N, 3)
        Gyro stamps [s] and readings [rad/s] (with every imperfection).
    t_torque, torque : ndarray, shape (M,), (M, 3)
        Known torque samples [N m] (M = 0 for the throw).
    t_speed, speed : ndarray, shape (K,), (K, 1)
        Wheel (motor) speed samples [rad/s], with their own noise.
    wheel_axis : ndarray, shape (3,)
        Unit spin axis of the wheel [-] (body axes).
    wheel_inertia : float
        Spin inertia of the wheel [kg m^2] (0 for the torque record's motor: no momentum).
    line_hz : float
        Lowest rotation frequency of the spinning part over the record [Hz].
    """

    inertia: np.ndarray
    t_gyro: np.ndarray
    omega: np.ndarray
    t_torque: np.ndarray
    torque: np.ndarray
    t_speed: np.ndarray
    speed: np.ndarray
    wheel_axis: np.ndarray
    wheel_inertia: float
    line_hz: float


def _speed_profile(rng: np.random.Generator, s0: float, depth: float):
    """A smooth wheel-speed command ``s(t)`` and its derivative [rad/s], [rad/s^2]."""
    f = rng.uniform(1.2, 3.0, 2)
    p = rng.uniform(0, 2 * np.pi, 2)
    a = depth * np.array([0.6, 0.4])

    def s(t):
        return s0 * (1 + a[0] * np.sin(2 * np.pi * f[0] * t + p[0])
                     + a[1] * np.sin(2 * np.pi * f[1] * t + p[1]))

    def sdot(t):
        return s0 * 2 * np.pi * (a[0] * f[0] * np.cos(2 * np.pi * f[0] * t + p[0])
                                 + a[1] * f[1] * np.cos(2 * np.pi * f[1] * t + p[1]))

    return s, sdot


def _integrate(I: np.ndarray, w0: np.ndarray, t: np.ndarray, torque, h, hdot,
               breaks: np.ndarray | None = None) -> np.ndarray:
    """Body rate at ``t`` from ``d/dt (I w + h) + w x (I w + h) = torque``, integrated
    piecewise between ``breaks`` (where the torque jumps) so that every piece is smooth."""
    from scipy.integrate import solve_ivp

    Iinv = np.linalg.inv(I)
    edges = np.unique(np.r_[t[0], [] if breaks is None else breaks, t[-1]])
    edges = edges[(edges >= t[0]) & (edges <= t[-1])]
    out = np.empty((len(t), 3))
    w = np.asarray(w0, dtype=float)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        tq = torque(0.5 * (a + b))       # held over the piece

        def rhs(tt, ww, tq=tq):
            hh = h(tt)
            return Iinv @ (tq - hdot(tt) - np.cross(ww, I @ ww + hh))

        sel = np.flatnonzero((t >= a) & (t <= b))
        sol = solve_ivp(rhs, (a, b), w, method='DOP853', t_eval=t[sel], rtol=1e-11,
                        atol=1e-12, dense_output=True)
        out[sel] = sol.y.T
        w = sol.sol(b)
    return out


def _sensor(rng: np.random.Generator, t: np.ndarray, w: np.ndarray, phase: np.ndarray,
            axis: np.ndarray, *, line: float, harmonic: float, mode_hz: float,
            mode_std: float, band_hz: float, white: float, colored: float) -> np.ndarray:
    """The gyro: true rate + imbalance lines + structural mode, band-limited, plus noise."""
    from scipy import signal

    dt = float(t[1] - t[0])
    u = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    vib = (line * (np.cos(phase)[:, None] * u + np.sin(phase)[:, None] * v)
           + harmonic * (np.cos(2 * phase + 0.7)[:, None] * u
                         + np.sin(2 * phase + 0.7)[:, None] * v))
    # a lightly damped structural mode (Q = 8) driven by white noise
    wn = 2 * np.pi * mode_hz
    b, a = signal.cont2discrete(([wn ** 2], [1.0, wn / 8.0, wn ** 2]), dt, method='bilinear')[:2]
    drive = rng.standard_normal((len(t), 3))
    mode = signal.lfilter(np.ravel(b), a, drive, axis=0)
    mode *= mode_std / max(float(np.std(mode)), 1e-300)
    bb, aa = signal.butter(2, band_hz, fs=1.0 / dt)
    x = w + vib + mode
    zi = signal.lfilter_zi(bb, aa)[:, None] * x[0][None]
    seen = signal.lfilter(bb, aa, x, axis=0, zi=zi)[0]
    rho = np.exp(-dt / 0.01)                              # 10 ms Gauss-Markov noise
    gm = signal.lfilter([np.sqrt(1 - rho ** 2)], [1, -rho], rng.standard_normal((len(t), 3)),
                        axis=0) * colored
    return seen + gm + white * rng.standard_normal((len(t), 3))


def wheel_throw(seed: int, *, duration: float = 1.5, gyro_rate: float = 1000.0,
                speed_rate: float = 200.0, wheel_hz: float = 45.0,
                line: float = 0.08, harmonic: float = 0.03, clean: bool = False
                ) -> VibrationRecord:
    """A torque-free throw of a body with a speed-varied flywheel (see the module docstring).

    Parameters
    ----------
    seed : int
        Random seed (initial rate, speed profile, noise).
    duration : float
        Record length [s] (0.5-3 s as a hand throw).
    gyro_rate, speed_rate : float
        Sample rates of the gyro and the wheel-speed stream [Hz].
    wheel_hz : float
        Mean wheel rotation frequency [Hz].
    line, harmonic : float
        Amplitude of the imbalance line and its second harmonic in the gyro [rad/s].
    clean : bool
        A model-conforming gyro instead: the true rate plus white noise only.
    """
    rng = np.random.default_rng(seed)
    I = THROW_INERTIA
    axis = np.array([0.15, -0.1, 1.0])
    axis /= np.linalg.norm(axis)
    J = 4.0e-4
    s, sdot = _speed_profile(rng, 2 * np.pi * wheel_hz, 0.3)
    fine = np.arange(0.0, duration + 1e-12, 1.0 / 10_000.0)
    w0 = rng.normal(0.0, 4.0, 3)
    w = _integrate(I, w0, fine, lambda tt: np.zeros(3), lambda tt: J * s(tt) * axis,
                   lambda tt: J * sdot(tt) * axis, np.arange(0.0, duration, 0.25))
    step = int(round(10_000.0 / gyro_rate))
    tg = fine[::step]
    phase = np.cumsum(s(fine)) / 10_000.0
    omega = (w[::step] + 0.004 * rng.standard_normal((len(tg), 3)) if clean else
             _sensor(rng, tg, w[::step], phase[::step], axis, line=line, harmonic=harmonic,
                     mode_hz=160.0, mode_std=0.02, band_hz=250.0, white=0.004,
                     colored=0.002))
    tsp = np.arange(0.0, duration + 1e-12, 1.0 / speed_rate)
    speed = (s(tsp) + rng.normal(0.0, 0.5, len(tsp)))[:, None]
    return VibrationRecord(I, tg, omega, np.zeros(0), np.zeros((0, 3)), tsp, speed, axis, J,
                           float(np.min(s(fine))) / (2 * np.pi))


def torque_record(seed: int, *, duration: float = 3.0, gyro_rate: float = 500.0,
                  torque_rate: float = 100.0, motor_hz: float = 35.0,
                  line: float = 0.05, harmonic: float = 0.02, clean: bool = False
                  ) -> VibrationRecord:
    """A body driven by a known held torque command, with a motor's vibration line.

    Parameters
    ----------
    seed : int
        Random seed.
    duration : float
        Record length [s].
    gyro_rate, torque_rate : float
        Sample rates [Hz]; the torque command is held between its samples.
    motor_hz : float
        Rotation frequency of the motor whose imbalance the gyro sees [Hz].
    line, harmonic : float
        Line amplitudes [rad/s].
    clean : bool
        A model-conforming gyro instead: the true rate plus white noise only.
    """
    rng = np.random.default_rng(seed)
    I = np.diag([0.8, 1.0, 1.3]) + np.array([[0, 0.03, -0.02], [0.03, 0, 0.01],
                                             [-0.02, 0.01, 0]])
    ts = np.arange(0.0, duration - 1e-9, 1.0 / torque_rate)
    f = rng.uniform(0.3, 1.5, (3, 2))
    p = rng.uniform(0, 2 * np.pi, (3, 2))
    tau = 0.6 * np.sum(np.sin(2 * np.pi * f[None] * ts[:, None, None] + p[None]), axis=2)

    def torque(tt):
        k = min(int(np.floor(tt * torque_rate + 1e-9)), len(ts) - 1)
        return tau[k]

    fine = np.arange(0.0, duration + 1e-12, 1.0 / 10_000.0)
    w0 = rng.normal(0.0, 1.0, 3)
    w = _integrate(I, w0, fine, torque, lambda tt: np.zeros(3), lambda tt: np.zeros(3), ts)
    step = int(round(10_000.0 / gyro_rate))
    tg = fine[::step]
    axis = np.array([0.0, 0.0, 1.0])
    phase = 2 * np.pi * motor_hz * fine
    omega = (w[::step] + 0.003 * rng.standard_normal((len(tg), 3)) if clean else
             _sensor(rng, tg, w[::step], phase[::step], axis, line=line, harmonic=harmonic,
                     mode_hz=110.0, mode_std=0.01, band_hz=150.0, white=0.003,
                     colored=0.0015))
    tsp = np.arange(0.0, duration + 1e-12, 0.01)
    speed = np.full((len(tsp), 1), 2 * np.pi * motor_hz) + rng.normal(0.0, 0.5, (len(tsp), 1))
    return VibrationRecord(I, tg, omega, ts, tau, tsp, speed, axis, 0.0, motor_hz)


def _estimates(kind: str, seed: int) -> tuple[VibrationRecord, dict[str, object]]:
    """One record and its estimates by auto, ml and filtered at hand-set cutoffs."""
    from inertia_ros.core.estimation.batch import estimate
    from inertia_ros.core.estimation.method_choice import lowest_rotation_hz
    from inertia_ros.core.estimation.momentum import (
        Wheel,
        estimate_with_momentum,
        wheels_momentum,
    )

    r = torque_record(seed) if kind == 'torque' else wheel_throw(
        seed, duration=0.5 if kind == 'short throw' else 1.5)
    if kind != 'torque':
        mom = wheels_momentum(r.t_speed, r.speed, [Wheel('fly', r.wheel_axis, r.wheel_inertia)])

        def run(**kw: object) -> object:
            return estimate_with_momentum(r.t_gyro, r.omega, r.t_torque, r.torque, mom, **kw)
        auto = run(rotation_hz=lowest_rotation_hz(r.speed))
    else:
        def run(**kw: object) -> object:
            return estimate(r.t_gyro, r.omega, r.t_torque, r.torque, **kw)
        auto = run()
    out = {'auto': auto, 'ml': run(method='ml')}
    for k in (2, 4, 6):
        out[f'filtered line/{k}'] = run(method='filtered', window=k / r.line_hz)
    return r, out


def summary(kind: str, seeds: range) -> list[str]:
    """Median error, share of principal moments within 3 sigma, ok count and ok with error
    over 10 % per method over ``seeds`` of one scenario (``'throw'`` 1.5 s, ``'short throw'``
    0.5 s or ``'torque'``)."""
    rows: dict[str, list[tuple[float, np.ndarray, str]]] = {}
    for seed in seeds:
        r, res = _estimates(kind, seed)
        for name, e in res.items():
            if e.inertia is None or e.principal_moments is None:
                rows.setdefault(name, []).append((np.inf, np.full(3, np.inf), e.status))
                continue
            err = 100 * np.linalg.norm(e.inertia - r.inertia) / np.linalg.norm(r.inertia)
            z = ((np.asarray(e.principal_moments) - np.linalg.eigvalsh(r.inertia))
                 / np.asarray(e.diagnostics['principal_moments_std']))
            rows.setdefault(name, []).append((err, np.abs(z), e.status))
    lines = [f'{kind} ({len(seeds)} seeds): method | median error % | within 3 sigma % | ok | '
             'ok with error > 10 %']
    for name, v in rows.items():
        errs = np.array([x[0] for x in v])
        zs = np.concatenate([x[1] for x in v])
        ok = [x[2] == 'ok' for x in v]
        bad = sum(1 for x in v if x[2] == 'ok' and x[0] > 10)
        lines.append(f'  {name:18s} | {np.median(errs):6.2f} | {100 * np.mean(zs < 3):5.0f} | '
                     f'{sum(ok)}/{len(v)} | {bad}')
    return lines


if __name__ == '__main__':
    for kind in ('throw', 'short throw', 'torque'):
        print('\n'.join(summary(kind, range(10))))
