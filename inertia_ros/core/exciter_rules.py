"""The exciter's safety and stopping rules: a small state machine, free of ROS (issue 28).

The ``exciter`` node (:mod:`inertia_ros.nodes.exciter`) commands a planned torque profile
to a body whose tensor is being estimated.  Every decision it takes lives here, as pure
functions of what it has seen, so that the rules are tested without ROS:

Safety (each command)
    - **Torque limit** per axis: a planned command with ``|tau_i| > max_torque`` on any
      axis is not clipped (a clipped multisine is another manoeuvre, with other
      information): the exciter holds zero instead and says which axis crossed.
    - **Slew rate**: every output moves from the previous one by at most
      ``max_slew * dt`` per axis [N m/s] (also on its way to a hold at zero).
    - **Body rate** from the newest gyro sample: the rate the body would reach before a
      later command can take the torque away (gyro age + one command period + half the
      ramp-down time at ``max_slew``) is predicted from Euler's equations with the prior
      (or latest estimated) tensor, inflated by ``rate_margin``; when it would exceed
      ``max_rate`` the exciter holds zero (a planned command that brakes the body, i.e.
      lowers the predicted rate, still passes).  It resumes once ``|omega|`` is back under
      ``rate_hysteresis * max_rate``.
    - **No gyro** for ``gyro_timeout``: hold zero (the rate cannot be checked).
    - **Wheel speed** (with wheels, :meth:`ExciterRules.set_wheels`): the wheels make the
      body torque, each wheel's motor torque ``m = P tau`` (:mod:`.excitation.actuators`)
      moves its speed by ``m / J``; over the same horizon as the rate check, from the newest
      JointState speeds, a wheel that would cross ``max_speed`` while speeding up holds
      zero (:func:`wheel_speed_check`; a command that slows every such wheel passes).  No
      wheel speeds for ``gyro_timeout``: hold zero.

Stopping (for good: after a stop the only output is a final zero)
    ``target_reached``  every targeted relative sigma <= ``target_rel_std``;
    ``timeout``         ``timeout`` s of excitation;
    ``estimator_lost``  no covariance for ``estimator_timeout`` s (counted from the start
                        of the excitation until the first one arrives);
    ``reset``           the estimator reset (its evidence is gone);
    ``not_improving``   the relative sigma did not fall by ``stall_min_gain`` (fraction)
                        over the last ``stall_window`` s of a continuous stretch: a rise
                        of more than :data:`REASSESSED_JUMP` from one covariance to the
                        next starts a new stretch.  Evidence only grows, so such a rise is
                        the estimator re-assessing it (a model, torque-bias or hold change,
                        a widening by an adequacy test), not a stall; judged across it, a
                        rise of 20 % once stopped a loop that was converging.

States: ``waiting`` (no gyro sample yet; zero), ``exciting``, ``holding`` (a safety rule
holds zero; the reason says which), ``stopped``.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .excitation.actuators import WheelLimit, allocation

__all__ = ['REASSESSED_JUMP', 'STATES', 'STOP_REASONS', 'Command', 'ExciterLimits', 'ExciterRules',
           'TorqueSchedule', 'predicted_rate', 'principal_rel_std', 'wheel_speed_check']

STATES = ('waiting', 'exciting', 'holding', 'stopped')
STOP_REASONS = ('target_reached', 'timeout', 'estimator_lost', 'reset', 'not_improving')
#: Rise of the relative sigma between two covariances that starts a new stall stretch
#: (fraction): consecutive covariances of a converging estimate differ by ~1 %; a model or
#: hold switch of the live estimator moves it by 20-150 % (measured on the closed loop).
REASSESSED_JUMP = 0.1
_AXES = 'xyz'


@dataclass(frozen=True)
class ExciterLimits:
    """The exciter's limits and stopping thresholds.

    Attributes
    ----------
    max_torque : float
        Largest commanded torque per axis [N m], > 0.
    max_slew : float
        Largest change of the command per axis [N m/s], > 0.
    max_rate : float
        Largest body rate ``|omega|`` [rad/s], > 0.
    target_rel_std : float
        Stop when every targeted relative sigma is at or below this [dimensionless], > 0.
    timeout : float
        Stop after this much excitation [s], > 0.
    estimator_timeout : float
        Stop when no covariance arrived for this long [s], > 0.
    command_period : float
        Period of the commands [s], > 0 (the torque is held this long at least).
    rate_margin : float
        Relative uncertainty of the tensor used in the rate prediction, 0..1.
    rate_hysteresis : float
        Resume after a rate hold once ``|omega| < rate_hysteresis * max_rate``, in (0, 1).
    gyro_timeout : float
        Hold zero when the newest gyro sample is older than this [s], > 0.
    stall_window : float
        Window of the not-improving rule [s], > 0.
    stall_min_gain : float
        Smallest relative fall of the sigma over ``stall_window``, 0..1.
    """

    max_torque: float
    max_slew: float
    max_rate: float
    target_rel_std: float = 0.02
    timeout: float = 120.0
    estimator_timeout: float = 10.0
    command_period: float = 0.02
    rate_margin: float = 0.2
    rate_hysteresis: float = 0.8
    gyro_timeout: float = 0.5
    stall_window: float = 20.0
    stall_min_gain: float = 0.02

    def __post_init__(self) -> None:
        for name in ('max_torque', 'max_slew', 'max_rate', 'target_rel_std', 'timeout',
                     'estimator_timeout', 'command_period', 'gyro_timeout', 'stall_window'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a positive number, got {value!r}')
        for name, lo, hi in (('rate_margin', 0.0, 1.0), ('stall_min_gain', 0.0, 1.0),
                             ('rate_hysteresis', 0.0, 1.0)):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and lo <= value <= hi):
                raise ValueError(f'{name} must be in [{lo:g}, {hi:g}], got {value!r}')
        if not 0.0 < self.rate_hysteresis < 1.0:
            raise ValueError(f'rate_hysteresis must be in (0, 1), got {self.rate_hysteresis!r}')


@dataclass(frozen=True)
class Command:
    """One decision of the rules.

    Attributes
    ----------
    torque : numpy.ndarray, shape (3,)
        Torque to command [N m], body axes.
    state : str
        One of :data:`STATES`.
    reason : str
        Why a hold or a stop ('' while exciting): one line.
    """

    torque: np.ndarray
    state: str
    reason: str = ''


def principal_rel_std(cov: np.ndarray, moments: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Relative one-sigma of each principal moment from the tensor-element covariance.

    First order: ``lambda_k = v_k^T I v_k`` moves by ``g_k . d theta`` with
    ``g_k = [vx^2, vy^2, vz^2, 2 vx vy, 2 vx vz, 2 vy vz]`` (``v_k`` column k of ``axes``).

    Parameters
    ----------
    cov : numpy.ndarray, shape (6, 6)
        Covariance of ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg^2 m^4].
    moments : numpy.ndarray, shape (3,)
        Principal moments [kg m^2], > 0.
    axes : numpy.ndarray, shape (3, 3)
        Principal axes as columns (unit vectors).

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``sigma(lambda_k) / lambda_k`` [dimensionless]; inf where a moment is not positive
        or the covariance is not finite.
    """
    cov = np.asarray(cov, dtype=float).reshape(6, 6)
    moments = np.asarray(moments, dtype=float).reshape(3)
    v = np.asarray(axes, dtype=float).reshape(3, 3)
    out = np.full(3, np.inf)
    for k in range(3):
        x, y, z = v[:, k]
        g = np.array([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z])
        var = float(g @ cov @ g)
        if np.isfinite(var) and var >= 0.0 and moments[k] > 0.0:
            out[k] = math.sqrt(var) / moments[k]
    return out


def predicted_rate(omega: np.ndarray, torque: np.ndarray, inertia: np.ndarray,
                   horizon: float, margin: float) -> float:
    """An upper estimate of ``|omega|`` after ``horizon`` s under ``torque``.

    Parameters
    ----------
    omega : numpy.ndarray, shape (3,)
        Body rate now [rad/s].
    torque : numpy.ndarray, shape (3,)
        Torque held over the horizon [N m].
    inertia : numpy.ndarray, shape (3, 3)
        Tensor [kg m^2] (prior or estimate).
    horizon : float
        Time [s], >= 0.
    margin : float
        Relative uncertainty of the tensor: the torque's effect is inflated by it.

    Returns
    -------
    float
        ``|omega + h I^-1 (tau - omega x I omega)| + margin h |I^-1 tau|`` [rad/s].
    """
    omega = np.asarray(omega, dtype=float)
    torque = np.asarray(torque, dtype=float)
    inv = np.linalg.inv(inertia)
    accel = inv @ (torque - np.cross(omega, inertia @ omega))
    return float(np.linalg.norm(omega + horizon * accel)
                 + margin * horizon * np.linalg.norm(inv @ torque))


def wheel_speed_check(speeds: np.ndarray, torque: np.ndarray,
                      wheels: Sequence[WheelLimit], horizon: float) -> str:
    """Why ``torque`` would drive a wheel over its speed limit ('' when it would not).

    Parameters
    ----------
    speeds : numpy.ndarray, shape (n,)
        Wheel speeds now [rad/s], in the order of ``wheels``.
    torque : numpy.ndarray, shape (3,)
        Body torque held over the horizon [N m].
    wheels : sequence of WheelLimit
        The wheels (axes, spin inertia, ``max_speed``).
    horizon : float
        Time [s], >= 0.

    Returns
    -------
    str
        '' when every wheel's predicted speed ``w + horizon m / J`` (``m = P tau``, the
        minimum-norm allocation) is within ``max_speed`` or slower than now; else one line
        naming the first wheel that would cross.
    """
    w = np.asarray(speeds, dtype=float).reshape(len(wheels))
    m = allocation(wheels) @ np.asarray(torque, dtype=float).reshape(3)
    pred = w + horizon * m / np.array([wl.inertia for wl in wheels])
    for k, wl in enumerate(wheels):
        if abs(pred[k]) > wl.max_speed and abs(pred[k]) > abs(w[k]):
            return (f'wheel speed limit: {wl.joint} at {w[k]:.4g} rad/s, predicted '
                    f'{pred[k]:.4g} beyond max_speed {wl.max_speed:g} rad/s')
    return ''


@dataclass
class _Memory:
    """What the rules have seen (mutable state of :class:`ExciterRules`)."""

    t_start: float | None = None
    t_gyro: float | None = None
    omega: np.ndarray = field(default_factory=lambda: np.zeros(3))
    t_cov: float | None = None
    t_step: float | None = None
    output: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rate_hold: bool = False
    stop_reason: str = ''
    stop_detail: str = ''
    sigma: deque = field(default_factory=deque)  # (t, rel_std)
    t_wheels: float | None = None
    wheel_speeds: np.ndarray | None = None


class ExciterRules:
    """The exciter's state machine (see the module docstring).

    Parameters
    ----------
    limits : ExciterLimits
        Limits and thresholds.
    inertia : numpy.ndarray, shape (3, 3)
        Prior tensor [kg m^2] for the rate prediction (positive definite).

    Feed it with :meth:`on_gyro`, :meth:`on_sigma` and :meth:`on_reset`; ask
    :meth:`step` for each command.  Times are seconds on one clock.
    """

    def __init__(self, limits: ExciterLimits, inertia: np.ndarray) -> None:
        self.limits = limits
        self.set_inertia(inertia)
        self.wheels: tuple[WheelLimit, ...] = ()
        self.m = _Memory()

    # ------------------------------------------------------------------ inputs
    def set_inertia(self, inertia: np.ndarray) -> None:
        """Use ``inertia`` (3, 3) [kg m^2] for the rate prediction from now on."""
        inertia = np.asarray(inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)) \
                or np.linalg.eigvalsh(0.5 * (inertia + inertia.T))[0] <= 0.0:
            raise ValueError(f'inertia must be a positive definite 3x3 tensor, got {inertia!r}')
        self.inertia = 0.5 * (inertia + inertia.T)

    def set_wheels(self, wheels: Sequence[WheelLimit]) -> None:
        """Enforce the speed limits of ``wheels`` (they make the body torque) from now on;
        :meth:`on_wheel_speeds` feeds their speeds.  Raises ValueError when their axes do
        not span the three body axes."""
        wheels = tuple(wheels)
        if wheels:
            allocation(wheels)
        self.wheels = wheels

    def on_wheel_speeds(self, t: float, speeds: np.ndarray) -> None:
        """The wheels' speeds ``speeds`` (n,) [rad/s], in :meth:`set_wheels` order, at ``t``."""
        self.m.t_wheels = float(t)
        self.m.wheel_speeds = np.asarray(speeds, dtype=float).reshape(len(self.wheels)).copy()

    def on_gyro(self, t: float, omega: np.ndarray) -> None:
        """The newest gyro sample ``omega`` (3,) [rad/s] taken at ``t`` [s]."""
        self.m.t_gyro = float(t)
        self.m.omega = np.asarray(omega, dtype=float).reshape(3).copy()

    def on_sigma(self, t: float, rel_std: float | None) -> None:
        """A new covariance at ``t`` [s]: the largest targeted relative sigma ``rel_std``
        (None: a covariance arrived but its sigma cannot be formed yet; only the estimator
        is known to be alive)."""
        m, lim = self.m, self.limits
        m.t_cov = float(t)
        if m.stop_reason or m.t_start is None or rel_std is None:
            return
        rel_std = float(rel_std)
        if rel_std <= lim.target_rel_std:
            self._stop('target_reached', f'relative sigma {rel_std:.4g} <= target '
                                         f'{lim.target_rel_std:g}')
            return
        if m.sigma and rel_std > m.sigma[-1][1] * (1.0 + REASSESSED_JUMP):
            m.sigma.clear()         # the estimator re-assessed its evidence: a new stretch
        m.sigma.append((float(t), rel_std))
        while len(m.sigma) > 1 and m.sigma[1][0] <= t - lim.stall_window:
            m.sigma.popleft()
        t_old, s_old = m.sigma[0]
        if t - t_old >= lim.stall_window and not rel_std < s_old * (1.0 - lim.stall_min_gain):
            self._stop('not_improving', f'relative sigma {rel_std:.4g} after '
                                        f'{t - t_old:.3g} s, was {s_old:.4g} (less than '
                                        f'{100 * lim.stall_min_gain:g} % better)')

    def on_reset(self, t: float, why: str = 'the estimator reset') -> None:
        """The estimator forgot its data at ``t`` [s]: stop (``reset``)."""
        if self.m.t_start is not None:
            self._stop('reset', why)

    def stop(self, reason: str, detail: str = '') -> None:
        """Stop for ``reason`` (one of :data:`STOP_REASONS` or another word) now."""
        self._stop(reason, detail)

    def _stop(self, reason: str, detail: str) -> None:
        if not self.m.stop_reason:
            self.m.stop_reason, self.m.stop_detail = reason, detail

    # ------------------------------------------------------------------ state
    @property
    def stopped(self) -> bool:
        """True once a stop rule fired (for good)."""
        return bool(self.m.stop_reason)

    @property
    def stop_reason(self) -> str:
        """One of :data:`STOP_REASONS` (or the reason given to :meth:`stop`); '' before."""
        return self.m.stop_reason

    @property
    def stop_detail(self) -> str:
        """One line on the stop ('' before)."""
        return self.m.stop_detail

    @property
    def t_start(self) -> float | None:
        """When the excitation started (first step with a gyro sample) [s], or None."""
        return self.m.t_start

    # ------------------------------------------------------------------ the step
    def step(self, t: float, planned: np.ndarray) -> Command:
        """The command at ``t`` [s] for the planned torque ``planned`` (3,) [N m]."""
        m, lim = self.m, self.limits
        t = float(t)
        if not m.stop_reason and m.t_gyro is None:
            m.t_step = t
            return Command(np.zeros(3), 'waiting', 'no gyro sample yet')
        if m.t_start is None and not m.stop_reason:
            m.t_start = t
        self._check_times(t)
        if m.stop_reason:
            m.output = np.zeros(3)
            m.t_step = t
            return Command(np.zeros(3), 'stopped', f'{m.stop_reason}: {m.stop_detail}'
                           if m.stop_detail else m.stop_reason)
        dt = lim.command_period if m.t_step is None else max(0.0, t - m.t_step)
        m.t_step = t
        target, reason = self._target(t, np.asarray(planned, dtype=float).reshape(3), dt)
        step = lim.max_slew * dt
        out = m.output + np.clip(target - m.output, -step, step)
        m.output = np.clip(out, -lim.max_torque, lim.max_torque)
        return Command(m.output.copy(), 'holding' if reason else 'exciting', reason)

    def _check_times(self, t: float) -> None:
        m, lim = self.m, self.limits
        if m.stop_reason or m.t_start is None:
            return
        if t - m.t_start >= lim.timeout:
            self._stop('timeout', f'{t - m.t_start:.3g} s of excitation >= timeout '
                                  f'{lim.timeout:g} s')
            return
        since = m.t_start if m.t_cov is None or m.t_cov < m.t_start else m.t_cov
        if t - since > lim.estimator_timeout:
            what = 'no covariance yet' if m.t_cov is None or m.t_cov < m.t_start else \
                'no covariance'
            self._stop('estimator_lost', f'{what} for {t - since:.3g} s > estimator_timeout '
                                         f'{lim.estimator_timeout:g} s')

    def _target(self, t: float, planned: np.ndarray, dt: float) -> tuple[np.ndarray, str]:
        """The torque to move towards and why it is held at zero ('' when it is not)."""
        m, lim = self.m, self.limits
        if not np.all(np.isfinite(planned)):
            return np.zeros(3), 'planned torque is not finite'
        over = np.flatnonzero(np.abs(planned) > lim.max_torque)
        if over.size:
            i = int(over[0])
            return np.zeros(3), (f'torque limit: planned {_AXES[i]} {planned[i]:.4g} N m '
                                 f'exceeds max_torque {lim.max_torque:g} N m')
        age = t - m.t_gyro
        if age > lim.gyro_timeout:
            return np.zeros(3), f'no gyro sample for {age:.3g} s (> {lim.gyro_timeout:g} s)'
        rate = float(np.linalg.norm(m.omega))
        if m.rate_hold and rate < lim.rate_hysteresis * lim.max_rate:
            m.rate_hold = False
        step = lim.max_slew * dt
        nxt = m.output + np.clip(planned - m.output, -step, step)
        horizon = max(age, 0.0) + lim.command_period + 0.5 * float(
            np.max(np.abs(nxt))) / lim.max_slew
        pred = predicted_rate(m.omega, nxt, self.inertia, horizon, lim.rate_margin)
        braking = pred < rate
        if not braking and (m.rate_hold or pred > lim.max_rate):
            if not m.rate_hold:
                m.rate_hold = True
            return np.zeros(3), (f'rate limit: |omega| {rate:.4g} rad/s, predicted '
                                 f'{pred:.4g} > max_rate {lim.max_rate:g} rad/s (resume '
                                 f'under {lim.rate_hysteresis * lim.max_rate:.4g})')
        why = self._wheel_reason(t, nxt, horizon - max(age, 0.0))
        return (np.zeros(3), why) if why else (planned, '')

    def _wheel_reason(self, t: float, nxt: np.ndarray, ahead: float) -> str:
        """Why the wheels hold zero ('' when they do not, or without wheels); ``ahead`` [s]
        is the rate check's horizon less the gyro's age (the wheel sample's age is added)."""
        m, lim = self.m, self.limits
        if not self.wheels:
            return ''
        if m.t_wheels is None or t - m.t_wheels > lim.gyro_timeout:
            return ('no wheel speeds yet' if m.t_wheels is None else
                    f'no wheel speeds for {t - m.t_wheels:.3g} s (> {lim.gyro_timeout:g} s)')
        return wheel_speed_check(m.wheel_speeds, nxt,
                                 self.wheels, max(t - m.t_wheels, 0.0) + ahead)


class TorqueSchedule:
    """A planned torque profile, zero-order held on its grid and repeated after its end.

    Parameters
    ----------
    t : numpy.ndarray, shape (J,)
        Command times [s], ``t[0] = 0``, evenly spaced.
    torque : numpy.ndarray, shape (J, 3)
        Torque [N m] held from ``t[j]`` to ``t[j + 1]``.
    """

    def __init__(self, t: np.ndarray, torque: np.ndarray) -> None:
        t = np.asarray(t, dtype=float)
        torque = np.asarray(torque, dtype=float)
        if t.ndim != 1 or t.size < 2 or torque.shape != (t.size, 3):
            raise ValueError(f'schedule: need >= 2 times and torque (J, 3), got {t.shape} '
                             f'and {torque.shape}')
        self.t, self.torque = t, torque
        self.period = float(t[1] - t[0])
        self.span = float(t[-1] + self.period)

    @classmethod
    def from_scene(cls, scene: object, seed: int | None = None) -> TorqueSchedule:
        """The scene's torque components on its command grid, drawn as the simulator draws
        them (same generator tree), so the open-loop run of the scene commands the same."""
        from inertia_ros.core.simulation import command_grid

        rng = np.random.default_rng(int(scene.seed if seed is None else seed))
        r_torque = rng.spawn(7)[0]
        t = command_grid(scene)
        cmd = np.zeros((t.size, 3))
        for comp, r in zip(scene.torque, r_torque.spawn(len(scene.torque)), strict=True):
            cmd += comp.evaluate(t, r)
        if t.size < 2:
            raise ValueError(f'scene {scene.name!r}: too short for a torque schedule')
        return cls(t, cmd)

    def at(self, t: float) -> np.ndarray:
        """Planned torque (3,) [N m] at ``t`` [s] from the start (repeats after the end)."""
        j = int(math.floor((float(t) % self.span) / self.period + 1e-9))
        return self.torque[min(max(j, 0), self.t.size - 1)].copy()
